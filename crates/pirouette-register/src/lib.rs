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

mod correlative;
mod field;

pub use correlative::{register, thin_points, MotionNoise, PosePrior, RegisterConfig, Registration};
pub use field::LikelihoodField;

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
