//! The engine for every sensor: a camera dataset's sweeps and a laser
//! log's scans become frames (radial obstacle profiles and the motion
//! between them), registered against what came before, matched against
//! the places seen, joined in a pose graph and fused into one occupancy
//! grid.
//!
//! - [`map`]: the one entry, for either sensor's [`Input`]: settings
//!   checked, the map made, [`MapOutput`] returned to be written.
//! - [`frame`]: the sensor-neutral input: a frame per camera image or
//!   laser scan, and a camera dataset's sweeps ([`frame::DatasetSweep`]).
//! - [`pipeline`]: a camera dataset's run: profiles, verified turns and
//!   sweeps ([`pipeline::sweep_dataset`]), then its map
//!   ([`pipeline::map_dataset`]).
//! - [`mapping`]: the sweeps placed, refined and adjusted jointly, and the
//!   grid ([`mapping::build_map`]).
//! - [`laser`]: a laser log streamed scan by scan: each matched against a
//!   local submap, revisits closed as loops, the grid of the graph's poses
//!   ([`laser::register_log`], [`laser::grid_of_log`]).
//! - [`localise`]: place queries against an index of sweeps.
//! - [`submap`]: obstacle points and their field in the frame of an
//!   anchor pose that the graph moves.
//! - [`backend`]: the graph, the revisit test and the gated solve both
//!   sensors share.
//!
//! ```no_run
//! use pirouette_slam::{map, Config, Input, MapOutput};
//! let input = Input::open("intel.log".as_ref())?;
//! match map(input, &Config::default(), &|_stage| ())? {
//!     MapOutput::Laser(out) => println!("{} scans registered", out.registered.scans.len()),
//!     MapOutput::Camera { mapped, .. } => println!("{} frames placed", mapped.map.frame_poses.len()),
//! }
//! # Ok::<(), pirouette_slam::SlamError>(())
//! ```
#![deny(missing_docs)]

pub use backend::revisit;
pub use entry::{map, Config, Input, LaserOutput, MapOutput, Work};
pub use error::{Result, SlamError};

use std::path::Path;

pub mod backend;
mod entry;
mod error;
pub mod final_grid;
pub mod frame;
pub mod laser;
pub mod localise;
pub mod mapping;
pub mod pipeline;
pub mod submap;

/// The sensor whose input a path holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sensor {
    /// A camera dataset (`rop-dataset/1`): its folder or its `dataset.json`.
    Camera,
    /// A laser log: a CARMEN log, a ROS 1 bag, a ROS 2 bag's folder (with
    /// its `metadata.yaml`) or its storage file.
    Laser,
}

impl Sensor {
    /// Which sensor's input `path` holds, by its shape alone (the reader
    /// then checks its content): a ROS 2 bag's folder and any file but a
    /// JSON file are laser logs; a `dataset.json`, an image folder's rig
    /// file (any other `.json`) and any other folder are camera input.
    pub fn of(path: &Path) -> Sensor {
        let ros2_folder = path.join("metadata.yaml").is_file();
        let log_file = path.is_file() && path.extension().is_none_or(|e| e != "json");
        if ros2_folder || log_file {
            Sensor::Laser
        } else {
            Sensor::Camera
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_says_which_sensor_it_holds() {
        let dir = std::env::temp_dir().join(format!("pirouette-sensor-{}", std::process::id()));
        let ros2 = dir.join("ros2");
        std::fs::create_dir_all(&ros2).unwrap();
        std::fs::write(ros2.join("metadata.yaml"), "rosbag2_bagfile_information: {}\n").unwrap();
        std::fs::write(dir.join("dataset.json"), "{}").unwrap();
        std::fs::write(dir.join("intel.log"), "").unwrap();
        assert_eq!(Sensor::of(&dir), Sensor::Camera);
        assert_eq!(Sensor::of(&dir.join("dataset.json")), Sensor::Camera);
        std::fs::write(dir.join("rig.json"), "{}").unwrap();
        assert_eq!(Sensor::of(&dir.join("rig.json")), Sensor::Camera);
        assert_eq!(Sensor::of(&dir.join("intel.log")), Sensor::Laser);
        assert_eq!(Sensor::of(&ros2), Sensor::Laser);
        assert_eq!(Sensor::of(&ros2.join("metadata.yaml")), Sensor::Laser);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
