//! Lens distortion: how a real lens bends the rays of an ideal pinhole.
//!
//! Both models act on normalised image coordinates `(x, y) = (X/Z, Y/Z)`
//! of a ray in the camera frame (x right, y down, z forward), as ROS
//! `camera_info` and OpenCV define them:
//!
//! - [`Distortion::RadialTangential`] (ROS `plumb_bob`, OpenCV's default):
//!   `r² = x² + y²`, `x' = x(1 + k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 x y + p2 (r² + 2x²)`,
//!   `y' = y(1 + k1 r² + k2 r⁴ + k3 r⁶) + p1 (r² + 2y²) + 2 p2 x y`.
//! - [`Distortion::Equidistant`] (ROS `equidistant`, OpenCV `fisheye`):
//!   `θ = atan(r)`, `θd = θ(1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸)`, `(x', y') = (θd / r)(x, y)`.
//!
//! [`Distortion::distort`] is the closed form; [`Distortion::undistort`]
//! inverts it by Newton's method and answers only where the inverse is the
//! ray that the closed form maps back to the pixel, on the branch where the
//! distortion still grows with the radius (beyond it a polynomial lens
//! model folds back and one pixel has two rays).

use serde::{Deserialize, Serialize};

/// A lens distortion model with its coefficients.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub enum Distortion {
    /// An ideal pinhole: rays are not bent.
    #[default]
    None,
    /// Radial-tangential (Brown-Conrady; ROS `plumb_bob`).
    RadialTangential {
        /// Radial coefficient of r².
        k1: f64,
        /// Radial coefficient of r⁴.
        k2: f64,
        /// First tangential coefficient.
        p1: f64,
        /// Second tangential coefficient.
        p2: f64,
        /// Radial coefficient of r⁶.
        k3: f64,
    },
    /// Equidistant fisheye (Kannala-Brandt; ROS `equidistant`).
    Equidistant {
        /// Coefficients of θ², θ⁴, θ⁶, θ⁸.
        k: [f64; 4],
    },
}

/// Newton's iterations before [`Distortion::undistort`] gives up.
const MAX_ITERATIONS: usize = 30;

/// How closely an undistorted point must map back, in normalised units
/// (a millionth of a pixel at a focal length of a thousand pixels).
const ROUND_TRIP_TOLERANCE: f64 = 1e-9;

impl Distortion {
    /// True for the ideal pinhole.
    pub fn is_none(&self) -> bool {
        matches!(self, Distortion::None)
    }

