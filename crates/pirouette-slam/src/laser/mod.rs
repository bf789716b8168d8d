//! Laser logs through the same engine: each scan a frame
//! ([`laser_frame`]) whose profile is registered against a local map of
//! the scans before it with the raw odometry as the prior, revisits
//! matched against the maps of earlier scans as loop edges of a pose
//! graph, and the grid made of the scans at the graph's poses.
//!
//! The log is streamed twice (registration, then the grid): memory holds
//! the poses, the thinned endpoints of the last few dozen scans (the local
//! map) and the keyframes' maps (one per half metre of ground, for
//! revisits), never the log's lines: a log that goes round the same
//! building for hours needs little more than one that goes round once.

use crate::frame::{laser_frame, Frame};
use crate::mapping::graph::{information, Edge as MeasuredEdge, EDGE_GATE};
use anyhow::{bail, Context, Result};
use nalgebra::{Matrix3, Vector3};
use nodes::Nodes;
use pirouette_geom::{Point2, Pose2};
use pirouette_graph::{optimise, Edge as GraphEdge, Kernel, OptimiseConfig, PoseGraph};
use pirouette_grid::{GridConfig, OccupancyGrid};
use pirouette_io::{open_laser_log, BagOptions, IoError, LaserScan, OdometrySource};
use pirouette_profile::Rop;
use pirouette_register::{
    endpoints, far_points, register, thin_points, LikelihoodField, PosePrior, RegisterConfig, RegisterError,
    Registration,
};
use revisits::{Keyframes, Track};
use std::collections::VecDeque;
use std::path::Path;

mod nodes;
mod revisits;

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
    /// Where the log holds no odometry for a step, the robot may have
    /// stood or moved a little: the previous pose, this far off in
    /// position (metres, one σ) ...
    pub unknown_step_m: f64,
    /// ... and in heading (radians, one σ); ...
    pub unknown_step_rad: f64,
    /// ... it may have turned in place through any angle: the previous
    /// position, this far off (metres, one σ); ...
    pub unknown_turn_m: f64,
    /// ... or repeated its last step, or driven on as far as it last
    /// drove, off by this much. The most probable of the matches is kept
    /// (see [`blind_priors`]).
    pub unknown_repeat: OdometryNoise,
    /// Loop closure.
    pub loops: LoopConfig,
    /// Which scans are registered.
    pub motion_filter: MotionFilter,
}

/// Which scans the local map and the pose graph take. Every scan is
/// matched against the local map (from the pose of the scan before it,
/// moved by the odometry); one whose matched pose lies less than both
/// limits from the last scan taken adds nothing the local map does not
/// hold, and keeps its matched pose relative to that scan. A scan whose
/// match is not trusted is always taken.
#[derive(Debug, Clone, PartialEq)]
pub struct MotionFilter {
    /// Distance, metres.
    pub min_step_m: f64,
    /// Turn, radians.
    pub min_turn_rad: f64,
}

impl Default for MotionFilter {
    /// 10 cm or 5°: two cells of the local map, and a turn that moves an
    /// endpoint 1 m out by under two cells.
    fn default() -> Self {
        Self {
            min_step_m: 0.1,
            min_turn_rad: 5f64.to_radians(),
        }
    }
}

impl MotionFilter {
    /// Whether a step moved enough for its scan to be taken.
    pub fn keeps(&self, step: &Pose2) -> bool {
        step.translation().norm() >= self.min_step_m || step.theta.abs() >= self.min_turn_rad
    }
}

/// Settings of loop closure: which places are kept, how revisits are
/// searched, and when a match becomes an edge of the pose graph.
#[derive(Debug, Clone, PartialEq)]
pub struct LoopConfig {
    /// Every this many scans, the scan is searched for among the earlier
    /// ones (0: no loop closure).
    pub every_scans: usize,
    /// Only scans at least this far back along the path, metres (nearer
    /// ones are in the local map already).
    pub min_separation_m: f64,
    /// Keyframes within this distance of the estimated pose are
    /// candidates, metres ...
    pub radius_m: f64,
    /// ... widened by this share of the path since the keyframe (drift
    /// grows with it) ...
    pub radius_per_m: f64,
    /// ... up to this, metres.
    pub max_radius_m: f64,
    /// Heading spread of the search, radians (one σ; searched ±3σ).
    pub sigma_rad: f64,
    /// A keyframe's map is its scan and this many on each side.
    pub anchor_scans: usize,
    /// A scan becomes a keyframe (a place kept for revisits) when no
    /// keyframe lies this close to it, metres: the places kept grow with
    /// the ground covered, not with the log's length. At most `radius_m`,
    /// so that a revisit has a keyframe within the search near it.
    pub keyframe_spacing_m: f64,
    /// At most this many candidates per search (the nearest, each at
    /// least `min_separation_m` along the path from the others).
    pub max_candidates: usize,
    /// A match counts when at least this share of the scan's endpoints
    /// lie on the candidate's map ...
    pub min_matched_share: f64,
    /// ... and no rival pose scores within this many nats of the best (a
    /// rival: a peak farther from the best than `confirm_m` or
    /// `confirm_rad`, the tolerance within which two matches agree).
    pub min_rival_gap_ln: f64,
    /// Where no keyframe lies near the estimate and the estimate may be
    /// lost (a step since the last loop closed was not registered, or the
    /// path since then is long enough for drift to exceed `max_radius_m`),
    /// up to this many keyframes that the place index finds by view are
    /// tried (0: none) ...
    pub index_candidates: usize,
    /// ... those whose view differs from the local map's by at most this
    /// RMS, metres ...
    pub max_profile_rms_m: f64,
    /// ... each searched within ±3 of this σ of its position, metres; a
    /// match counts once the next search's match (at most two searches
    /// on) moves the estimate the same way ...
    pub index_sigma_m: f64,
    /// ... within this distance, metres ...
    pub confirm_m: f64,
    /// ... and within this heading, radians.
    pub confirm_rad: f64,
}

