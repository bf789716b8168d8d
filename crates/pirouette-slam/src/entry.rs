//! One entry for every sensor: [`map`] takes a camera dataset or a laser
//! log ([`Input`]), checks the settings for it and returns what to write
//! ([`MapOutput`]). Callers parse and print; the rules live here.

use crate::error::{Result, SlamError};
use crate::laser::{
    check_config, count_scans, fitted_grid, grid_of_log, register_log, LaserConfig, RegisteredLog,
};
use crate::mapping::progress_steps;
use crate::pipeline::{map_dataset, sweep_count, Mapped, PipelineConfig, Stage};
use crate::Sensor;
use pirouette_grid::OccupancyGrid;
use pirouette_io::bag::{log_kind, LogKind};
use pirouette_io::{BagOptions, Dataset};
use std::path::{Path, PathBuf};

/// Every setting of a map, for either sensor: each input takes its own.
#[derive(Debug, Clone, Default)]
pub struct Config {
    /// A camera dataset's run.
    pub camera: PipelineConfig,
    /// A laser log's run.
    pub laser: LaserConfig,
    /// Which topics of a bag hold the scans and the motion.
    pub bag: BagOptions,
}

/// What [`map`] maps: a camera dataset (read) or a laser log (streamed
/// from its file as it is mapped).
#[derive(Debug)]
pub enum Input {
    /// A camera dataset, its manifest read.
    Camera(Box<Dataset>),
    /// A laser log: a CARMEN log, a ROS 1 bag, a ROS 2 bag's folder or its
    /// storage file.
    Laser(PathBuf),
}

/// How much a run of [`map`] reports, stage by stage, where known
/// before the run: progress bars' lengths.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Work {
    /// [`Stage::Profiled`] reports (a camera's frames).
    pub profiled: usize,
    /// [`Stage::Placed`] reports (a camera map's steps).
    pub placed: usize,
    /// [`Stage::Scan`] reports (a laser log's scans), where counted
    /// cheaply (a CARMEN log; a bag's are known only once read).
    pub scans: Option<usize>,
}

/// What a map is: the camera's run, or a laser log's poses and grid;
/// each with its input.
pub enum MapOutput {
    /// A camera dataset's profiles, sweeps, poses and grid.
    Camera {
        /// The dataset mapped.
        dataset: Box<Dataset>,
        /// Its run.
        mapped: Box<Mapped>,
    },
    /// A laser log's.
    Laser(Box<LaserOutput>),
}

/// A mapped laser log. Its poses are there whatever befell the grid, so
/// that minutes of registration are never lost to it.
#[derive(Debug)]
pub struct LaserOutput {
    /// The log mapped.
    pub log: PathBuf,
    /// The scans' poses, the loops closed and the pose graph.
    pub registered: RegisteredLog,
    /// The occupancy grid, or why it could not be made.
    pub grid: std::result::Result<OccupancyGrid, SlamError>,
    /// Where the grid's cells are coarser than asked (the map would have
    /// outgrown its budget), what was done.
    pub coarsened: Option<String>,
}

impl Input {
    /// The input `path` holds, by its shape ([`Sensor::of`]): a camera
    /// dataset's manifest is read (its warnings in
    /// [`Dataset::warnings`]); a laser log is found, and read only by
    /// [`map`].
    pub fn open(path: &Path) -> Result<Input> {
        match Sensor::of(path) {
            Sensor::Camera => Ok(Input::Camera(Box::new(Dataset::open(path)?))),
            Sensor::Laser => {
                log_kind(path)?;
                Ok(Input::Laser(path.to_owned()))
            }
        }
    }

    /// Its sensor.
    pub fn sensor(&self) -> Sensor {
        match self {
            Input::Camera(_) => Sensor::Camera,
            Input::Laser(_) => Sensor::Laser,
        }
    }

    /// How much [`map`] will report (a CARMEN log is counted here, a
    /// cheap read).
    pub fn work(&self, config: &Config) -> Result<Work> {
        Ok(match self {
            Input::Camera(ds) => Work {
                profiled: ds.manifest.frames.len(),
                placed: progress_steps(sweep_count(ds)),
                scans: None,
            },
            Input::Laser(path) => Work {
                profiled: 0,
                placed: 0,
                scans: match log_kind(path)?.0 {
                    LogKind::Carmen => Some(count_scans(path, &config.bag)?),
                    _ => None,
                },
            },
        })
    }
}

/// Maps `input` with its sensor's settings of `config` (checked first,
/// before any image or scan is read); `progress` hears of each stage's
/// steps ([`Input::work`] says how many).
pub fn map(input: Input, config: &Config, progress: &(dyn Fn(Stage) + Sync)) -> Result<MapOutput> {
    match input {
        Input::Camera(dataset) => {
            let mapped = Box::new(map_dataset(&dataset, &config.camera, progress)?);
            Ok(MapOutput::Camera { dataset, mapped })
        }
        Input::Laser(path) => {
            check_config(&config.laser)?;
            let registered = register_log(&path, &config.laser, &config.bag, &|| progress(Stage::Scan))?;
            let at = |e: SlamError| e.at(path.display().to_string());
            let (grid, coarsened) = match fitted_grid(&registered, &config.laser) {
                Ok((fitted, coarsened)) => (
                    grid_of_log(&path, &registered, &config.bag, &config.laser, &fitted),
                    coarsened,
                ),
                Err(e) => (Err(at(e)), None),
            };
            Ok(MapOutput::Laser(Box::new(LaserOutput {
                log: path,
                registered,
                grid,
                coarsened,
            })))
        }
    }
}
