//! Laser logs through the same engine: each scan a profile, registered
//! against a local map of the scans before it with the raw odometry as
//! the prior, and the grid made of the registered scans.
//!
//! The log is streamed twice (registration, then the grid), so memory
//! holds the poses and a local map, never the log.

use crate::geom::{Point2, Pose2};
use crate::grid::{GridConfig, OccupancyGrid};
use crate::io::{CarmenReader, IoError, LaserScan};
use crate::profile::Rop;
use crate::register::{endpoints, far_points, register, LikelihoodField, PosePrior, RegisterConfig};
use anyhow::{bail, Context, Result};
use std::collections::VecDeque;
use std::path::Path;

/// How far raw odometry may stray, one standard deviation.
#[derive(Debug, Clone, PartialEq)]
pub struct OdometryNoise {
    /// Position error per metre travelled.
    pub per_m: f64,
    /// Position error per radian turned, metres.
    pub m_per_rad: f64,
    /// Heading error per radian turned.
    pub per_rad: f64,
    /// Heading error per metre travelled, radians.
    pub rad_per_m: f64,
    /// Position error of any step, metres.
    pub floor_m: f64,
    /// Heading error of any step, radians.
    pub floor_rad: f64,
}

impl Default for OdometryNoise {
    /// A wheeled indoor robot's odometry at its worst: 20 % of the
    /// distance and 5 cm per radian turned; 20 % of the turn and 5° per
    /// metre; 5 cm and 3° whatever the step (logs are timestamped
    /// loosely, and wheels slip).
    fn default() -> Self {
        Self {
            per_m: 0.2,
            m_per_rad: 0.05,
            per_rad: 0.2,
            rad_per_m: 5f64.to_radians(),
            floor_m: 0.05,
            floor_rad: 3f64.to_radians(),
        }
    }
}

/// Settings of laser mapping.
#[derive(Debug, Clone)]
pub struct LaserConfig {
    /// The soft range limit of the map, metres: farther ranges say the
    /// way is free this far and mark no obstacle.
    pub max_range_m: f32,
    /// Registration matches ranges up to this far, metres (far walls pin
    /// the heading).
    pub reach_m: f64,
    /// The grid.
    pub grid: GridConfig,
    /// Side of the local map's likelihood lattice, metres.
    pub field_resolution_m: f64,
    /// Registration of a scan against the local map.
    pub register: RegisterConfig,
    /// The local map holds the endpoints of this many scans before.
    pub local_scans: usize,
    /// Raw odometry as a prior.
    pub odometry: OdometryNoise,
    /// The prior where the log holds no odometry for a step: the previous
    /// pose, this far off in position (metres, one σ) ...
    pub unknown_step_m: f64,
    /// ... and in heading (radians, one σ).
    pub unknown_step_rad: f64,
}

impl Default for LaserConfig {
    /// A 20 m map limit and 40 m registration reach (indoor scanners
    /// measure to a few centimetres that far); 5 cm cells for the grid and
    /// the local map; registration with a 5 cm Gaussian (the local map's
    /// cell), endpoints thinned to one per 5 cm, a window of at most
    /// ±2.5 m; the last 30 scans as the local map; a step without odometry
    /// searched ±3σ of 0.8 m and 25° (a metre and more apart, turns to
    /// about 60°).
    fn default() -> Self {
        Self {
            max_range_m: 20.0,
            reach_m: 40.0,
            grid: GridConfig {
                resolution_m: 0.05,
                ..GridConfig::default()
            },
            field_resolution_m: 0.05,
            register: RegisterConfig {
                sigma_m: 0.05,
                spacing_m: 0.05,
                max_window_m: 2.5,
                min_matched: 20,
                ..RegisterConfig::default()
            },
            local_scans: 30,
            odometry: OdometryNoise::default(),
            unknown_step_m: 0.8,
            unknown_step_rad: 25f64.to_radians(),
        }
    }
}

/// One registered scan.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanPose {
    /// The scan's position among the log's laser lines.
    pub scan: usize,
    /// Its timestamp, seconds.
    pub t: f64,
    /// Its registered pose in the map frame (the first scan's).
    pub pose: Pose2,
    /// The pose the log records for it, in the log's frame.
    pub recorded: Pose2,
    /// The pose by raw odometry alone, in the map frame.
    pub dead_reckoning: Pose2,
    /// Whether the log held odometry for the step to it.
    pub odometry: bool,
    /// Whether its registration was trusted (else the prior's mean).
    pub registered: bool,
}

/// A mapped log.
#[derive(Debug)]
pub struct LaserMap {
    /// Every scan, in log order.
    pub scans: Vec<ScanPose>,
    /// The occupancy grid.
    pub grid: OccupancyGrid,
}

/// A scan as a radial obstacle profile: one bin per beam, centred on it;
/// no-return beams read "nothing within the limit".
pub fn scan_profile(scan: &LaserScan, max_range_m: f32) -> Rop {
    let step = scan.beam_step_rad;
    let mut rop = Rop::empty(
        scan.first_bearing_rad - 0.5 * step,
        step,
        scan.ranges_m.len(),
        max_range_m,
    );
    rop.range_m.clone_from(&scan.ranges_m);
    rop
}