impl Default for LoopConfig {
    /// A keyframe (its scan and 10 each side) wherever none lies within
    /// 0.5 m; every 5th scan searched among the keyframes 8 m or more back
    /// along the path, within 0.5 m plus 2 % of the path since (at most
    /// 3 m) and ±15° of the estimate; up to 2 candidates; a match with
    /// 60 % of the endpoints on the map and no rival (a peak over 0.3 m or
    /// 5° from the best) within 10 nats. Where
    /// the estimate may be lost, the 2 keyframes whose views the place
    /// index finds within 1 m RMS of the local map's, each searched
    /// ±1.5 m about it; such a match counts once the next one moves the
    /// estimate the same way within 0.3 m and 5°.
    fn default() -> Self {
        Self {
            every_scans: 5,
            min_separation_m: 8.0,
            radius_m: 0.5,
            radius_per_m: 0.02,
            max_radius_m: 3.0,
            sigma_rad: 5f64.to_radians(),
            anchor_scans: 10,
            keyframe_spacing_m: 0.5,
            max_candidates: 2,
            min_matched_share: 0.6,
            min_rival_gap_ln: 10.0,
            index_candidates: 2,
            max_profile_rms_m: 1.0,
            index_sigma_m: 0.5,
            confirm_m: 0.3,
            confirm_rad: 5f64.to_radians(),
        }
    }
}

impl Default for LaserConfig {
    /// A 20 m map limit and 40 m registration reach (indoor scanners
    /// measure to a few centimetres that far); 5 cm cells for the grid and
    /// the local map; registration with a 5 cm Gaussian (the local map's
    /// cell), endpoints thinned to one per 5 cm, a window of at most
    /// ±2.5 m; the last 30 scans as the local map; a step without odometry
    /// searched as a stand of ±3σ of 0.8 m and 25° (a metre and more
    /// apart, turns to about 60°), a turn in place within 25 cm (σ), and
    /// a repeat of the last step (or a drive on after a turn) off by 20 %
    /// of its length plus 10 cm per radian (at least 10 cm) and 30 % of
    /// its turn plus 4° per metre (at least 4°).
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
            unknown_turn_m: 0.25,
            unknown_repeat: OdometryNoise {
                per_m: 0.2,
                m_per_rad: 0.1,
                per_rad: 0.3,
                rad_per_m: 4f64.to_radians(),
                floor_m: 0.1,
                floor_rad: 4f64.to_radians(),
            },
            loops: LoopConfig::default(),
            motion_filter: MotionFilter::default(),
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
    /// Where the log's odometry for the step to it came from (`None`:
    /// the log held none).
    pub odometry: Option<OdometrySource>,
    /// Whether its registration was trusted (else the prior's mean).
    pub registered: bool,
}

/// A mapped log.
#[derive(Debug)]
pub struct LaserMap {
    /// The scans' poses and the loops closed.
    pub registered: RegisteredLog,
    /// The occupancy grid.
    pub grid: OccupancyGrid,
}

/// A scan as a radial obstacle profile (see [`laser_frame`]).
pub fn scan_profile(scan: &LaserScan, max_range_m: f32) -> Rop {
    laser_frame(scan, max_range_m).rop
}

/// The prior of a scan's pose from the previous pose and the step's raw
/// odometry (`None`: the log holds none; the first of [`blind_priors`]).
pub fn step_prior(previous: &Pose2, odometry: Option<&Pose2>, config: &LaserConfig) -> PosePrior {
    match odometry {
        Some(step) => moved_by(previous, step, &config.odometry),
        None => blind_priors(previous, &MotionSoFar::default(), config)[0].1,
    }
}

