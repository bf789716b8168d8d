//! Angles: radians inside the code, degrees only at the edges.

use std::f64::consts::{PI, TAU};

/// Wraps an angle in radians into `(-π, π]`.
pub fn wrap_angle(angle_rad: f64) -> f64 {
    let mut a = angle_rad.rem_euclid(TAU);
    if a > PI {
        a -= TAU;
    }
    a
}

/// Converts degrees to radians.
pub fn deg_to_rad(angle_deg: f64) -> f64 {
    angle_deg.to_radians()
}

/// Converts radians to degrees.
pub fn rad_to_deg(angle_rad: f64) -> f64 {
    angle_rad.to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn wraps_known_values() {
        assert_eq!(wrap_angle(0.0), 0.0);
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-3.0 * PI / 2.0) - PI / 2.0).abs() < 1e-12);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 512, rng_seed: proptest::test_runner::RngSeed::Fixed(7), ..ProptestConfig::default() })]
        #[test]
        fn wrapped_is_in_range_and_equivalent(a in -100.0f64..100.0) {
            let w = wrap_angle(a);
            prop_assert!(w > -PI && w <= PI);
            prop_assert!((w.sin() - a.sin()).abs() < 1e-9 && (w.cos() - a.cos()).abs() < 1e-9);
        }
    }
}
