//! 2D registration of radial sweeps (and scans) against an occupancy grid.
//!
//! - [`LikelihoodField`]: how well an endpoint at a map point explains a
//!   mapped obstacle.
//! - [`register`]: correlative search over translation and rotation around
//!   a [`PosePrior`], local refinement below one cell, and the covariance
//!   of the result ([`Registration`]), tuned by [`RegisterConfig`].
//! - [`PosePrior::after_forward`]: the belief after a commanded straight
//!   move, from [`MotionNoise`].
//! - [`endpoints`]: the obstacle points of a profile in its own frame.
//!
//! ```
//! use pirouette_geom::{Point2, Pose2};
//! use pirouette_register::{register, LikelihoodField, MotionNoise, PosePrior, RegisterConfig};
//! // A mapped wall along y = 1 m, 2 m long, and what the robot sees of it
//! // from (0.52, 0.0) facing +x.
//! let wall: Vec<Point2> = (0..400).map(|k| Point2::new(-1.0 + 0.005 * k as f64, 1.0)).collect();
//! let field = LikelihoodField::from_points(&wall, 0.01, 0.015, 0.2);
//! let seen: Vec<Point2> = (0..80).map(|k| Point2::new(-0.4 + 0.01 * k as f64, 1.0)).collect();
//! let prior = PosePrior::after_forward(&Pose2::IDENTITY, 0.5, 0.01, &MotionNoise::default());
//! let reg = register(&field, &seen, &prior, &RegisterConfig::default())?;
//! assert!(reg.accepted && reg.pose.y.abs() < 0.005);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

mod bound;
mod correlative;
mod field;

pub use correlative::{
    may_accept, register, thin_points, Covariance, MotionNoise, PosePrior, RegisterConfig, Registration,
    Rival, Search, Window,
};
pub use field::{LikelihoodField, CUTOFF_SIGMAS};

use pirouette_geom::Point2;
use pirouette_profile::Rop;

/// Errors of registration.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RegisterError {
    /// The prior is not a finite pose with positive spreads.
    #[error("registration prior is not usable: {problem}")]
    BadPrior {
        /// The prior as given.
        problem: String,
    },
}

/// `⌊x⌋` as an integer, bit for bit `x.floor() as i64` (saturating, NaN
/// to 0) without a call to the maths library: the lattice's cell of every
/// point of every pose searched goes through it.
#[inline]
pub(crate) fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// The obstacle points of a profile (its reliable ranges) in the profile's
/// own frame, in bin order.
pub fn endpoints(rop: &Rop) -> Vec<Point2> {
    (0..rop.len())
        .filter_map(|i| {
            rop.reliable(i)
                .map(|r| Point2::from_polar(r as f64, rop.bin_centre_rad(i)))
        })
        .collect()
}

/// The points of a profile's ranges beyond its soft limit, up to
/// `reach_m`, in the profile's own frame, in bin order.
///
/// The soft limit is a rule for the map: a range beyond it never marks an
/// obstacle there. Its bearing and (less precisely) its distance still say
/// where the robot stands, and far points are what pins a heading when
/// the near floor is open: a heading error moves a point in proportion to
/// its range.
pub fn far_points(rop: &Rop, reach_m: f64) -> Vec<Point2> {
    (0..rop.len())
        .filter_map(|i| {
            let r = rop.range_m[i];
            (r.is_finite() && r > rop.max_range_m && r as f64 <= reach_m)
                .then(|| Point2::from_polar(r as f64, rop.bin_centre_rad(i)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_i64_is_floor() {
        let mut checked = 0;
        for x in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.999_999_999,
            -2.000_000_001,
            1e15 + 0.5,
            -1e15 - 0.5,
            9.3e18,
            -9.3e18,
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            4503599627370497.0,
            -4503599627370497.0,
        ] {
            assert_eq!(floor_i64(x), x.floor() as i64, "{x}");
            checked += 1;
        }
        for k in -2000..2000 {
            let x = k as f64 * 0.0137 / 0.05;
            assert_eq!(floor_i64(x), x.floor() as i64, "{x}");
            checked += 1;
        }
        assert_eq!(checked, 4021);
    }

    #[test]
    fn near_and_far_points_split_a_profile_at_its_soft_limit() {
        // Bins 10° wide from 0°, soft limit 1 m.
        let mut rop = Rop::empty(0.0, 10f64.to_radians(), 6, 1.0);
        rop.range_m = vec![0.5, 1.0, 1.5, 2.5, f32::INFINITY, f32::NAN];
        let near = endpoints(&rop);
        let far = far_points(&rop, 2.0);
        let at = |r: f64, deg: f64| Point2::from_polar(r, deg.to_radians());
        let close = |a: &[Point2], b: &[Point2]| {
            a.len() == b.len() && a.iter().zip(b).all(|(p, q)| (p.x - q.x).hypot(p.y - q.y) < 1e-6)
        };
        assert!(close(&near, &[at(0.5, 5.0), at(1.0, 15.0)]), "{near:?}");
        // Beyond the limit and within reach only: 2.5 m is out of reach,
        // nothing in sight and unseen bins are no points.
        assert!(close(&far, &[at(1.5, 25.0)]), "{far:?}");
        assert!(close(&far_points(&rop, 3.0), &[at(1.5, 25.0), at(2.5, 35.0)]));
        assert!(far_points(&rop, 1.0).is_empty());
    }
}