/// `previous` moved by `step`, measured with `noise`.
fn moved_by(previous: &Pose2, step: &Pose2, noise: &OdometryNoise) -> PosePrior {
    let n = noise;
    let (d, t) = (step.translation().norm(), step.theta.abs());
    let sigma_m = (n.per_m * d + n.m_per_rad * t).hypot(n.floor_m);
    PosePrior {
        mean: *previous * *step,
        sigma_forward_m: sigma_m,
        sigma_left_m: sigma_m,
        sigma_theta_rad: (n.per_rad * t + n.rad_per_m * d).hypot(n.floor_rad),
    }
}

/// What a log without odometry tells of the robot's motion: its matched
/// steps so far.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MotionSoFar {
    /// The newest scan's matched step from the scan before it (`None`
    /// where that match was not trusted).
    pub last_step: Option<Pose2>,
    /// The distance of the last step that drove (moved farther than
    /// [`LaserConfig::unknown_step_m`]), metres.
    pub last_drive_m: Option<f64>,
}

impl MotionSoFar {
    /// After a step matched as `step` (`None`: not trusted).
    pub fn after(self, step: Option<Pose2>, config: &LaserConfig) -> Self {
        let drive = step
            .map(|s| s.translation().norm())
            .filter(|&d| d > config.unknown_step_m);
        Self {
            last_step: step,
            last_drive_m: drive.or(self.last_drive_m),
        }
    }
}

/// A motion a robot may have made over a step the log holds no odometry
/// for (see [`blind_priors`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BlindMotion {
    /// Stood, or moved a little.
    Stood,
    /// Turned in place through any angle.
    Turned,
    /// Repeated its last matched step.
    Repeated,
    /// Drove straight on as far as it last drove.
    DroveOn,
}

impl BlindMotion {
    /// Whether the motion keeps the robot's course (it stood or went on
    /// as it was going); the others break it.
    pub fn keeps_course(self) -> bool {
        matches!(self, BlindMotion::Stood | BlindMotion::Repeated)
    }
}

/// The priors of a step the log holds no odometry for, one per motion a
/// robot may have made since the previous scan: stood or moved a little
/// ([`LaserConfig::unknown_step_m`]); turned in place through any angle;
/// repeated its last step (a robot keeps its speed and turn rate from scan
/// to scan); or, where that step did not drive, driven straight on as far
/// as it last drove (a robot that moves by turns in place and straight
/// moves, as the paper's, drives on after a turn). The first is always
/// [`BlindMotion::Stood`].
pub fn blind_priors(
    previous: &Pose2,
    motion: &MotionSoFar,
    config: &LaserConfig,
) -> Vec<(BlindMotion, PosePrior)> {
    let mut priors = vec![
        (
            BlindMotion::Stood,
            PosePrior {
                mean: *previous,
                sigma_forward_m: config.unknown_step_m,
                sigma_left_m: config.unknown_step_m,
                sigma_theta_rad: config.unknown_step_rad,
            },
        ),
        (
            BlindMotion::Turned,
            PosePrior {
                mean: *previous,
                sigma_forward_m: config.unknown_turn_m,
                sigma_left_m: config.unknown_turn_m,
                sigma_theta_rad: std::f64::consts::FRAC_PI_3,
            },
        ),
    ];
    let noise = &config.unknown_repeat;
    priors.extend(
        motion
            .last_step
            .map(|step| (BlindMotion::Repeated, moved_by(previous, &step, noise))),
    );
    let drove = motion
        .last_step
        .is_some_and(|s| s.translation().norm() > config.unknown_step_m);
    if !drove {
        let on = motion.last_drive_m.map(|d| Pose2::new(d, 0.0, 0.0));
        priors.extend(on.map(|step| (BlindMotion::DroveOn, moved_by(previous, &step, noise))));
    }
    priors
}

/// Whether `pose` lies within a cell (or a degree) of the edge of the
/// window [`register`] searched about `prior`.
fn at_window_edge(prior: &PosePrior, pose: &Pose2, config: &RegisterConfig, cell_m: f64) -> bool {
    let w = prior.window(config);
    let turn = pirouette_geom::wrap_angle(pose.theta - prior.mean.theta);
    (pose.x - prior.mean.x).abs() >= w.half_x - cell_m
        || (pose.y - prior.mean.y).abs() >= w.half_y - cell_m
        || turn.abs() >= w.half_t - 1f64.to_radians()
}

