//! Laser logs through the same engine: each scan a frame
//! ([`laser_frame`](crate::frame::laser_frame)) whose profile is registered against a local map of
//! the scans before it with the raw odometry as the prior, revisits
//! matched against the maps of earlier scans as loop edges of a pose
//! graph, and the grid made of the scans at the graph's poses.
//!
//! The log is streamed twice (registration, then the grid): memory holds
//! the poses, the thinned endpoints of the last few dozen scans (the local
//! map) and the keyframes' maps (one per half metre of ground, for
//! revisits), never the log's lines: a log that goes round the same
//! building for hours needs little more than one that goes round once.
//!
//! - [`config`]: the settings ([`LaserConfig`]) and their check.
//! - [`motion`]: the prior of each scan's pose, with odometry or without.
//! - `mapper`: the running state: the local map, the pose graph's nodes,
//!   the keyframes, loops closed.
//! - [`run`]: a log's run ([`register_log`], then [`fitted_grid`] and
//!   [`grid_of_log`]; [`crate::map`] runs them in turn) and what it
//!   returns.

pub mod config;
mod mapper;
pub mod motion;
mod revisits;
pub mod run;

pub use config::{check_config, LaserConfig, LoopConfig, MotionFilter, OdometryNoise, MAX_WINDOW_SCANS};
pub use motion::{blind_priors, step_prior, BlindMotion, MotionSoFar};
pub use run::{
    count_scans, fitted_grid, grid_of_log, register_log, scan_profile, LoopClosure, RegisteredLog, ScanPose,
    SkippedScan,
};
