//! Bayesian occupancy grids (Moravec-Elfes, log-odds) built from radial
//! profiles, and their export as ROS `map_server` maps.
//!
//! - [`OccupancyGrid`]: the grid; it grows as the robot explores.
//! - [`GridConfig`]: resolution, prior, sensor model, clamping.
//! - [`traverse`]: the exact cells a segment passes through.
//! - [`RosMap`]: the trinary P5 PGM and YAML of `map_server`.
//!
//! The vision sensor model: along each bearing the robot saw, cells from
//! the blind distance up to the obstacle are free and the obstacle's cell
//! is occupied; cells beyond are unknown. The soft range limit: a range
//! beyond `max_range` (or nothing in sight) makes the cells up to
//! `max_range` free and marks no obstacle. Bearings outside the view are
//! untouched.
//!
//! ```
//! use pirouette_geom::Pose2;
//! use pirouette_grid::{GridConfig, OccupancyGrid};
//! use pirouette_profile::Rop;
//! let mut rop = Rop::covering(-0.5, 0.5, 1f64.to_radians(), 0.9)?;
//! rop.range_m.iter_mut().for_each(|r| *r = 0.5);
//! let mut grid = OccupancyGrid::new(GridConfig::default())?;
//! grid.insert_profile(&Pose2::IDENTITY, &rop, 0.1);
//! assert!(grid.probability_at(0.505, 0.0) > 0.5 && grid.probability_at(0.3, 0.0) < 0.5);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

mod export;
mod grid;
mod traverse;

pub use export::{RosMap, FREE, MAP_BORDER_CELLS, OCCUPIED, UNKNOWN};
pub use grid::{GridConfig, GridError, OccupancyGrid, BYTES_PER_CELL, FREE_THRESH, OCCUPIED_THRESH};
pub use traverse::traverse;