/// The most scans a local map or a keyframe's map (each side) may hold:
/// their endpoints are kept in memory.
pub const MAX_WINDOW_SCANS: usize = 10_000;

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
        && positive(config.unknown_step_rad)
        && positive(config.unknown_turn_m))
    {
        bail!("the local map's cell and the unknown step's spreads must be positive");
    }
    for (what, n) in [
        ("odometry", &config.odometry),
        ("repeated step", &config.unknown_repeat),
    ] {
        let rates = [n.per_m, n.m_per_rad, n.per_rad, n.rad_per_m];
        if !(rates.iter().all(|v| v.is_finite() && *v >= 0.0) && positive(n.floor_m) && positive(n.floor_rad))
        {
            bail!("the {what} noise's rates must be zero or more and its floors positive: {n:?}");
        }
    }
    if !(1..=MAX_WINDOW_SCANS).contains(&config.local_scans) || config.loops.anchor_scans > MAX_WINDOW_SCANS {
        bail!(
            "the local map must hold 1 to {MAX_WINDOW_SCANS} scans, a keyframe's map at most that many each side (given {} and {})",
            config.local_scans,
            config.loops.anchor_scans
        );
    }
    let l = &config.loops;
    let spreads = [
        l.min_separation_m,
        l.radius_m,
        l.max_radius_m,
        l.sigma_rad,
        l.keyframe_spacing_m,
        l.max_profile_rms_m,
        l.index_sigma_m,
        l.confirm_m,
        l.confirm_rad,
    ];
    if !(spreads.into_iter().all(positive) && l.radius_per_m.is_finite() && l.radius_per_m >= 0.0) {
        bail!("loop closure's distances, spreads and tolerances must be positive: {l:?}");
    }
    let f = &config.motion_filter;
    if !(f.min_step_m.is_finite()
        && f.min_step_m >= 0.0
        && f.min_turn_rad.is_finite()
        && f.min_turn_rad >= 0.0)
    {
        bail!("the motion filter's limits must be zero or more: {f:?}");
    }
    OccupancyGrid::new(config.grid.clone()).context("grid settings")?;
    Ok(())
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
    /// Whether the pose graph kept it (a match the rest of the graph
    /// contradicts is dropped).
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
    /// Places kept for revisits (see [`LoopConfig::keyframe_spacing_m`]).
    pub keyframes: usize,
    /// Times the pose graph was solved: only for loops that disagree with
    /// the poses (a χ² above 7.81 there), and once at the end for any left.
    pub solves: usize,
    /// The pose graph at its solution: a node per searched scan (every
    /// [`LoopConfig::every_scans`]th) and per scan that may be a keyframe,
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

/// The running state of registration: the poses, the path length to
/// each, the pose graph's edges, the thinned endpoints (in their own
/// frame) of the last scans (the local map's and the newest keyframe's),
/// and the keyframes.
struct Mapper<'c> {
    config: &'c LaserConfig,
    /// The endpoints of scans `first..first + recent.len()`.
    recent: VecDeque<Vec<Point2>>,
    first: usize,
    /// Every scan's current pose.
    poses: Vec<Pose2>,
    /// The pose graph over the node scans.
    nodes: Nodes,
    along_m: Vec<f64>,
    keyframes: Keyframes,
    loops: Vec<(LoopClosure, usize)>,
    /// Whether a step since the last loop closed was not registered.
    lost: bool,
    /// The path length at the last loop closed, metres.
    closed_at_m: f64,
    /// Whether loop edges were added since the graph was last solved ...
    unsolved: bool,
    /// ... and whether one of them disagreed with the poses (see
    /// [`SOLVE_GATE`]).
    disagree: bool,
    /// Times the graph was solved.
    solves: usize,
    /// Skipped scans placed: each relative to the registered scan before.
    placed: Vec<Placed>,
    /// The newest scan's pose relative to the last registered one (the
    /// identity where that is the newest): the next scan's prior starts
    /// there.
    newest: Pose2,
    /// The steps matched so far, for steps without odometry.
    motion: MotionSoFar,
    /// The local map's likelihood field while the scans and poses it was
    /// made of stand (a scan registered or a graph solved drops it).
    field: Option<LikelihoodField>,
}

/// A skipped scan placed against the registered scan before it.
struct Placed {
    scan: usize,
    t: f64,
    /// The registered scan before it (its place among those registered).
    anchor: usize,
    /// Its pose in that scan's frame.
    relative: Pose2,
}

/// A loop edge whose squared Mahalanobis residual at the current poses is
/// at most this (three degrees of freedom, 95 %) agrees with them within
/// its noise: solving the graph for it would move the poses by less than
/// the match measures, so the solve waits for a loop that disagrees (or
/// the log's end). Revisits of ground already closed then cost nothing,
/// and the solves grow with the corrections, not with the revisits.
const SOLVE_GATE: f64 = 7.81;

/// The least spread of a step's or a loop's measured relative pose, one
/// σ: registration's posterior can claim less than a laser's range noise
/// and the local map's own error support.
const EDGE_FLOOR_M: f64 = 0.01;
/// The same for heading, radians.
const EDGE_FLOOR_RAD: f64 = 0.004;

