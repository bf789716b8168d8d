//! The engine for every sensor: a camera dataset's sweeps and a laser
//! log's scans become frames (radial obstacle profiles and the motion
//! between them), registered against what came before, matched against
//! the places seen, joined in a pose graph and fused into one occupancy
//! grid.
//!
//! - [`frame`]: the sensor-neutral input: a frame per camera image or
//!   laser scan, and a camera dataset's sweeps ([`frame::DatasetSweep`]).
//! - [`pipeline`]: a camera dataset's run: profiles, verified turns and
//!   sweeps ([`pipeline::sweep_dataset`]), then its map
//!   ([`pipeline::map_dataset`]).
//! - [`mapping`]: the sweeps placed, refined and adjusted jointly, and the
//!   grid ([`mapping::build_map`]).
//! - [`laser`]: a laser log streamed scan by scan: each matched against a
//!   local submap, revisits closed as loops, the grid of the graph's poses
//!   ([`laser::map_log`]).
//! - [`localise`]: place queries against an index of sweeps.
//!
//! ```no_run
//! use pirouette_io::BagOptions;
//! use pirouette_slam::laser::{map_log, LaserConfig};
//! let map = map_log("intel.log".as_ref(), &LaserConfig::default(), &BagOptions::default(), &|| ())?;
//! println!("{} scans registered", map.registered.scans.len());
//! # Ok::<(), anyhow::Error>(())
//! ```
#![deny(missing_docs)]

pub mod frame;
pub mod laser;
pub mod localise;
pub mod mapping;
pub mod pipeline;
