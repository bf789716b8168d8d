//! SE(2) poses.

use crate::angle::wrap_angle;
use nalgebra::{Isometry2, Matrix3, Vector2};
use serde::{Deserialize, Serialize};
use std::ops::Mul;

/// A point in a planar frame, metres.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Point2 {
    /// First coordinate (forward in a robot frame), metres.
    pub x: f64,
    /// Second coordinate (left in a robot frame), metres.
    pub y: f64,
}

impl Point2 {
    /// A point from its coordinates.
    pub const fn new(x: f64, y: f64) -> Self {
        Self { x, y }
    }

    /// Distance from the frame origin.
    pub fn norm(self) -> f64 {
        self.x.hypot(self.y)
    }

    /// Distance to another point of the same frame.
    pub fn distance(self, other: Point2) -> f64 {
        (self.x - other.x).hypot(self.y - other.y)
    }

    /// Bearing from the frame origin, radians counter-clockwise from +x.
    pub fn bearing(self) -> f64 {
        self.y.atan2(self.x)
    }

    /// The point turned by `angle_rad` about the origin (any angle, not
    /// wrapped first).
    pub fn rotated(self, angle_rad: f64) -> Self {
        let (s, c) = angle_rad.sin_cos();
        Self::new(c * self.x - s * self.y, s * self.x + c * self.y)
    }

    /// The point at `range` along `bearing_rad` from the origin.
    pub fn from_polar(range: f64, bearing_rad: f64) -> Self {
        Self::new(range * bearing_rad.cos(), range * bearing_rad.sin())
    }
}

/// A rigid planar transform `a_from_b`: maps coordinates in frame `b` into
/// frame `a`. As a robot pose, `world_from_robot` holds the robot's position
/// and heading (counter-clockwise from world +x) in the world.
///
/// The heading is kept wrapped into `(-π, π]`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose2 {
    /// Translation x, metres.
    pub x: f64,
    /// Translation y, metres.
    pub y: f64,
    /// Rotation, radians, in `(-π, π]`.
    pub theta: f64,
}

impl Pose2 {
    /// The identity transform.
    pub const IDENTITY: Pose2 = Pose2 {
        x: 0.0,
        y: 0.0,
        theta: 0.0,
    };

    /// A pose from translation and rotation (radians, wrapped).
    pub fn new(x: f64, y: f64, theta: f64) -> Self {
        Self {
            x,
            y,
            theta: wrap_angle(theta),
        }
    }

    /// A pose from translation and a heading in degrees.
    pub fn from_deg(x: f64, y: f64, theta_deg: f64) -> Self {
        Self::new(x, y, theta_deg.to_radians())
    }

    /// The heading in degrees.
    pub fn theta_deg(&self) -> f64 {
        self.theta.to_degrees()
    }

    /// The translation as a point.
    pub fn translation(&self) -> Point2 {
        Point2::new(self.x, self.y)
    }

    /// The inverse transform: `b_from_a` for `a_from_b`.
    pub fn inverse(&self) -> Pose2 {
        let (s, c) = self.theta.sin_cos();
        Pose2::new(-(c * self.x + s * self.y), s * self.x - c * self.y, -self.theta)
    }

    /// Maps a point from frame `b` into frame `a`.
    pub fn transform_point(&self, p: Point2) -> Point2 {
        let (s, c) = self.theta.sin_cos();
        Point2::new(self.x + c * p.x - s * p.y, self.y + s * p.x + c * p.y)
    }

    /// Maps a direction (no translation) from frame `b` into frame `a`.
    pub fn rotate_vector(&self, v: Point2) -> Point2 {
        v.rotated(self.theta)
    }

    /// The relative transform `self⁻¹ · other`: for `world_from_a` and
    /// `world_from_b` it is `a_from_b`.
    pub fn between(&self, other: &Pose2) -> Pose2 {
        self.inverse() * *other
    }

    /// The matrix that turns an `(x, y, θ)` offset or covariance given in
    /// this pose's frame into its parent's: its rotation on the position,
    /// the heading unchanged (`R · Σ · Rᵀ` turns a covariance).
    pub fn tangent_rotation(&self) -> Matrix3<f64> {
        let (s, c) = self.theta.sin_cos();
        Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
    }