/// The floors' covariance.
fn edge_floor() -> Matrix3<f64> {
    Matrix3::from_diagonal(&Vector3::new(
        EDGE_FLOOR_M.powi(2),
        EDGE_FLOOR_M.powi(2),
        EDGE_FLOOR_RAD.powi(2),
    ))
}

impl<'c> Mapper<'c> {
    /// Nothing registered yet.
    fn new(config: &'c LaserConfig) -> Result<Self> {
        Ok(Self {
            config,
            recent: VecDeque::new(),
            first: 0,
            poses: Vec::new(),
            nodes: Nodes::new(),
            along_m: Vec::new(),
            keyframes: Keyframes::new()?,
            loops: Vec::new(),
            lost: false,
            closed_at_m: 0.0,
            unsolved: false,
            disagree: false,
            solves: 0,
            placed: Vec::new(),
            newest: Pose2::IDENTITY,
            motion: MotionSoFar::default(),
            field: None,
        })
    }

    /// Matches a scan's frame against the local map (the registered scans
    /// before it), from the newest scan's pose moved by the frame's
    /// odometry: its thinned endpoints and the match.
    fn matched(&mut self, frame: &Frame, label: &dyn Fn() -> String) -> Result<(Vec<Point2>, Registration)> {
        let config = self.config;
        let points = self.scan_points(frame);
        let last = self.poses.len() - 1;
        let odometry = frame.odometry();
        let previous = self.poses[last] * self.newest;
        let field = match self.field.take() {
            Some(field) => field,
            None => self.field((last + 1).saturating_sub(config.local_scans)..last + 1),
        };
        let reg = match &odometry {
            Some(step) => self.with_odometry(&field, &points, &previous, step),
            None => self.blind(&field, &points, &previous),
        };
        let step = reg
            .as_ref()
            .ok()
            .filter(|r| r.accepted)
            .map(|r| previous.between(&r.pose));
        self.motion = self.motion.after(step, config);
        self.field = Some(field);
        Ok((points, reg.with_context(label)?))
    }

    /// A match from `previous` moved by the step's odometry. A best pose
    /// on the window's edge may have a better one beyond: the odometry was
    /// wrong by more than its noise (a wheel slipping, a robot pushed).
    /// Searched again, three times as wide; that answer counts where its
    /// best lies inside its own window (one on the edge again is a ridge,
    /// a corridor's length, that a wider window only slides along: the
    /// odometry's pose stands there).
    fn with_odometry(
        &self,
        field: &LikelihoodField,
        points: &[Point2],
        previous: &Pose2,
        step: &Pose2,
    ) -> Result<Registration, RegisterError> {
        let config = self.config;
        let prior = moved_by(previous, step, &config.odometry);
        let reg = register(field, points, &prior, &config.register)?;
        let cell = config.field_resolution_m;
        if reg.accepted && at_window_edge(&prior, &reg.pose, &config.register, cell) {
            let wide = PosePrior {
                sigma_forward_m: 3.0 * prior.sigma_forward_m,
                sigma_left_m: 3.0 * prior.sigma_left_m,
                sigma_theta_rad: 3.0 * prior.sigma_theta_rad,
                ..prior
            };
            let again = register(field, points, &wide, &config.register)?;
            if again.accepted && !at_window_edge(&wide, &again.pose, &config.register, cell) {
                return Ok(again);
            }
        }
        Ok(reg)
    }

    /// A match of a step without odometry: one under each of
    /// [`blind_priors`], the trusted one of highest posterior density
    /// kept (the endpoints' summed log-likelihood at its pose plus its
    /// prior's normalised log density there). A motion that breaks the
    /// robot's course (see [`BlindMotion::keeps_course`]) is taken only
    /// where it beats every trusted one that keeps it by
    /// [`LoopConfig::min_rival_gap_ln`]: in a corridor, a half turn
    /// explains a scan about as well as a step on, and a robot keeps its
    /// course far more often than it turns round. None trusted, the first
    /// prior's answer.
    fn blind(
        &self,
        field: &LikelihoodField,
        points: &[Point2],
        previous: &Pose2,
    ) -> Result<Registration, RegisterError> {
        let config = self.config;
        let mut trusted: Vec<(f64, BlindMotion, Registration)> = Vec::new();
        let mut untrusted = None;
        for (motion, prior) in blind_priors(previous, &self.motion, config) {
            let reg = register(field, points, &prior, &config.register)?;
            if reg.accepted {
                let ln = reg.mean_log_likelihood * reg.points as f64 + prior.ln_density(&reg.pose);
                trusted.push((ln, motion, reg));
            } else if untrusted.is_none() {
                untrusted = Some(reg);
            }
        }
        let most = |keeping: bool| {
            trusted
                .iter()
                .filter(|t| !keeping || t.1.keeps_course())
                .max_by(|a, b| a.0.total_cmp(&b.0))
        };
        let chosen = match (most(false), most(true)) {
            (Some(best), Some(course)) if best.0 - course.0 < config.loops.min_rival_gap_ln => Some(course),
            (best, _) => best,
        };
        match (chosen, untrusted) {
            (Some(t), _) => Ok(t.2.clone()),
            (None, Some(reg)) => Ok(reg),
            (None, None) => register(
                field,
                points,
                &step_prior(previous, None, config),
                &config.register,
            ),
        }
    }

