//! A log's run: its scans registered, then its grid; and what a run
//! returns.

use super::config::{check_config, LaserConfig};
use super::mapper::{Mapper, Matched};
use crate::frame::laser_frame;
use pirouette_geom::{Point2, Pose2};
use pirouette_graph::PoseGraph;
use pirouette_grid::{GridConfig, OccupancyGrid, BYTES_PER_CELL};
use pirouette_io::{open_laser_log, BagOptions, IoError, LaserScan, OdometrySource};
use pirouette_profile::Rop;

use crate::error::{Result, SlamError};
use crate::final_grid::FinalGrid;
use std::path::Path;

/// One registered scan.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanPose {
    /// The scan's position among the log's laser lines.
    pub scan: usize,
    /// Its timestamp, seconds.
    pub t: f64,
    /// Its registered pose in the map frame (the first scan's).
    pub pose: Pose2,
    /// Where the log's odometry for the step to it came from (`None`:
    /// the log held none).
    pub odometry: Option<OdometrySource>,
    /// Whether its registration was trusted (else the prior's mean).
    pub registered: bool,
    /// Whether another pose, apart from the one kept (beyond the revisit
    /// test's tolerances), explained the scan nearly as well (within its
    /// gap): a rival peak of the match, or without odometry another
    /// motion's match. The pose kept may be wrong.
    pub ambiguous: bool,
}

impl ScanPose {
    /// `"unmatched"` or `"ambiguous"` where the pose is not one trusted
    /// match, else `None`.
    pub fn trust(&self) -> Option<&'static str> {
        match (self.registered, self.ambiguous) {
            (false, _) => Some("unmatched"),
            (true, true) => Some("ambiguous"),
            (true, false) => None,
        }
    }
}

/// A scan as a radial obstacle profile (see [`laser_frame`]).
pub fn scan_profile(scan: &LaserScan, max_range_m: f32) -> Rop {
    laser_frame(scan, max_range_m).rop
}

/// A loop closure: a scan matched against the map of an earlier one.
#[derive(Debug, Clone, PartialEq)]
pub struct LoopClosure {
    /// The earlier scan.
    pub from: usize,
    /// The scan that came back.
    pub to: usize,
    /// Whether the place index found it (the estimate put the scan too far
    /// from the earlier one for the search near it).
    pub recognised: bool,
    /// Whether the graph's last solve used it: a match the solution
    /// contradicts is dropped, and one the newest loops' pairwise check
    /// finds inconsistent with the rest is left out.
    pub kept: bool,
}

/// A scan the motion filter left out of the local map and the graph,
/// placed by its match alone.
#[derive(Debug, Clone, PartialEq)]
pub struct SkippedScan {
    /// The scan's position in the log.
    pub scan: usize,
    /// Its timestamp, seconds.
    pub t: f64,
    /// Its pose in the map frame: matched against the local map that holds
    /// the registered scan before it, and moved with that scan by the pose
    /// graph.
    pub pose: Pose2,
}

/// A registered log: every scan's pose and the loops closed.
#[derive(Debug, Clone)]
pub struct RegisteredLog {
    /// Every scan registered, in log order; poses are the robot's (the
    /// laser's mount taken off).
    pub scans: Vec<ScanPose>,
    /// The scans the motion filter skipped, in log order.
    pub skipped: Vec<SkippedScan>,
    /// What the log's reader found (format, topics, the laser's mount,
    /// messages skipped).
    pub info: pirouette_io::LogInfo,
    /// The loop closures accepted by matching, kept or dropped by the graph.
    pub loops: Vec<LoopClosure>,
    /// Searches for a revisit made.
    pub loop_searches: usize,
    /// Places kept for revisits (see [`super::LoopConfig::keyframe_spacing_m`]).
    pub keyframes: usize,
    /// Times the pose graph was solved: only for loops that disagree with
    /// the poses (a χ² above 7.81 there), and once at the end for any left.
    pub solves: usize,
    /// The pose graph at its solution: a node per searched scan (every
    /// [`super::LoopConfig::every_scans`]th) and per scan that may be a keyframe,
    /// at its pose (every scan, without loop closure); an edge per run of
    /// steps between two nodes (their composed relative pose and
    /// covariance) and per loop kept.
    pub graph: PoseGraph,
    /// The scan of each node of `graph`.
    pub nodes: Vec<usize>,
}

impl RegisteredLog {
    /// Every scan read, registered or skipped: its position in the log,
    /// time and pose, in log order.
    pub fn every_scan(&self) -> Vec<(usize, f64, Pose2)> {
        let mut all: Vec<(usize, f64, Pose2)> = (self.scans.iter().map(|s| (s.scan, s.t, s.pose)))
            .chain(self.skipped.iter().map(|s| (s.scan, s.t, s.pose)))
            .collect();
        all.sort_by_key(|&(k, _, _)| k);
        all
    }
}

