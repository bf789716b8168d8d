//! Pirouette: maps from a cheap camera, by vision-based pirouettes and
//! Radial Obstacle Profiles.
//!
//! This package is the `pirouette` command and a thin facade over the
//! library crates:
//! - [`geom`]: SE(2) poses and angles;
//! - [`camera`]: the paper's IPM and the pinhole model, pixel ↔ floor tables;
//! - [`profile`]: the Radial Obstacle Profile, rotation matching, sweeps;
//! - [`grid`]: the occupancy grid and map export;
//! - [`graph`]: SE(2) pose graphs and their sparse optimiser;
//! - [`register`]: registration of sweeps against the map;
//! - [`io`]: the `rop-dataset/1` format and other files;
//! - [`vision`]: floor segmentation and ROPs from images;
//! - [`sim`]: the renderer of scenes into datasets;
//! - the engine (`pirouette-slam`): [`frame`], the sensor-neutral input;
//!   [`pipeline`], a camera dataset's run; [`mapping`], its map; [`laser`],
//!   laser logs through the same registration and grid; [`localise`],
//!   place queries;
//! - [`eval`]: scores against truth; [`plot`]: pictures.
//!
//! ```no_run
//! use pirouette::io::Dataset;
//! let ds = Dataset::open("datasets/field-pirouette".as_ref())?;
//! let camera = ds.camera(None)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

pub use pirouette_camera as camera;
pub use pirouette_geom as geom;
pub use pirouette_graph as graph;
pub use pirouette_grid as grid;
pub use pirouette_io as io;
pub use pirouette_places as places;
pub use pirouette_profile as profile;
pub use pirouette_register as register;
pub use pirouette_sim as sim;
pub use pirouette_slam as slam;
pub use pirouette_slam::{frame, laser, localise, mapping, pipeline};
pub use pirouette_vision as vision;

pub mod camera_report;
pub mod eval;
pub mod plot;
