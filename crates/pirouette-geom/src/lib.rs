//! Shared geometric vocabulary of Pirouette: planar rigid poses and angles.
//!
//! - [`Pose2`]: an SE(2) transform, named by the frames it links
//!   (`world_from_robot * robot_from_camera` reads right to left).
//! - [`angle`]: wrapping and degree/radian helpers.
//! - [`Point2`]: a point in some planar frame.
//!
//! ```
//! use pirouette_geom::{Pose2, Point2};
//! let world_from_robot = Pose2::new(1.0, 2.0, std::f64::consts::FRAC_PI_2);
//! let in_world = world_from_robot.transform_point(Point2::new(1.0, 0.0));
//! assert!((in_world.x - 1.0).abs() < 1e-12 && (in_world.y - 3.0).abs() < 1e-12);
//! ```
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod angle;
mod pose;

pub use angle::{deg_to_rad, rad_to_deg, wrap_angle};
pub use pose::{Point2, Pose2};