    /// A covariance of `(x, y, θ)` given in this pose's frame, in its
    /// parent's: `R · Σ · Rᵀ` with `R` the [`Pose2::tangent_rotation`].
    pub fn rotate_covariance(&self, covariance: &Matrix3<f64>) -> Matrix3<f64> {
        let r = self.tangent_rotation();
        r * covariance * r.transpose()
    }

    /// A covariance of `(x, y, θ)` given in the parent's frame, in this
    /// pose's: `Rᵀ · Σ · R` (the inverse of [`Pose2::rotate_covariance`]).
    pub fn unrotate_covariance(&self, covariance: &Matrix3<f64>) -> Matrix3<f64> {
        let r = self.tangent_rotation();
        r.transpose() * covariance * r
    }

    /// The adjoint: `T · Exp(ξ) · T⁻¹ = Exp(Ad(T) · ξ)` for a twist
    /// `ξ = (vₓ, v_y, ω)`. It carries an error taken on the right of `T`
    /// (in `T`'s frame) to one on the left (in the parent's).
    pub fn adjoint(&self) -> Matrix3<f64> {
        let (s, c) = self.theta.sin_cos();
        Matrix3::new(c, -s, self.y, s, c, -self.x, 0.0, 0.0, 1.0)
    }

    /// The Jacobians of `self * other`'s `(x, y, θ)` with respect to
    /// `self`'s and to `other`'s (each pose moved by adding to its
    /// components): `(J_self, J_other)`.
    pub fn compose_jacobians(&self, other: &Pose2) -> (Matrix3<f64>, Matrix3<f64>) {
        let (s, c) = self.theta.sin_cos();
        let j_self = Matrix3::new(
            1.0,
            0.0,
            -s * other.x - c * other.y,
            0.0,
            1.0,
            c * other.x - s * other.y,
            0.0,
            0.0,
            1.0,
        );
        (j_self, self.tangent_rotation())
    }

    /// The covariance of `self * other` to first order, the two poses'
    /// errors independent with covariances `of_self` and `of_other`.
    pub fn compose_covariance(
        &self,
        of_self: &Matrix3<f64>,
        other: &Pose2,
        of_other: &Matrix3<f64>,
    ) -> Matrix3<f64> {
        let (a, b) = self.compose_jacobians(other);
        a * of_self * a.transpose() + b * of_other * b.transpose()
    }

    /// As a nalgebra isometry, for linear-algebra code.
    pub fn to_isometry(&self) -> Isometry2<f64> {
        Isometry2::new(Vector2::new(self.x, self.y), self.theta)
    }

    /// From a nalgebra isometry.
    pub fn from_isometry(iso: &Isometry2<f64>) -> Self {
        Self::new(iso.translation.x, iso.translation.y, iso.rotation.angle())
    }

    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.theta.is_finite()
    }
}

impl Mul for Pose2 {
    type Output = Pose2;

    /// Composition: `a_from_b * b_from_c = a_from_c`.
    // Composing rotations adds their angles: the `+` is the group law.
    #[allow(clippy::suspicious_arithmetic_impl)]
    fn mul(self, rhs: Pose2) -> Pose2 {
        let t = self.transform_point(rhs.translation());
        Pose2::new(t.x, t.y, self.theta + rhs.theta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn close(a: &Pose2, b: &Pose2) -> bool {
        (a.x - b.x).abs() < 1e-9 && (a.y - b.y).abs() < 1e-9 && wrap_angle(a.theta - b.theta).abs() < 1e-9
    }

    fn pose() -> impl Strategy<Value = Pose2> {
        (-10.0f64..10.0, -10.0f64..10.0, -4.0f64..4.0).prop_map(|(x, y, t)| Pose2::new(x, y, t))
    }

    #[test]
    fn quarter_turn_moves_point() {
        let a_from_b = Pose2::new(1.0, 0.0, std::f64::consts::FRAC_PI_2);
        let p = a_from_b.transform_point(Point2::new(2.0, 0.0));
        assert!((p.x - 1.0).abs() < 1e-12 && (p.y - 2.0).abs() < 1e-12);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(11), ..ProptestConfig::default() })]