/// Matches every scan of a log (any [`open_laser_log`] reads) against a
/// local map of the scans registered before it; those that moved enough
/// (see [`MotionFilter`](super::MotionFilter)) are registered: the local map and the pose
/// graph take them, and loops are closed where the log comes back (see
/// [`LoopConfig`](super::LoopConfig)). The others keep their matched pose relative to the
/// registered scan before them. `progress` is called once per scan read.
pub fn register_log(
    path: &Path,
    config: &LaserConfig,
    options: &BagOptions,
    progress: &dyn Fn(),
) -> Result<RegisteredLog> {
    check_config(config)?;
    let mut m = Mapper::new(config)?;
    let mut meta: Vec<ScanPose> = Vec::new();
    // The odometry since the last registered scan (`None`: a step without).
    let mut since: Option<Pose2> = Some(Pose2::IDENTITY);
    let mut log = open_laser_log(path, options)?;
    for scan in &mut log {
        let scan = scan?;
        progress();
        let k = meta.len();
        let label = || match scan.line {
            0 => format!("{}: scan {}", path.display(), scan.scan),
            line => format!("{}: scan {} (line {line})", path.display(), scan.scan),
        };
        let frame = laser_frame(&scan, config.max_range_m);
        since = since.zip(frame.odometry()).map(|(a, o)| a * o);
        let (points, reg, ambiguous) = if k == 0 {
            (m.scan_points(&frame), None, false)
        } else {
            let Matched {
                points,
                registration: reg,
                ambiguous,
            } = m.matched(&frame, &label)?;
            // Matched near the last registered scan: the local map holds
            // what it sees.
            let relative = m.poses[k - 1].between(&reg.pose);
            if reg.accepted && !config.motion_filter.keeps(&relative) {
                m.skip(&scan, relative);
                continue;
            }
            (points, Some(reg), ambiguous)
        };
        let registered = m.take(k, points, reg.as_ref());
        meta.push(ScanPose {
            scan: scan.scan,
            t: scan.t,
            pose: Pose2::IDENTITY,
            odometry: since.filter(|_| k > 0).and(scan.odometry_source),
            registered,
            ambiguous,
        });
        since = Some(Pose2::IDENTITY);
        // Places kept, revisits searched, the graph solved.
        m.revisit(k)?;
    }
    if meta.is_empty() {
        return Err(SlamError::Input {
            problem:
                "no laser scan in the log (CARMEN: FLASER or ROBOTLASER1 lines; a bag: LaserScan messages)"
                    .into(),
        }
        .at(path.display().to_string()));
    }
    let info = log.info();
    let mut registered = m.finish(meta)?;
    // The laser's poses as the robot's: `M·L·M⁻¹` keeps the first at the origin.
    let (mount, unmount) = (info.mount, info.mount.inverse());
    for p in (registered.scans.iter_mut().map(|s| &mut s.pose))
        .chain(registered.skipped.iter_mut().map(|s| &mut s.pose))
    {
        *p = mount * *p * unmount;
    }
    registered.info = info;
    Ok(registered)
}

/// The grid settings for a registered log, known before any scan is
/// fused: `config.grid` where the map of the scans' poses fits its cell
/// budget, else its cells made 2, 4, 8, … times as wide until it fits, and
/// a warning naming the side used. Refused only where not even that fits
/// (poses kilometres apart, or not finite).
pub fn fitted_grid(registered: &RegisteredLog, config: &LaserConfig) -> Result<(GridConfig, Option<String>)> {
    let (lo, hi) = sensor_box(registered);
    let reach = f64::from(config.max_range_m);
    let asked = &config.grid;
    let fitted = asked.fitted(lo, hi, reach).ok_or(SlamError::Budget {
        max_cells: asked.max_cells,
        hint: "the poses lie too far apart for any cell size; the poses can still be written",
    })?;
    let warning = (fitted.resolution_m != asked.resolution_m).then(|| {
        format!(
            "the map of {:.0} × {:.0} m would need {:.0} million cells of {} cm, beyond the budget of {} million ({} MB): written with cells of {} cm instead",
            hi.x - lo.x + 2.0 * reach,
            hi.y - lo.y + 2.0 * reach,
            asked.cells_for(lo, hi, reach) / 1e6,
            asked.resolution_m * 100.0,
            asked.max_cells / 1_000_000,
            asked.max_cells * BYTES_PER_CELL / 1_000_000,
            fitted.resolution_m * 100.0
        )
    });
    Ok((fitted, warning))
}

/// The box of the laser's positions over a log's registered scans.
fn sensor_box(registered: &RegisteredLog) -> (Point2, Point2) {
    let mount = registered.info.mount;
    let mut lo = Point2::new(f64::INFINITY, f64::INFINITY);
    let mut hi = Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
    for s in &registered.scans {
        let c = (s.pose * mount).translation();
        (lo.x, lo.y, hi.x, hi.y) = (lo.x.min(c.x), lo.y.min(c.y), hi.x.max(c.x), hi.y.max(c.y));
    }
    (lo, hi)
}

/// The grid of a log's registered scans at the given robot poses (one
/// per registered scan, in log order), the log streamed again; its
/// settings `grid` (see [`fitted_grid`]), its cells stored at once.
pub fn grid_of_log(
    path: &Path,
    registered: &RegisteredLog,
    options: &BagOptions,
    config: &LaserConfig,
    grid: &GridConfig,
) -> Result<OccupancyGrid> {
    let at = || path.display().to_string();
    let (lo, hi) = sensor_box(registered);
    let mut grid = FinalGrid::covering(
        grid,
        0.0,
        "use coarser cells",
        (lo, hi),
        f64::from(config.max_range_m),
    )
    .map_err(|e| e.at(at()))?;
    let mount = registered.info.mount;
    let mut wanted = registered.scans.iter().peekable();
    for scan in open_laser_log(path, options)? {
        let scan = scan?;
        let Some(s) = wanted.next_if(|s| s.scan == scan.scan) else {
            continue;
        };
        let rop = laser_frame(&scan, config.max_range_m).rop;
        grid.insert(&(s.pose * mount), &rop).map_err(|e| e.at(at()))?;
    }
    if let Some(s) = wanted.next() {
        return Err(IoError::Invalid {
            path: path.to_owned(),
            problem: format!("scan {} registered but not found when read again", s.scan),
        }
        .into());
    }
    Ok(grid.finish())
}

/// The laser scans of a log, counted without keeping them.
pub fn count_scans(path: &Path, options: &BagOptions) -> Result<usize> {
    let mut n = 0;
    for scan in open_laser_log(path, options)? {
        scan?;
        n += 1;
    }
    Ok(n)
}
