//! The laser engine's settings and their check.

use pirouette_geom::Pose2;
use pirouette_grid::{GridConfig, OccupancyGrid};
use pirouette_register::{Covariance, RegisterConfig};

use crate::error::{Result, SlamError};
use crate::revisit::RevisitTest;

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
    /// Registration of a scan against the local map (Laplace's covariance:
    /// see [`pirouette_register::Covariance`]).
    pub register: RegisterConfig,
    /// The local map (a submap) holds the endpoints of this many scans
    /// before at least, and twice as many at most: a new submap is begun
    /// every this many scans.
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
    /// (see [`blind_priors`](super::blind_priors)).
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
    /// When a scan's match on a candidate's map is a revisit (the test
    /// camera runs use too). Its rival tolerances are also how far two
    /// matches may differ and still agree (see `index_sigma_m`).
    pub revisit: RevisitTest,
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
    /// on) moves the estimate the same way (within the revisit test's
    /// rival tolerances).
    pub index_sigma_m: f64,
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
            revisit: RevisitTest::default(),
            index_candidates: 2,
            max_profile_rms_m: 1.0,
            index_sigma_m: 0.5,
        }
    }
}

impl Default for LaserConfig {
    /// A 20 m map limit and 40 m registration reach (indoor scanners
    /// measure to a few centimetres that far); 5 cm cells for the grid and
    /// the local map; registration with a 5 cm Gaussian (the local map's
    /// cell), endpoints thinned to one per 5 cm, a window of at most
    /// ±2.5 m, Laplace's covariance; a local map of the last 30 to 60
    /// scans; a step without odometry
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
                covariance: Covariance::Laplace,
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

/// The most scans a local map or a keyframe's map (each side) may hold:
/// their endpoints are kept in memory.
pub const MAX_WINDOW_SCANS: usize = 10_000;

/// Checks the settings before any line is read.
pub fn check_config(config: &LaserConfig) -> Result<()> {
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if !(positive(f64::from(config.max_range_m)) && config.reach_m >= f64::from(config.max_range_m)) {
        return Err(SlamError::settings(
            "laser",
            format!(
                "the map limit {} m must be positive and the reach {} m at least as far",
                config.max_range_m, config.reach_m
            ),
        ));
    }
    if !(positive(config.field_resolution_m)
        && positive(config.unknown_step_m)
        && positive(config.unknown_step_rad)
        && positive(config.unknown_turn_m))
    {
        return Err(SlamError::settings(
            "laser",
            "the local map's cell and the unknown step's spreads must be positive",
        ));
    }
    for (what, n) in [
        ("odometry", &config.odometry),
        ("repeated step", &config.unknown_repeat),
    ] {
        let rates = [n.per_m, n.m_per_rad, n.per_rad, n.rad_per_m];
        if !(rates.iter().all(|v| v.is_finite() && *v >= 0.0) && positive(n.floor_m) && positive(n.floor_rad))
        {
            return Err(SlamError::settings(
                "laser",
                format!("the {what} noise's rates must be zero or more and its floors positive: {n:?}"),
            ));
        }
    }
    if !(1..=MAX_WINDOW_SCANS).contains(&config.local_scans) || config.loops.anchor_scans > MAX_WINDOW_SCANS {
        return Err(SlamError::settings(
            "laser",
            format!(
                "the local map must hold 1 to {MAX_WINDOW_SCANS} scans, a keyframe's map at most that many each side (given {} and {})",
                config.local_scans, config.loops.anchor_scans
            ),
        ));
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
    ];
    if !(spreads.into_iter().all(positive)
        && l.radius_per_m.is_finite()
        && l.radius_per_m >= 0.0
        && l.revisit.is_valid())
    {
        return Err(SlamError::settings(
            "laser",
            format!("loop closure's distances, spreads and tolerances must be positive: {l:?}"),
        ));
    }
    let f = &config.motion_filter;
    if !(f.min_step_m.is_finite()
        && f.min_step_m >= 0.0
        && f.min_turn_rad.is_finite()
        && f.min_turn_rad >= 0.0)
    {
        return Err(SlamError::settings(
            "laser",
            format!("the motion filter's limits must be zero or more: {f:?}"),
        ));
    }
    OccupancyGrid::new(config.grid.clone())?;
    Ok(())
}