    /// Registers scan `k` (`points` its thinned endpoints, `reg` its match,
    /// `None` for the first): the local map and the graph take it.
    /// Whether its registration was trusted.
    fn take(&mut self, k: usize, points: Vec<Point2>, reg: Option<&Registration>) -> bool {
        self.remember(k, points);
        self.field = None;
        self.newest = Pose2::IDENTITY;
        let Some(reg) = reg else {
            self.poses.push(Pose2::IDENTITY);
            self.along_m.push(0.0);
            return true;
        };
        let step = self.poses[k - 1].between(&reg.pose);
        let covariance = self.local_covariance(k - 1, &reg.covariance);
        self.poses.push(reg.pose);
        self.along_m.push(self.along_m[k - 1] + step.translation().norm());
        let node = self.is_node(k);
        self.nodes.step(&step, &covariance, reg.pose, node);
        self.lost |= !reg.accepted;
        reg.accepted
    }

    /// Places a scan the motion filter leaves out at `relative`, its
    /// matched pose in the last registered scan's frame.
    fn skip(&mut self, scan: &LaserScan, relative: Pose2) {
        let anchor = self.poses.len() - 1;
        self.placed.push(Placed {
            scan: scan.scan,
            t: scan.t,
            anchor,
            relative,
        });
        self.newest = relative;
    }

    /// A scan's thinned endpoints (those it sees and those beyond the
    /// map's limit within reach), in its frame.
    fn scan_points(&self, frame: &Frame) -> Vec<Point2> {
        let config = self.config;
        let mut points = endpoints(&frame.compared);
        points.extend(far_points(&frame.compared, config.reach_m));
        thin_points(&points, config.register.spacing_m.max(config.field_resolution_m))
    }

    /// After scan `k` is placed: a keyframe filed where one is wanted,
    /// and every [`LoopConfig::every_scans`] a search for revisits, the
    /// graph solved where one was found.
    fn revisit(&mut self, k: usize) -> Result<()> {
        let every = self.config.loops.every_scans;
        if every > 0 {
            self.file_keyframe(k)?;
            if k > 0 && k % every == 0 && self.close_loops(k)? {
                self.unsolved = true;
                if self.disagree {
                    self.optimise();
                }
            }
        }
        Ok(())
    }

    /// The registered log: `meta` with the final poses, the loops, and
    /// the graph without the loop edges it dropped.
    fn finish(mut self, mut meta: Vec<ScanPose>) -> Result<RegisteredLog> {
        if self.unsolved {
            self.optimise();
        }
        for (s, p) in meta.iter_mut().zip(&self.poses) {
            s.pose = *p;
        }
        let dropped: Vec<usize> = (self.loops.iter())
            .filter(|(l, _)| !l.kept)
            .map(|&(_, e)| e)
            .collect();
        let Nodes {
            mut graph,
            scans: nodes,
            ..
        } = self.nodes;
        graph.edges = (graph.edges.into_iter().enumerate())
            .filter(|(e, _)| !dropped.contains(e))
            .map(|(_, edge)| edge)
            .collect();
        let skipped = (self.placed.iter())
            .map(|p| SkippedScan {
                scan: p.scan,
                t: p.t,
                pose: self.poses[p.anchor] * p.relative,
            })
            .collect();
        Ok(RegisteredLog {
            scans: meta,
            skipped,
            info: pirouette_io::LogInfo {
                format: "",
                scan_topic: None,
                motion: None,
                mount: Pose2::IDENTITY,
                skipped: Vec::new(),
            },
            loops: self.loops.into_iter().map(|(l, _)| l).collect(),
            loop_searches: self.keyframes.searches,
            keyframes: self.keyframes.len(),
            solves: self.solves,
            graph,
            nodes,
        })
    }

    /// The endpoints of scan `k`, in its frame (a recent scan).
    fn points(&self, k: usize) -> &[Point2] {
        &self.recent[k - self.first]
    }

    /// The likelihood field of recent scans `range` at their current poses.
    fn field(&self, range: std::ops::Range<usize>) -> LikelihoodField {
        let points: Vec<Point2> = range
            .flat_map(|k| {
                self.points(k)
                    .iter()
                    .map(move |p| self.poses[k].transform_point(*p))
            })
            .collect();
        self.field_of(&points)
    }

