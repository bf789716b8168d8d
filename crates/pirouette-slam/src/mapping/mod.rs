//! Maps of whole datasets: sweeps registered one after another against the
//! map built so far, then fused into one occupancy grid.
//!
//! - [`config`]: the settings ([`MapConfig`]).
//! - [`build`]: the run ([`build_map`]) and what it returns.
//! - `placed`: a sweep as placed, in blocks of frames turns join.
//! - `chain`, `fields`, `adjust`: frames' headings chained about a sweep's
//!   centre, the fields registration matches against, the joint adjustment.
//! - [`revisits`]: revisits the place index recognises.
//! - [`route`]: the commanded route alone, and maps of given poses.

mod adjust;
pub mod build;
mod chain;
pub mod config;
mod fields;
mod placed;
pub mod revisits;
pub mod route;

pub use build::{build_map, progress_steps, MapRun, SweepPose};
pub use config::MapConfig;
pub use route::{check_extent, dead_reckoning, map_with_poses};