/// The prior of a scan's pose from the previous pose and the step's raw
/// odometry (`None`: the log holds none).
pub fn step_prior(previous: &Pose2, odometry: Option<&Pose2>, config: &LaserConfig) -> PosePrior {
    match odometry {
        Some(step) => {
            let n = &config.odometry;
            let (d, t) = (step.translation().norm(), step.theta.abs());
            let sigma_m = (n.per_m * d + n.m_per_rad * t).hypot(n.floor_m);
            PosePrior {
                mean: *previous * *step,
                sigma_forward_m: sigma_m,
                sigma_left_m: sigma_m,
                sigma_theta_rad: (n.per_rad * t + n.rad_per_m * d).hypot(n.floor_rad),
            }
        }
        None => PosePrior {
            mean: *previous,
            sigma_forward_m: config.unknown_step_m,
            sigma_left_m: config.unknown_step_m,
            sigma_theta_rad: config.unknown_step_rad,
        },
    }
}

/// The local map: the endpoints of the last scans, in the map frame.
struct LocalMap {
    scans: VecDeque<Vec<Point2>>,
    capacity: usize,
}

impl LocalMap {
    fn field(&self, config: &LaserConfig) -> LikelihoodField {
        let points: Vec<Point2> = self.scans.iter().flatten().copied().collect();
        let r = &config.register;
        LikelihoodField::from_points(&points, config.field_resolution_m, r.sigma_m, r.epsilon)
    }

    fn push(&mut self, pose: &Pose2, points: &[Point2]) {
        if self.scans.len() == self.capacity {
            self.scans.pop_front();
        }
        self.scans
            .push_back(points.iter().map(|p| pose.transform_point(*p)).collect());
    }
}

/// Checks the settings before any line is read.
pub fn check_config(config: &LaserConfig) -> Result<()> {
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if !(positive(f64::from(config.max_range_m)) && config.reach_m >= f64::from(config.max_range_m)) {
        bail!(
            "the map limit {} m must be positive and the reach {} m at least as far",
            config.max_range_m,
            config.reach_m
        );
    }
    if !(positive(config.field_resolution_m)
        && positive(config.unknown_step_m)
        && positive(config.unknown_step_rad))
    {
        bail!("the local map's cell and the unknown step's spreads must be positive");
    }
    if config.local_scans == 0 {
        bail!("the local map must hold at least one scan");
    }
    OccupancyGrid::new(config.grid.clone()).context("grid settings")?;
    Ok(())
}

/// Registers every scan of a log: the poses, in log order. `progress` is
/// called once per scan.
pub fn register_log(path: &Path, config: &LaserConfig, progress: &dyn Fn()) -> Result<Vec<ScanPose>> {
    check_config(config)?;
    let mut local = LocalMap {
        scans: VecDeque::new(),
        capacity: config.local_scans,
    };
    let mut out: Vec<ScanPose> = Vec::new();
    // The log's frame to the map frame: the first scan's recorded pose.
    let mut origin = None;
    for scan in CarmenReader::open(path)? {
        let scan = scan?;
        let rop = scan_profile(&scan, config.max_range_m);
        let mut points = endpoints(&rop);
        points.extend(far_points(&rop, config.reach_m));
        let (pose, dead_reckoning, registered) = match out.last() {
            None => {
                origin = Some(scan.recorded);
                (Pose2::default(), Pose2::default(), true)
            }
            Some(previous) => {
                let prior = step_prior(&previous.pose, scan.odometry.as_ref(), config);
                let field = local.field(config);
                let reg = register(&field, &points, &prior, &config.register).with_context(|| {
                    format!("{}: scan {} (line {})", path.display(), scan.scan, scan.line)
                })?;
                let dead = previous.dead_reckoning * scan.odometry.unwrap_or_default();
                (reg.pose, dead, reg.accepted)
            }
        };
        local.push(&pose, &points);
        let recorded = match origin {
            Some(o) => o.between(&scan.recorded),
            None => scan.recorded,
        };
        out.push(ScanPose {
            scan: scan.scan,
            t: scan.t,
            pose,
            recorded,
            dead_reckoning,
            odometry: scan.odometry.is_some(),
            registered,
        });
        progress();
    }
    if out.is_empty() {
        bail!(
            "{}: no laser scan (FLASER or ROBOTLASER1 line) in the log",
            path.display()
        );
    }
    Ok(out)
}

/// The grid of a log's scans at the given poses (one per scan, in log
/// order), the log streamed again.
pub fn grid_of_log(path: &Path, poses: &[Pose2], config: &LaserConfig) -> Result<OccupancyGrid> {
    let mut grid = OccupancyGrid::new(config.grid.clone()).context("grid settings")?;
    let mut used = 0;
    for (scan, pose) in CarmenReader::open(path)?.zip(poses) {
        let scan = scan?;
        grid.insert_profile(pose, &scan_profile(&scan, config.max_range_m), 0.0);
        used += 1;
    }
    if used != poses.len() {
        return Err(IoError::Invalid {
            path: path.to_owned(),
            problem: format!("{used} scans where registration read {}", poses.len()),
        }
        .into());
    }
    if grid.overflowed() {
        bail!(
            "{}: the map outgrew its budget of {} cells; use coarser cells",
            path.display(),
            config.grid.max_cells
        );
    }
    Ok(grid)
}

/// Maps a log: registration, then the grid. `progress` is called once per
/// scan registered.
pub fn map_log(path: &Path, config: &LaserConfig, progress: &dyn Fn()) -> Result<LaserMap> {
    let scans = register_log(path, config, progress)?;
    let poses: Vec<Pose2> = scans.iter().map(|s| s.pose).collect();
    let grid = grid_of_log(path, &poses, config)?;
    Ok(LaserMap { scans, grid })
}

/// The laser scans of a log, counted without keeping them.
pub fn count_scans(path: &Path) -> Result<usize> {
    let mut n = 0;
    for scan in CarmenReader::open(path)? {
        scan?;
        n += 1;
    }
    Ok(n)
}