    /// The likelihood field of obstacle points in the map frame.
    fn field_of(&self, points: &[Point2]) -> LikelihoodField {
        let r = &self.config.register;
        LikelihoodField::from_points(points, self.config.field_resolution_m, r.sigma_m, r.epsilon)
    }

    /// Files scan `k`'s endpoints, forgetting those no local map or
    /// keyframe needs any more.
    fn remember(&mut self, k: usize, points: Vec<Point2>) {
        let c = &self.config;
        let keep = (c.local_scans + 1).max(2 * c.loops.anchor_scans + 1);
        self.recent.push_back(points);
        while self.recent.len() > keep {
            self.recent.pop_front();
            self.first += 1;
        }
        debug_assert_eq!(self.first + self.recent.len(), k + 1);
    }

    /// The poses and path lengths so far.
    fn track(&self) -> Track<'_> {
        Track {
            poses: &self.poses,
            along_m: &self.along_m,
        }
    }

    /// Makes scan `k − anchor_scans` a keyframe (its neighbours now all
    /// placed) where no keyframe lies near it.
    fn file_keyframe(&mut self, k: usize) -> Result<()> {
        let c = &self.config.loops;
        let Some(j) = k.checked_sub(c.anchor_scans) else {
            return Ok(());
        };
        // A keyframe is a loop's earlier end: a node of the graph.
        if self.nodes.node_of(j).is_none() || !self.keyframes.wanted(self.config, &self.track(), j) {
            return Ok(());
        }
        let points = self.points_in_frame(j, j.saturating_sub(c.anchor_scans)..k + 1);
        // Its view: every scan remembered, the 180° scanners' blind backs
        // filled by the scans before.
        let seen = self.points_in_frame(j, self.first..k + 1);
        let spacing = self.config.register.spacing_m.max(self.config.field_resolution_m);
        let along = self.along_m[k];
        self.keyframes
            .file(self.config, j, along, thin_points(&points, spacing), &seen)
    }

    /// The endpoints of recent scans `range` in scan `j`'s frame.
    fn points_in_frame(&self, j: usize, range: std::ops::Range<usize>) -> Vec<Point2> {
        let to_j = self.poses[j].inverse();
        range
            .flat_map(|m| {
                let rel = to_j * self.poses[m];
                self.points(m).iter().map(move |p| rel.transform_point(*p))
            })
            .collect()
    }

    /// A registered pose's covariance (in the world frame) in the frame of
    /// scan `i`'s current pose, with the floors added.
    fn local_covariance(&self, i: usize, covariance: &Matrix3<f64>) -> Matrix3<f64> {
        let r = self.poses[i].tangent_rotation();
        r.transpose() * covariance * r + edge_floor()
    }

    /// A loop edge `i → j` measuring `j`'s registered pose `pose_j` (with
    /// its world covariance) in the frame of `i`'s current pose, between
    /// scans `i` and `j`.
    fn loop_edge(&self, i: usize, j: usize, pose_j: &Pose2, covariance: &Matrix3<f64>) -> GraphEdge {
        let mut e = MeasuredEdge {
            i,
            j,
            z: self.poses[i].between(pose_j),
            info: information(&self.local_covariance(i, covariance)),
        }
        .to_graph();
        e.kernel = Kernel::Cauchy { c: 1.0 };
        e
    }

    /// Whether scan `k` (placed) is to be a node of the graph: every scan
    /// searched for revisits (a loop's later end) and every scan that may
    /// become a keyframe (a loop's earlier end); every scan where loops
    /// are not closed.
    fn is_node(&self, k: usize) -> bool {
        let every = self.config.loops.every_scans;
        every == 0 || k % every == 0 || self.keyframes.wanted(self.config, &self.track(), k)
    }

    /// Searches the keyframes for the place of scan `k`; each match found
    /// becomes a loop edge. Whether any did.
    fn close_loops(&mut self, k: usize) -> Result<bool> {
        let c = &self.config.loops;
        // The estimate may be out of the search near it when a step since
        // the last loop was not registered, or when the path since has
        // grown drift beyond its radius: then the view is asked as well.
        let drift_reach_m = (c.max_radius_m - c.radius_m) / c.radius_per_m.max(1e-9);
        let lost = self.lost || self.along_m[k] - self.closed_at_m > drift_reach_m;
        let local = if lost {
            self.points_in_frame(k, k.saturating_sub(self.config.local_scans)..k + 1)
        } else {
            Vec::new()
        };
        let track = Track {
            poses: &self.poses,
            along_m: &self.along_m,
        };
        let scan = &self.recent[k - self.first];
        let found = self
            .keyframes
            .search(self.config, &track, k, scan, lost.then_some(&local[..]))?;
        if !found.is_empty() {
            self.lost = false;
            self.closed_at_m = self.along_m[k];
        }
        for f in &found {
            let reg = &f.registration;
            let edge = self.loop_edge(f.from, f.to, &reg.pose, &reg.covariance);
            let chi2 = edge.chi2(&self.poses[f.from], &self.poses[f.to]);
            // Both ends are nodes: a keyframe and a searched scan.
            let Some(e) = self.nodes.add(edge) else {
                continue;
            };
            self.disagree |= chi2 > SOLVE_GATE;
            let closure = LoopClosure {
                from: f.from,
                to: f.to,
                recognised: f.recognised,
                kept: true,
            };
            self.loops.push((closure, e));
        }
        Ok(!found.is_empty())
    }

    /// Solves the pose graph of the scans so far, drops the loop edges the
    /// solution contradicts and solves again; the poses follow.
    fn optimise(&mut self) {
        let config = OptimiseConfig {
            max_iterations: 20,
            ..OptimiseConfig::default()
        };
        self.solves += 1;
        // A graph that cannot be solved keeps its poses.
        let graph = &mut self.nodes.graph;
        if optimise(graph, &config).is_err() {
            return;
        }
        let mut dropped = false;
        for (closure, e) in self.loops.iter_mut().filter(|(l, _)| l.kept) {
            let edge = &graph.edges[*e];
            if edge.chi2(&graph.poses[edge.from], &graph.poses[edge.to]) > EDGE_GATE {
                closure.kept = false;
                // Kept in place (indices stay valid), with no weight.
                graph.edges[*e].information = [[1e-12, 0.0, 0.0], [0.0, 1e-12, 0.0], [0.0, 0.0, 1e-12]];
                dropped = true;
            }
        }
        // Solved again without them (where that fails, the first solution
        // stands).
        if dropped {
            let _ = optimise(graph, &config);
        }
        for (p, q) in self.poses.iter_mut().zip(self.nodes.poses()) {
            *p = q;
        }
        self.unsolved = false;
        self.disagree = false;
        self.field = None;
        self.keyframes.forget_pending();
    }
}