        #[test]
        fn inverse_composes_to_identity(p in pose()) {
            prop_assert!(close(&(p * p.inverse()), &Pose2::IDENTITY));
            prop_assert!(close(&(p.inverse() * p), &Pose2::IDENTITY));
        }

        #[test]
        fn composition_is_associative(a in pose(), b in pose(), c in pose()) {
            prop_assert!(close(&((a * b) * c), &(a * (b * c))));
        }

        #[test]
        fn composition_matches_nalgebra(a in pose(), b in pose()) {
            let ours = a * b;
            let theirs = Pose2::from_isometry(&(a.to_isometry() * b.to_isometry()));
            prop_assert!(close(&ours, &theirs));
        }

        #[test]
        fn between_recovers_relative(a in pose(), b in pose()) {
            prop_assert!(close(&(a * a.between(&b)), &b));
        }

        /// The composition's Jacobians are its derivatives (central
        /// differences), and the adjoint moves a small twist from the
        /// right of a pose to its left.
        #[test]
        fn composition_jacobians_and_adjoint_match_differences(a in pose(), b in pose()) {
            let h = 1e-6;
            let (ja, jb) = a.compose_jacobians(&b);
            let ad = a.adjoint();
            for d in 0..3 {
                let mut t = [0.0; 3];
                t[d] = h;
                let nudge = |p: &Pose2, sign: f64| Pose2::new(p.x + sign * t[0], p.y + sign * t[1], p.theta + sign * t[2]);
                let diff = |p: Pose2, q: Pose2| [(p.x - q.x) / (2.0 * h), (p.y - q.y) / (2.0 * h), wrap_angle(p.theta - q.theta) / (2.0 * h)];
                let by_a = diff(nudge(&a, 1.0) * b, nudge(&a, -1.0) * b);
                let by_b = diff(a * nudge(&b, 1.0), a * nudge(&b, -1.0));
                let twist = Pose2::new(t[0], t[1], t[2]);
                let moved = diff(a * twist * a.inverse(), a * twist.inverse() * a.inverse());
                for r in 0..3 {
                    prop_assert!((by_a[r] - ja[(r, d)]).abs() < 1e-5, "J_a ({r}, {d})");
                    prop_assert!((by_b[r] - jb[(r, d)]).abs() < 1e-5, "J_b ({r}, {d})");
                    prop_assert!((moved[r] - ad[(r, d)]).abs() < 1e-5, "Ad ({r}, {d})");
                }
            }
            let (sa, sb) = (Matrix3::from_diagonal(&nalgebra::Vector3::new(0.01, 0.02, 0.003)), Matrix3::identity() * 0.5);
            let sum = a.compose_covariance(&sa, &b, &sb);
            prop_assert!((sum - (ja * sa * ja.transpose() + jb * sb * jb.transpose())).norm() < 1e-12);
            let r = a.tangent_rotation();
            prop_assert!((a.rotate_covariance(&sb.scale(3.0)) - r * sb.scale(3.0) * r.transpose()).norm() < 1e-12);
            prop_assert!((a.unrotate_covariance(&a.rotate_covariance(&sa)) - sa).norm() < 1e-12);
        }

        /// A small step taken in the pose's frame lands, to first order,
        /// where the tangent rotation sends it; distance is what the
        /// transform keeps.
        #[test]
        fn tangent_rotation_turns_steps_and_distance_is_kept(a in pose(), b in pose(), p in pose()) {
            let step = nalgebra::Vector3::new(1e-7 * b.x, 1e-7 * b.y, 1e-7 * b.theta);
            let moved = a * Pose2::new(step.x, step.y, step.z);
            let turned = a.tangent_rotation() * step;
            prop_assert!((moved.x - a.x - turned.x).abs() < 1e-12);
            prop_assert!((moved.y - a.y - turned.y).abs() < 1e-12);
            prop_assert!((wrap_angle(moved.theta - a.theta) - turned.z).abs() < 1e-12);
            let (u, v) = (b.translation(), p.translation());
            let d = u.distance(v);
            prop_assert!((a.transform_point(u).distance(a.transform_point(v)) - d).abs() < 1e-9);
            prop_assert!((d - (u.x - v.x).hypot(u.y - v.y)).abs() == 0.0);
        }
    }
}