    /// The model's name as ROS `camera_info` writes it.
    pub fn ros_name(&self) -> &'static str {
        match self {
            Distortion::None => "none",
            Distortion::RadialTangential { .. } => "plumb_bob",
            Distortion::Equidistant { .. } => "equidistant",
        }
    }

    /// The coefficients as ROS lists them (`D`): `k1 k2 p1 p2 k3` or
    /// `k1 k2 k3 k4`; empty for the ideal pinhole.
    pub fn coefficients(&self) -> Vec<f64> {
        match *self {
            Distortion::None => Vec::new(),
            Distortion::RadialTangential { k1, k2, p1, p2, k3 } => vec![k1, k2, p1, p2, k3],
            Distortion::Equidistant { k } => k.to_vec(),
        }
    }

    /// The model named `name` (ROS and OpenCV spellings) with coefficients
    /// `d`; an error says what is wrong. All-zero coefficients are the
    /// ideal pinhole whatever the name, so that a calibration of an
    /// undistorted camera maps exactly as one without a lens model.
    pub fn from_named(name: &str, d: &[f64]) -> Result<Self, String> {
        if let Some(v) = d.iter().find(|v| !v.is_finite()) {
            return Err(format!("distortion coefficient {v} is not finite"));
        }
        let key = name.trim().to_ascii_lowercase();
        // ROS writes an empty `D` for a camera calibrated without a lens
        // model: the ideal pinhole (a fisheye always needs its four).
        let radtan = matches!(
            key.as_str(),
            "plumb_bob" | "radtan" | "radial-tangential" | "radial_tangential" | "brown" | "none" | ""
        );
        if d.is_empty() && radtan {
            return Ok(Distortion::None);
        }
        let model = match key.as_str() {
            "plumb_bob" | "radtan" | "radial-tangential" | "radial_tangential" | "brown" => {
                // OpenCV writes 4, 5, 8, 12 or 14 coefficients; the terms
                // past k3 (rational and thin-prism) must be zero here.
                if !(d.len() == 4 || d.len() >= 5) {
                    return Err(format!(
                        "the {key} model takes 4 or 5 coefficients (k1 k2 p1 p2 [k3]), not {}",
                        d.len()
                    ));
                }
                if d.len() > 5 && d[5..].iter().any(|v| *v != 0.0) {
                    return Err(format!(
                        "{} distortion coefficients with terms past k3: the rational or thin-prism model, which is not supported (plumb_bob and equidistant are)",
                        d.len()
                    ));
                }
                Distortion::RadialTangential {
                    k1: d[0],
                    k2: d[1],
                    p1: d[2],
                    p2: d[3],
                    k3: d.get(4).copied().unwrap_or(0.0),
                }
            }
            "equidistant" | "fisheye" | "kannala_brandt" | "kannala-brandt" => {
                if d.len() != 4 {
                    return Err(format!(
                        "the {key} model takes 4 coefficients (k1 k2 k3 k4), not {}",
                        d.len()
                    ));
                }
                Distortion::Equidistant {
                    k: [d[0], d[1], d[2], d[3]],
                }
            }
            "none" | "" if d.iter().all(|v| *v == 0.0) => Distortion::None,
            other => {
                return Err(format!(
                    "unknown distortion model `{other}` (known: plumb_bob, equidistant)"
                ))
            }
        };
        Ok(if model.coefficients().iter().all(|v| *v == 0.0) {
            Distortion::None
        } else {
            model
        })
    }

    /// The distorted normalised point of the ray `(x, y)`.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        match *self {
            Distortion::None => (x, y),
            Distortion::RadialTangential { k1, k2, p1, p2, k3 } => {
                let r2 = x * x + y * y;
                let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
                (
                    x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                    y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
                )
            }
            Distortion::Equidistant { k } => {
                let r = x.hypot(y);
                if r < 1e-12 {
                    return (x, y);
                }
                let theta = r.atan();
                let scale = equidistant_theta_d(&k, theta) / r;
                (x * scale, y * scale)
            }
        }
    }

    /// The ray `(x, y)` whose distorted point is `(xd, yd)`, or `None`
    /// where none is found on the lens's monotonic branch (the image
    /// corner of a lens whose polynomial folds back, or a fisheye pixel
    /// beyond 90° from the axis).
    pub fn undistort(&self, xd: f64, yd: f64) -> Option<(f64, f64)> {
        match *self {
            Distortion::None => Some((xd, yd)),
            Distortion::RadialTangential { .. } => self.undistort_radtan(xd, yd),
            Distortion::Equidistant { k } => undistort_equidistant(&k, xd, yd),
        }
    }

    /// Newton's method on the 2D map, from the distorted point.
    fn undistort_radtan(&self, xd: f64, yd: f64) -> Option<(f64, f64)> {
        let (mut x, mut y) = (xd, yd);
        for _ in 0..MAX_ITERATIONS {
            let (fx, fy) = self.distort(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            if ex.hypot(ey) < ROUND_TRIP_TOLERANCE * 1e-3 {
                break;
            }
            let [[a, b], [c, d]] = self.radtan_jacobian(x, y);
            let det = a * d - b * c;
            if det.abs() < 1e-12 || !det.is_finite() {
                return None;
            }
            x -= (d * ex - b * ey) / det;
            y -= (a * ey - c * ex) / det;
        }
        let (fx, fy) = self.distort(x, y);
        let on_branch = self.radially_increasing(x, y);
        ((fx - xd).hypot(fy - yd) < ROUND_TRIP_TOLERANCE && on_branch && x.is_finite() && y.is_finite())
            .then_some((x, y))
    }

    /// ∂(x', y') / ∂(x, y) of the radial-tangential model.
    fn radtan_jacobian(&self, x: f64, y: f64) -> [[f64; 2]; 2] {
        let Distortion::RadialTangential { k1, k2, p1, p2, k3 } = *self else {
            return [[1.0, 0.0], [0.0, 1.0]];
        };
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        // d(radial)/d(r²)
        let dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2);
        [
            [
                radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x,
                2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y,
            ],
            [
                2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y,
                radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x,
            ],
        ]
    }

    /// True where the radial part still grows with the radius:
    /// `d(r·radial(r²))/dr > 0`.
    fn radially_increasing(&self, x: f64, y: f64) -> bool {
        match *self {
            Distortion::RadialTangential { k1, k2, k3, .. } => {
                let r2 = x * x + y * y;
                1.0 + r2 * (3.0 * k1 + r2 * (5.0 * k2 + r2 * 7.0 * k3)) > 0.0
            }
            _ => true,
        }
    }
}