/// Matches every scan of a log (any [`open_laser_log`] reads) against a
/// local map of the scans registered before it; those that moved enough
/// (see [`MotionFilter`]) are registered: the local map and the pose
/// graph take them, and loops are closed where the log comes back (see
/// [`LoopConfig`]). The others keep their matched pose relative to the
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
        let (points, reg) = if k == 0 {
            (m.scan_points(&frame), None)
        } else {
            let (points, reg) = m.matched(&frame, &label)?;
            // Matched near the last registered scan: the local map holds
            // what it sees.
            let relative = m.poses[k - 1].between(&reg.pose);
            if reg.accepted && !config.motion_filter.keeps(&relative) {
                m.skip(&scan, relative);
                continue;
            }
            (points, Some(reg))
        };
        let registered = m.take(k, points, reg.as_ref());
        meta.push(ScanPose {
            scan: scan.scan,
            t: scan.t,
            pose: Pose2::IDENTITY,
            odometry: since.filter(|_| k > 0).and(scan.odometry_source),
            registered,
        });
        since = Some(Pose2::IDENTITY);
        // Places kept, revisits searched, the graph solved.
        m.revisit(k)?;
    }
    if meta.is_empty() {
        bail!(
            "{}: no laser scan in the log (CARMEN: FLASER or ROBOTLASER1 lines; a bag: LaserScan messages)",
            path.display()
        );
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

/// The grid of a log's registered scans at the given robot poses (one
/// per registered scan, in log order), the log streamed again.
pub fn grid_of_log(
    path: &Path,
    registered: &RegisteredLog,
    options: &BagOptions,
    config: &LaserConfig,
) -> Result<OccupancyGrid> {
    let mut grid = OccupancyGrid::new(config.grid.clone()).context("grid settings")?;
    let mount = registered.info.mount;
    let mut wanted = registered.scans.iter().peekable();
    for scan in open_laser_log(path, options)? {
        let scan = scan?;
        let Some(s) = wanted.next_if(|s| s.scan == scan.scan) else {
            continue;
        };
        grid.insert_profile(
            &(s.pose * mount),
            &laser_frame(&scan, config.max_range_m).rop,
            0.0,
        );
    }
    if let Some(s) = wanted.next() {
        return Err(IoError::Invalid {
            path: path.to_owned(),
            problem: format!("scan {} registered but not found when read again", s.scan),
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
pub fn map_log(
    path: &Path,
    config: &LaserConfig,
    options: &BagOptions,
    progress: &dyn Fn(),
) -> Result<LaserMap> {
    let registered = register_log(path, config, options, progress)?;
    let grid = grid_of_log(path, &registered, options, config)?;
    Ok(LaserMap { registered, grid })
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
