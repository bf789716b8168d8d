//! Readers and writers for Pirouette's files.
//!
//! - [`Dataset`]: a camera dataset in `rop-dataset/1` format (manifest,
//!   frames, optional truth), read with every field checked.
//! - [`Manifest`], [`CameraSpec`], [`FrameSpec`], [`Motion`]: the manifest.
//! - [`ImageFolder`], [`Rig`]: a folder of a real camera's images with
//!   a stamps file, a calibration (ROS `camera_info` or OpenCV YAML) and
//!   optional odometry and truth, read as a dataset.
//! - [`World`], [`Obstacle`]: the scene of `truth/world.json`.
//! - [`TruthRop`]: a true radial profile of `truth/rop/`.
//! - [`write_map_dir`], [`read_ros_map`], [`read_poses`], [`PoseRecord`]:
//!   the folder of a map (ROS `map_server` files, picture, poses).
//! - [`read_g2o`], [`write_g2o`], [`write_pose_graph`], [`G2oGraph`]: 2D pose graphs in g2o's
//!   text format.
//! - [`CarmenReader`], [`LaserScan`]: CARMEN laser logs, streamed.
//! - [`open_laser_log`], [`LaserLog`], [`bag`]: any laser input (CARMEN,
//!   ROS 1 bags, ROS 2 bags in MCAP or sqlite3), streamed as scans.
//! - [`read_tum`], [`read_relations`]: TUM trajectories and the SLAM
//!   benchmark's relation files.
//! - [`read_place_index`], [`write_place_index`]: place index files
//!   (versioned header, checksum, postcard payload).
//! - [`atomic_write`]: every file is written to a temporary file, then
//!   renamed, so a crash never leaves a half-written file.
//!
//! ```no_run
//! use pirouette_io::Dataset;
//! let ds = Dataset::open("datasets/field-pirouette".as_ref())?;
//! println!("{} frames", ds.manifest.frames.len());
//! let first = ds.load_image(0)?;
//! assert_eq!(first.width(), ds.manifest.camera.width);
//! # Ok::<(), pirouette_io::IoError>(())
//! ```
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

mod atomic;
pub mod bag;
mod carmen;
mod dataset;
mod error;
mod g2o;
mod images;
mod map_dir;
mod places;
mod relations;
mod world;

pub use atomic::{atomic_write, atomic_write_with};
pub use bag::{open_laser_log, BagOptions, LaserLog, LogInfo};
pub use carmen::{CarmenReader, LaserScan, OdometrySource, FLASER_NO_RETURN_M, MAX_BEAMS, MAX_LINE_BYTES};
pub use dataset::{
    limits, CameraSpec, Dataset, FrameSpec, LensSpec, Manifest, Motion, MountSpec, MoveSpec, PinholeSpec,
    PoseSpec, TruthRop, FORMAT_VERSION, IN_PLACE_SHIFT_M,
};
pub use error::IoError;
pub use g2o::{parse_g2o, read_g2o, write_g2o, write_pose_graph, G2oGraph, MAX_ELEMENTS as G2O_MAX_ELEMENTS};
pub use images::{
    read_stamps, read_truth, ImageFolder, Rig, Selection, Stamped, TruthClock, TruthFrame, TruthTrack,
    RIG_FILE, RIG_FORMAT,
};
pub use map_dir::{
    names as map_names, read_poses, read_ros_map, write_map_dir, write_map_files, write_poses, write_tum,
    PoseRecord,
};
pub use places::{
    decode_place_index, read_place_index, write_place_index, PlaceIndexHeader, MAX_PLACE_INDEX_BYTES,
    OLDEST_PLACE_INDEX_FORMAT, PLACE_INDEX_FORMAT, PLACE_INDEX_HEADER_BYTES, PLACE_INDEX_MAGIC,
};
pub use relations::{read_relations, read_tum, Relation, StampedPose, MAX_TEXT_ROWS};
pub use world::{FootprintHit, Obstacle, World};