/// `θd = θ(1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸)`.
fn equidistant_theta_d(k: &[f64; 4], theta: f64) -> f64 {
    let t2 = theta * theta;
    theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))))
}

/// Solves `θd(θ) = |(xd, yd)|` for θ in `[0, π/2)` by Newton's method, on
/// the branch where `θd` grows with θ.
fn undistort_equidistant(k: &[f64; 4], xd: f64, yd: f64) -> Option<(f64, f64)> {
    let rd = xd.hypot(yd);
    if rd < 1e-12 {
        return Some((xd, yd));
    }
    let mut theta = rd.min(1.5);
    for _ in 0..MAX_ITERATIONS {
        let t2 = theta * theta;
        let f = equidistant_theta_d(k, theta) - rd;
        let df = 1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + t2 * 9.0 * k[3])));
        if df <= 0.0 || !df.is_finite() {
            return None;
        }
        let step = f / df;
        theta -= step;
        if step.abs() < 1e-15 {
            break;
        }
    }
    let t2 = theta * theta;
    let slope = 1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + t2 * 9.0 * k[3])));
    let ok = (0.0..std::f64::consts::FRAC_PI_2 - 1e-6).contains(&theta)
        && slope > 0.0
        && (equidistant_theta_d(k, theta) - rd).abs() < ROUND_TRIP_TOLERANCE;
    ok.then(|| {
        let scale = theta.tan() / rd;
        (xd * scale, yd * scale)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// TUM freiburg2's published RGB distortion.
    const TUM_FR2: Distortion = Distortion::RadialTangential {
        k1: 0.2312,
        k2: -0.7849,
        p1: -0.0033,
        p2: -0.0001,
        k3: 0.9172,
    };

    /// A fisheye lens of the kind small robots carry (coefficients of the
    /// order a calibration of a 180° lens gives).
    const FISHEYE: Distortion = Distortion::Equidistant {
        k: [-0.013, 0.021, -0.017, 0.004],
    };

    #[test]
    fn radial_tangential_matches_the_formula_at_a_hand_worked_point() {
        // x = 0.3, y = -0.2: r² = 0.13, radial = 1 + 0.13 k1 + 0.0169 k2 + 0.002197 k3.
        let d = Distortion::RadialTangential {
            k1: 0.1,
            k2: -0.05,
            p1: 0.01,
            p2: -0.02,
            k3: 0.2,
        };
        let radial = 1.0 + 0.013 - 0.000845 + 0.0004394;
        let xd = 0.3 * radial + 2.0 * 0.01 * 0.3 * -0.2 + -0.02 * (0.13 + 2.0 * 0.09);
        let yd = -0.2 * radial + 0.01 * (0.13 + 2.0 * 0.04) + 2.0 * -0.02 * 0.3 * -0.2;
        let (a, b) = d.distort(0.3, -0.2);
        assert!(
            (a - xd).abs() < 1e-15 && (b - yd).abs() < 1e-15,
            "{a} {b} vs {xd} {yd}"
        );
    }

    #[test]
    fn equidistant_matches_the_formula_at_a_hand_worked_point() {
        // r = 1: θ = π/4.
        let d = Distortion::Equidistant {
            k: [0.1, 0.01, 0.0, 0.0],
        };
        let t = std::f64::consts::FRAC_PI_4;
        let td = t * (1.0 + 0.1 * t * t + 0.01 * t.powi(4));
        let (a, b) = d.distort(0.6, 0.8);
        assert!((a - 0.6 * td).abs() < 1e-15 && (b - 0.8 * td).abs() < 1e-15);
    }

    #[test]
    fn no_distortion_is_the_identity_to_the_bit() {
        for (x, y) in [(0.0, 0.0), (0.31, -0.77), (-1.5, 2.25)] {
            assert_eq!(Distortion::None.distort(x, y), (x, y));
            assert_eq!(Distortion::None.undistort(x, y), Some((x, y)));
        }
    }

    #[test]
    fn named_models_read_as_ros_and_opencv_write_them() {
        let d = Distortion::from_named("plumb_bob", &[0.2312, -0.7849, -0.0033, -0.0001, 0.9172]).unwrap();
        assert_eq!(d, TUM_FR2);
        // OpenCV's eight coefficients with the rational terms zero.
        let d8 = Distortion::from_named(
            "plumb_bob",
            &[0.2312, -0.7849, -0.0033, -0.0001, 0.9172, 0.0, 0.0, 0.0],
        )
        .unwrap();
        assert_eq!(d8, TUM_FR2);
        let rational = Distortion::from_named("plumb_bob", &[0.1, 0.0, 0.0, 0.0, 0.0, 0.3, 0.0, 0.0]);
        assert!(rational.unwrap_err().contains("rational"));
        assert_eq!(
            Distortion::from_named("fisheye", &[-0.013, 0.021, -0.017, 0.004]).unwrap(),
            FISHEYE
        );
        assert!(Distortion::from_named("equidistant", &[0.1, 0.2]).is_err());
        assert!(Distortion::from_named("rational_polynomial", &[0.0; 8])
            .unwrap_err()
            .contains("unknown distortion model"));
        assert!(Distortion::from_named("plumb_bob", &[f64::NAN, 0.0, 0.0, 0.0]).is_err());
        assert_eq!(
            Distortion::from_named("plumb_bob", &[0.0; 5]).unwrap(),
            Distortion::None
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2000, rng_seed: proptest::test_runner::RngSeed::Fixed(11), ..ProptestConfig::default() })]

        /// Every ray within the TUM camera's 640x480 image maps there and back.
        #[test]
        fn radial_tangential_round_trip(x in -0.63f64..0.63, y in -0.49f64..0.49) {
            let (xd, yd) = TUM_FR2.distort(x, y);
            let (x2, y2) = TUM_FR2.undistort(xd, yd).unwrap();
            prop_assert!((x - x2).abs() < 1e-9 && (y - y2).abs() < 1e-9, "{x} {y} -> {x2} {y2}");
        }

        /// Every ray up to 80° from the axis maps there and back.
        #[test]
        fn equidistant_round_trip(theta in 0.0f64..80f64.to_radians(), phi in -3.2f64..3.2) {
            let r = theta.tan();
            let (x, y) = (r * phi.cos(), r * phi.sin());
            let (xd, yd) = FISHEYE.distort(x, y);
            let (x2, y2) = FISHEYE.undistort(xd, yd).unwrap();
            prop_assert!((x - x2).abs() < 1e-8 * r.max(1.0) && (y - y2).abs() < 1e-8 * r.max(1.0));
        }
    }

    #[test]
    fn a_folding_lens_answers_only_on_its_monotonic_branch() {
        // r·(1 − 0.5 r²) peaks at r = √(2/3) (r' ≈ 0.544); beyond it no ray.
        let d = Distortion::RadialTangential {
            k1: -0.5,
            k2: 0.0,
            p1: 0.0,
            p2: 0.0,
            k3: 0.0,
        };
        let (x, _) = d.undistort(0.5, 0.0).unwrap();
        assert!(x < (2.0f64 / 3.0).sqrt());
        assert!(d.undistort(0.6, 0.0).is_none());
    }
}
