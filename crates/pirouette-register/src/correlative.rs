//! Correlative registration of a sweep against a map: an exhaustive search
//! over translation and rotation, then a local refinement below one cell,
//! with the covariance of the pose from the spread of the search.

use crate::bound::{
    Block, Excluded, GaussianTerm, Kept, Node, PriorTerm, Pyramid, RotationSearch, SharedBest, TOP_LEVEL,
};
use crate::field::{LikelihoodField, Neighbourhood};
use crate::floor_i64;
use crate::RegisterError;
use nalgebra::{Matrix3, Vector3};
use pirouette_geom::{wrap_angle, Point2, Pose2};
use pirouette_grid::{FREE_THRESH, OCCUPIED_THRESH};
use rayon::prelude::*;
use std::sync::atomic::AtomicUsize;

/// How far a forward move may stray from its command (one standard
/// deviation).
#[derive(Debug, Clone, PartialEq)]
pub struct MotionNoise {
    /// Distance error as a share of the distance commanded.
    pub distance_frac: f64,
    /// Heading error of a forward move, radians (the robot veers).
    pub heading_rad: f64,
    /// Position error of any move however short, metres.
    pub floor_m: f64,
}

impl Default for MotionNoise {
    /// The worst of what a cheap differential drive does, taken as one
    /// standard deviation: distance off by 10 %, heading by 2°, and 1 cm
    /// regardless.
    fn default() -> Self {
        Self {
            distance_frac: 0.10,
            heading_rad: 2f64.to_radians(),
            floor_m: 0.01,
        }
    }
}

/// A Gaussian belief in a pose before registration, with the standard
/// deviations expressed in the frame of its own mean.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PosePrior {
    /// The expected pose, `world_from_robot`.
    pub mean: Pose2,
    /// Along the robot's heading, metres.
    pub sigma_forward_m: f64,
    /// Across the robot's heading, metres.
    pub sigma_left_m: f64,
    /// Heading, radians.
    pub sigma_theta_rad: f64,
}

impl PosePrior {
    /// The pose after a commanded straight move of `distance_m` from
    /// `start` (whose heading is itself known to `start_sigma_theta_rad`).
    /// The heading error of the start and the veer of the move both swing
    /// the end point sideways.
    pub fn after_forward(
        start: &Pose2,
        distance_m: f64,
        start_sigma_theta_rad: f64,
        noise: &MotionNoise,
    ) -> Self {
        let d = distance_m.abs();
        let sigma_theta = start_sigma_theta_rad.hypot(noise.heading_rad);
        Self {
            mean: *start * Pose2::new(distance_m, 0.0, 0.0),
            sigma_forward_m: (noise.distance_frac * d).hypot(noise.floor_m),
            // A veer spread along the move moves the end by half its angle.
            sigma_left_m: (d * start_sigma_theta_rad)
                .hypot(0.5 * d * noise.heading_rad)
                .hypot(noise.floor_m),
            sigma_theta_rad: sigma_theta,
        }
    }

    /// The pose after a general move `relative` (a turn and a shift
    /// together, in the start's frame, as odometry gives it) from `start`,
    /// whose heading is known to `start_sigma_theta_rad`; the move's own
    /// turn errs by `turn_sigma_rad`. As [`PosePrior::after_forward`] along
    /// the shift's direction, the turn's error added to the heading's.
    pub fn after_move(
        start: &Pose2,
        relative: &Pose2,
        start_sigma_theta_rad: f64,
        turn_sigma_rad: f64,
        noise: &MotionNoise,
    ) -> Self {
        let d = relative.x.hypot(relative.y);
        // The shift's errors lie along and across its own direction; in
        // the end pose's frame that direction is turned by the move's turn.
        let along = (noise.distance_frac * d).hypot(noise.floor_m);
        let across = (d * start_sigma_theta_rad)
            .hypot(0.5 * d * noise.heading_rad)
            .hypot(noise.floor_m);
        let shift_dir = relative.y.atan2(relative.x) - relative.theta;
        let (s, c) = shift_dir.sin_cos();
        // The prior is axis-aligned in its own frame: the larger spread
        // is taken on both axes where the shift runs at a slant (a slight
        // overstatement, never an understatement).
        let (sigma_forward_m, sigma_left_m) = if c.abs() > 0.999 {
            (along, across)
        } else if s.abs() > 0.999 {
            (across, along)
        } else {
            (along.max(across), along.max(across))
        };
        Self {
            mean: *start * *relative,
            sigma_forward_m,
            sigma_left_m,
            sigma_theta_rad: start_sigma_theta_rad
                .hypot(noise.heading_rad)
                .hypot(turn_sigma_rad),
        }
    }

    /// The box [`register`] searches about the prior's mean.
    pub fn window(&self, config: &RegisterConfig) -> Window {
        let window = |sigma: f64| (config.window_sigmas * sigma).min(config.max_window_m);
        let cov = self.covariance();
        Window {
            half_x: window(cov[(0, 0)].sqrt()),
            half_y: window(cov[(1, 1)].sqrt()),
            half_t: (config.window_sigmas * self.sigma_theta_rad).min(std::f64::consts::PI),
        }
    }

    /// The prior's covariance in world `(x, y, θ)`.
    pub fn covariance(&self) -> Matrix3<f64> {
        self.mean.rotate_covariance(&Matrix3::from_diagonal(&Vector3::new(
            self.sigma_forward_m.powi(2),
            self.sigma_left_m.powi(2),
            self.sigma_theta_rad.powi(2),
        )))
    }

    /// The log probability density of `pose` (normalised: priors of
    /// other spreads compare).
    pub fn ln_density(&self, pose: &Pose2) -> f64 {
        let volume = self.sigma_forward_m * self.sigma_left_m * self.sigma_theta_rad;
        self.log_density(pose.x, pose.y, pose.theta) - (std::f64::consts::TAU.powf(1.5) * volume).ln()
    }

    /// `−½ Δᵀ Σ⁻¹ Δ` of a candidate pose.
    fn log_density(&self, x: f64, y: f64, theta: f64) -> f64 {
        self.log_density_turned(self.mean.theta.sin_cos(), x, y, theta)
    }

    /// [`PosePrior::log_density`] with the mean heading's `(sin, cos)`
    /// given, for callers that evaluate many poses.
    fn log_density_turned(&self, (s, c): (f64, f64), x: f64, y: f64, theta: f64) -> f64 {
        let (dx, dy) = (x - self.mean.x, y - self.mean.y);
        let forward = c * dx + s * dy;
        let left = -s * dx + c * dy;
        let dt = wrap_angle(theta - self.mean.theta);
        -0.5 * ((forward / self.sigma_forward_m).powi(2)
            + (left / self.sigma_left_m).powi(2)
            + (dt / self.sigma_theta_rad).powi(2))
    }

    fn check(&self) -> Result<(), RegisterError> {
        let ok = |v: f64| v.is_finite() && v > 0.0;
        if !(self.mean.is_finite()
            && ok(self.sigma_forward_m)
            && ok(self.sigma_left_m)
            && ok(self.sigma_theta_rad))
        {
            return Err(RegisterError::BadPrior {
                problem: format!("{self:?}"),
            });
        }
        Ok(())
    }
}

/// The box a registration searches about its prior's mean, in world axes:
/// ± `window_sigmas` of the prior's spread, at most ± `max_window_m` in
/// position and half a turn in heading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Window {
    /// Half-width along world x, metres.
    pub half_x: f64,
    /// Half-width along world y, metres.
    pub half_y: f64,
    /// Half-width in heading, radians.
    pub half_t: f64,
}

/// Settings of registration.
#[derive(Debug, Clone, PartialEq)]
pub struct RegisterConfig {
    /// Width of the likelihood field's Gaussian, metres.
    pub sigma_m: f64,
    /// Likelihood floor of an endpoint on ground the map knows nothing of
    /// (an obstacle not yet mapped).
    pub epsilon: f64,
    /// Likelihood floor of an endpoint on floor the map has seen free (a
    /// false range).
    pub epsilon_free: f64,
    /// Map cells below this probability are known floor.
    pub free_threshold: f64,
    /// Map cells above this probability are obstacles.
    pub occupied_threshold: f64,
    /// Half-width of the search window, in prior standard deviations.
    pub window_sigmas: f64,
    /// The largest half-width of the translation window, metres.
    pub max_window_m: f64,
    /// The fewest endpoints within two σ of a mapped obstacle for the
    /// match to be trusted.
    pub min_matched: usize,
    /// Endpoints closer than this are one piece of evidence (kept once per
    /// cell of this side): neighbouring bins see the same stretch of wall
    /// with the same range error, so counting each would overrule the
    /// prior with correlated evidence.
    pub spacing_m: f64,
    /// How the lattice is searched; both find the same poses.
    pub search: Search,
    /// A rival ([`Registration::rival`]) lies more than this from the best
    /// pose along x or y, metres, or more than `rival_apart_rad` in
    /// heading; nearer peaks are the best answer's own spread (its
    /// covariance), not another answer. Never under one lattice step.
    pub rival_apart_m: f64,
    /// The same in heading, radians.
    pub rival_apart_rad: f64,
    /// Rivals are sought this far below the best score, nats: a peak
    /// lower than that is no second answer, and the search for it stops
    /// there (with [`Covariance::Laplace`]; the whole posterior holds every
    /// peak within `10⁻⁹` of the best's weight).
    pub rival_gap_ln: f64,
    /// Where the covariance comes from.
    pub covariance: Covariance,
    /// The most lattice poses the posterior may spread over (weights of
    /// at least `10⁻⁹` of the best's) for the match to be trusted: one
    /// that loose does not pin the pose (a featureless view). Counted in
    /// Laplace's Gaussian at the refined pose (its ellipsoid's volume in
    /// lattice cells), and among the poses apart from the best within
    /// [`RegisterConfig::rival_gap_ln`] of it (a wide search through
    /// look-alike places).
    pub max_spread_poses: usize,
}

/// Where [`register`]'s covariance comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Covariance {
    /// The lattice's whole posterior: every pose within `10⁻⁹` of the
    /// best's weight found and weighed, the best refined by a pattern
    /// search. It keeps the spread of broad and many-peaked posteriors (a
    /// camera frame's narrow view, a sweep in a look-alike room), and the
    /// search cannot stop at the best.
    #[default]
    Posterior,
    /// Laplace's: the curvature of the exact score at the best pose
    /// refined by Gauss-Newton steps (each endpoint held by the surface its
    /// obstacle lies on), the lattice's quantisation and a rival peak's
    /// mass added; the search stops at the best, and a second one bounded
    /// by [`RegisterConfig::rival_gap_ln`] finds the rival.
    Laplace,
}

/// How [`register`] searches its lattice. All find the same best pose and
/// the same posterior (every pose whose weight counts, scored alike and
/// summed in the same order); they differ only in time (and, near
/// [`RegisterConfig::max_spread_poses`], in when they give up).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Search {
    /// Score every pose: the reference.
    Exhaustive,
    /// Score blocks of poses by an upper bound first and drop those that
    /// cannot count (max-pooled levels of the field bound each block).
    BranchAndBound,
    /// Branch and bound, but where the whole posterior is sought
    /// ([`Covariance::Posterior`]) on a field whose pooled levels are not
    /// made yet and scoring every pose looks up fewer cells than making
    /// them would write, every pose (a small window on a wide field).
    #[default]
    Cheaper,
}

impl Default for RegisterConfig {
    /// σ 1.5 cm (a 1 cm map cell's quantisation and the profile's few
    /// millimetres of range noise); ε 0.2 on unknown ground; ε 0.02 on seen
    /// floor (a profile's false ranges are a few per cent of its bins);
    /// obstacles above and floor below `map_server`'s 0.65 and 0.196;
    /// a ±3σ window of at most ±1 m; endpoints counted once per 3 cm (2σ:
    /// closer ones share their error); at least 10 of them (30 cm of edge)
    /// on mapped obstacles; the branch-and-bound search; any peak beyond the
    /// best one's lattice neighbours within 10 nats of it (a factor of
    /// 22,000) a rival; a posterior over more than 2²⁰ poses not trusted.
    fn default() -> Self {
        Self {
            sigma_m: 0.015,
            epsilon: 0.2,
            epsilon_free: 0.02,
            free_threshold: FREE_THRESH,
            occupied_threshold: OCCUPIED_THRESH,
            window_sigmas: 3.0,
            max_window_m: 1.0,
            min_matched: 10,
            spacing_m: 0.03,
            search: Search::Cheaper,
            rival_apart_m: 0.0,
            rival_apart_rad: 0.0,
            rival_gap_ln: 10.0,
            covariance: Covariance::Posterior,
            max_spread_poses: 1 << 20,
        }
    }
}

/// The result of registering one sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct Registration {
    /// The registered pose, `world_from_robot` (the prior's mean when the
    /// match is not trusted).
    pub pose: Pose2,
    /// Covariance of `pose` in world `(x, y, θ)` (the prior's when the match
    /// is not trusted).
    pub covariance: Matrix3<f64>,
    /// Mean log-likelihood of an endpoint at `pose` (0 best, `ln ε` worst).
    pub mean_log_likelihood: f64,
    /// Endpoints used (one per map cell).
    pub points: usize,
    /// Endpoints within two σ of a mapped obstacle at `pose`.
    pub matched: usize,
    /// Whether the match was trusted.
    pub accepted: bool,
    /// Lattice poses and blocks of poses scored.
    pub evaluated: usize,
    /// The best rival peak of the search's posterior, where it holds one
    /// (see [`Rival`]).
    pub rival: Option<Rival>,
}

/// A second peak of the registration's posterior: the best local maximum
/// of the lattice's scores apart from the best pose (see
/// [`RegisterConfig::rival_apart_m`]), within
/// [`RegisterConfig::rival_gap_ln`] of it. The covariance (Laplace's, of
/// the best peak alone) leaves it out; how far it falls below the best
/// says how ambiguous the match is (a gap of a few nats on a wide search
/// means a look-alike pose nearly as good).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rival {
    /// The rival pose, `world_from_robot`, on the search lattice.
    pub pose: Pose2,
    /// The best score less the rival's (nats, at least 0).
    pub below_best_ln: f64,
}

/// Keeps one endpoint per cell of side `cell_m` (the first), so that a
/// wall seen by many fine bins counts once per cell, as independent
/// evidence should.
pub fn thin_points(points: &[Point2], cell_m: f64) -> Vec<Point2> {
    let mut seen = std::collections::HashSet::new();
    points
        .iter()
        .copied()
        .filter(|p| p.x.is_finite() && p.y.is_finite())
        .filter(|p| seen.insert((floor_i64(p.x / cell_m), floor_i64(p.y / cell_m))))
        .collect()
}

/// Registers the endpoints of a sweep (`points_robot`, in the sweep's own
/// frame) against the map's likelihood field, starting from `prior`.
///
/// The search covers a lattice spanning the prior's ± `window_sigmas` box:
/// rotations a step apart that moves the farthest endpoint by at most one
/// cell, translations one cell apart. It finds the lattice pose of highest
/// posterior score (the field summed over the endpoints plus the prior's
/// log density), by branch and bound or exhaustively
/// ([`RegisterConfig::search`]), and refines it on the exact field by
/// Gauss-Newton steps. The covariance is Laplace's at the refined pose:
/// the inverse of the curvature of the score there, so that it grows
/// along a corridor and with few endpoints. A second search, bounded by
/// [`RegisterConfig::rival_gap_ln`] below the best, finds a rival peak
/// apart from the best ([`Registration::rival`]).
pub fn register(
    field: &LikelihoodField,
    points_robot: &[Point2],
    prior: &PosePrior,
    config: &RegisterConfig,
) -> Result<Registration, RegisterError> {
    if config.covariance == Covariance::Posterior {
        return posterior::register_posterior(field, points_robot, prior, config);
    }
    let points = thinned(field, points_robot, prior, config)?;
    let res = field.resolution_m();
    let fallback = |mean_ll, matched, evaluated| untrusted(prior, points.len(), mean_ll, matched, evaluated);
    if points.len() < config.min_matched || field.obstacle_points() == 0 {
        return Ok(fallback(field.floor() as f64, 0, 0));
    }
    let (lattice, nt) = Lattice::around(prior, &points, res, config);
    let cells_at = |kt: i64| lattice.cells_at(&points, kt);
    let search = match config.search {
        Search::Exhaustive => exhaustive(field, &lattice, nt, &cells_at),
        Search::BranchAndBound | Search::Cheaper => {
            bounded(field, &lattice, nt, &cells_at, -config.rival_gap_ln.max(0.0))
        }
    };
    let Some(mut search) = search else {
        return Ok(fallback(field.floor() as f64, 0, 0));
    };
    let best = search.best;
    let theta_step = lattice.theta_step;
    let start = Pose2::new(
        prior.mean.x + best.1 as f64 * res,
        prior.mean.y + best.2 as f64 * res,
        prior.mean.theta + best.3 as f64 * theta_step,
    );
    // Refinement moves the pose by about a cell: the obstacles near each
    // endpoint's start decide its exact values there.
    let anchored = Anchored::new(field, &points, start, res);
    let (pose, information) = refine(&anchored, prior, res, theta_step);
    let Some(laplace) = information.try_inverse().map(|c| 0.5 * (c + c.transpose())) else {
        return Ok(fallback(field.floor() as f64, 0, search.evaluated));
    };
    // The lattice's own quantisation (a uniform cell) added, as the
    // search resolves no finer.
    let covariance = laplace
        + Matrix3::from_diagonal(&Vector3::new(
            res * res / 12.0,
            res * res / 12.0,
            theta_step * theta_step / 12.0,
        ));
    if lattice.spread_poses(&covariance, nt) > config.max_spread_poses as f64 {
        return Ok(fallback(field.floor() as f64, 0, search.evaluated));
    }
    let (sum, matched) = anchored.evaluate(&pose);
    let mean_ll = sum / points.len() as f64;
    if matched < config.min_matched {
        return Ok(fallback(mean_ll, matched, search.evaluated));
    }
    let Some(rival) = search.rival(&lattice, nt, &cells_at, config) else {
        return Ok(fallback(mean_ll, matched, search.evaluated));
    };
    let rival = rival.map(|(kt, k)| {
        let x = lattice.pose(k.a, k.b, kt);
        Rival {
            pose: Pose2::new(x[0], x[1], x[2]),
            below_best_ln: best.0 - k.score,
        }
    });
    // The rival's mass: the covariance of the two peaks as a mixture,
    // weighed by their scores (`w(1 − w)·ΔΔᵀ` added).
    let covariance = match rival {
        Some(r) => {
            let d = Vector3::new(
                r.pose.x - pose.x,
                r.pose.y - pose.y,
                wrap_angle(r.pose.theta - pose.theta),
            );
            let w = 1.0 / (1.0 + r.below_best_ln.exp());
            covariance + d * d.transpose() * (w * (1.0 - w))
        }
        None => covariance,
    };
    Ok(Registration {
        pose,
        covariance,
        mean_log_likelihood: mean_ll,
        points: points.len(),
        matched,
        accepted: true,
        evaluated: search.evaluated,
        rival,
    })
}

/// Whether [`register`] could accept `points_robot` against `field` from
/// `prior`: `false` only where it cannot, because fewer than
/// [`RegisterConfig::min_matched`] of the endpoints it would match can
/// come within the matched distance of a mapped obstacle at any pose the
/// search and its refinement may reach (an endpoint moves by at most the
/// translation plus its range times the turn). It looks up each endpoint
/// once, at the prior's mean, against the field's obstacle points, at a
/// small part of a registration's cost: what two views that share nothing
/// spend on learning so.
pub fn may_accept(
    field: &LikelihoodField,
    points_robot: &[Point2],
    prior: &PosePrior,
    config: &RegisterConfig,
) -> Result<bool, RegisterError> {
    let points = thinned(field, points_robot, prior, config)?;
    if points.len() < config.min_matched || field.obstacle_points() == 0 {
        return Ok(false);
    }
    let Some(radius) = field.matched_radius() else {
        return Ok(true);
    };
    let res = field.resolution_m();
    let (lattice, nt) = Lattice::around(prior, &points, res, config);
    // The farthest the search's lattice and then its refinement move the
    // pose from the prior's mean.
    let shift = ((lattice.nx as f64 + REFINE_REACH_STEPS) * res)
        .hypot((lattice.ny as f64 + REFINE_REACH_STEPS) * res);
    let turn = (nt as f64 + REFINE_REACH_STEPS) * lattice.theta_step;
    let mut near = 0;
    for p in &points {
        let at = prior.mean.transform_point(*p);
        if field.obstacle_within(at, radius + shift + p.norm() * turn) {
            near += 1;
            if near >= config.min_matched {
                return Ok(true);
            }
        }
    }
    Ok(false)
}

/// The endpoints a registration matches, its prior checked: thinned to
/// one per [`RegisterConfig::spacing_m`] (at least a field cell).
fn thinned(
    field: &LikelihoodField,
    points_robot: &[Point2],
    prior: &PosePrior,
    config: &RegisterConfig,
) -> Result<Vec<Point2>, RegisterError> {
    prior.check()?;
    Ok(thin_points(
        points_robot,
        config.spacing_m.max(field.resolution_m()),
    ))
}

/// A registration that trusts no match: the prior's mean and covariance,
/// with what was found of `points` endpoints.
fn untrusted(
    prior: &PosePrior,
    points: usize,
    mean_ll: f64,
    matched: usize,
    evaluated: usize,
) -> Registration {
    Registration {
        pose: prior.mean,
        covariance: prior.covariance(),
        mean_log_likelihood: mean_ll,
        points,
        matched,
        accepted: false,
        evaluated,
        rival: None,
    }
}

/// A lattice pose's score and its steps `(a, b, kt)` (see [`Lattice`]).
type LatticeBest = (f64, i64, i64, i64);

/// The search lattice of [`register`]: translations `a·res`, `b·res`
/// (`|a| ≤ nx`, `|b| ≤ ny`) and rotations `kt·theta_step` about the prior's
/// mean.
struct Lattice<'p> {
    prior: &'p PosePrior,
    /// The prior mean heading's `(sin, cos)`.
    turned: (f64, f64),
    res: f64,
    theta_step: f64,
    nx: i64,
    ny: i64,
    /// The farthest point's distance from the robot, metres.
    far_m: f64,
}

impl<'p> Lattice<'p> {
    /// The lattice of `prior`'s ± `window_sigmas` box for `points` (in the
    /// robot's frame) on a field of `res` cells: rotations a step apart
    /// that moves the farthest point by at most one cell (at most 1°),
    /// translations one cell apart; and its rotation steps each way.
    fn around(prior: &'p PosePrior, points: &[Point2], res: f64, config: &RegisterConfig) -> (Self, i64) {
        let far = points.iter().map(|p| p.norm()).fold(res, f64::max);
        let theta_step = (res / far).min(1f64.to_radians());
        let Window {
            half_x,
            half_y,
            half_t,
        } = prior.window(config);
        let lattice = Self {
            prior,
            turned: prior.mean.theta.sin_cos(),
            res,
            theta_step,
            nx: (half_x / res).ceil() as i64,
            ny: (half_y / res).ceil() as i64,
            far_m: far,
        };
        (lattice, (half_t / theta_step).ceil() as i64)
    }

    /// The cells of `points` at rotation `kt` about the prior's mean.
    fn cells_at(&self, points: &[Point2], kt: i64) -> Vec<(i64, i64)> {
        let (mean, res) = (self.prior.mean, self.res);
        let theta = mean.theta + kt as f64 * self.theta_step;
        let (s, c) = theta.sin_cos();
        points
            .iter()
            .map(|p| {
                let x = mean.x + c * p.x - s * p.y;
                let y = mean.y + s * p.x + c * p.y;
                (floor_i64(x / res), floor_i64(y / res))
            })
            .collect()
    }

    /// The lattice pose `(a, b, kt)` as world `(x, y, θ)`.
    fn pose(&self, a: i64, b: i64, kt: i64) -> Vector3<f64> {
        let mean = self.prior.mean;
        Vector3::new(
            mean.x + a as f64 * self.res,
            mean.y + b as f64 * self.res,
            mean.theta + kt as f64 * self.theta_step,
        )
    }

    /// The prior's log density at a lattice pose.
    fn prior_at(&self, a: i64, b: i64, kt: i64) -> f64 {
        let x = self.pose(a, b, kt);
        self.prior.log_density_turned(self.turned, x[0], x[1], x[2])
    }

    /// The score of lattice pose `(a, b)` of the rotation whose endpoint
    /// cells are `cells`: the field's cells summed in the exhaustive
    /// search's order with its arithmetic, plus the prior.
    fn score(&self, field: &LikelihoodField, cells: &[(i64, i64)], a: i64, b: i64, kt: i64) -> f64 {
        field.cells_sum(cells, a, b) as f64 + self.prior_at(a, b, kt)
    }

    /// How many lattice poses a Gaussian posterior of `covariance` holds
    /// within [`NEGLIGIBLE_LN`] of its peak (the ellipsoid's volume in
    /// lattice cells), at most the lattice's own count.
    fn spread_poses(&self, covariance: &Matrix3<f64>, nt: i64) -> f64 {
        let radius = (-2.0 * NEGLIGIBLE_LN).sqrt();
        let volume =
            4.0 / 3.0 * std::f64::consts::PI * radius.powi(3) * covariance.determinant().max(0.0).sqrt();
        let all = ((2 * self.nx + 1) * (2 * self.ny + 1) * (2 * nt + 1)) as f64;
        (volume / (self.res * self.res * self.theta_step)).min(all)
    }

    /// The poses of rotation `kt` with their posterior scores (the field's
    /// `slab` plus the prior) and translation steps `(a, b)`, row-major in
    /// `b`.
    fn scores<'s>(&'s self, slab: &'s [f32], kt: i64) -> impl Iterator<Item = (f64, (i64, i64))> + 's {
        let (nx, ny) = (self.nx, self.ny);
        let sx = (2 * nx + 1) as usize;
        (-ny..=ny).flat_map(move |b| {
            (-nx..=nx).map(move |a| {
                let k = (b + ny) as usize * sx + (a + nx) as usize;
                (slab[k] as f64 + self.prior_at(a, b, kt), (a, b))
            })
        })
    }

    /// Whether lattice pose `(kt, k)`, at least as good as every pose in
    /// `better` (those scoring more, all at hand), is a local maximum: no
    /// lattice neighbour scores higher. Its neighbours are scored afresh
    /// where `better` does not settle them.
    fn is_peak(
        &self,
        field: &LikelihoodField,
        cells_at: &impl Fn(i64) -> Vec<(i64, i64)>,
        nt: i64,
        (kt, k): KeptPose,
    ) -> bool {
        (kt - 1..=kt + 1).filter(|t| t.abs() <= nt).all(|t| {
            let cells = cells_at(t);
            (-1..=1).all(|db: i64| {
                (-1..=1).all(|da: i64| {
                    let (a, b) = (k.a + da, k.b + db);
                    let outside = a.abs() > self.nx || b.abs() > self.ny;
                    outside || (t, a, b) == (kt, k.a, k.b) || self.score(field, &cells, a, b, t) <= k.score
                })
            })
        })
    }
}

/// A lattice pose kept by a search, with its rotation step.
type KeptPose = (i64, Kept);

/// The scores a search of the lattice holds after finding the best pose,
/// for the rival's search.
enum Scores<'f> {
    /// Every rotation's slab (the exhaustive search).
    Slabs(Vec<Vec<f32>>),
    /// The pooled levels of the field (branch and bound), and per
    /// rotation (from the least) the blocks and poses its search dropped
    /// or kept within the rival's gap of the best then.
    Pyramid(Pyramid<'f>, Vec<Vec<Node>>),
}

/// What the search for the best lattice pose found.
struct Searched<'f> {
    field: &'f LikelihoodField,
    /// The best pose: the first in lattice order (rotation, row, column)
    /// of the highest score.
    best: LatticeBest,
    scores: Scores<'f>,
    /// Lattice poses and blocks scored.
    evaluated: usize,
}

/// Every lattice pose scored, one slab of sx·sy per rotation; the best
/// kept (`None`: an empty lattice).
fn exhaustive<'f>(
    field: &'f LikelihoodField,
    lattice: &Lattice,
    nt: i64,
    cells_at: &(impl Fn(i64) -> Vec<(i64, i64)> + Sync),
) -> Option<Searched<'f>> {
    let (nx, ny) = (lattice.nx, lattice.ny);
    let slabs: Vec<Vec<f32>> = (-nt..=nt)
        .into_par_iter()
        .map(|kt| lattice_slab(field, &cells_at(kt), nx, ny))
        .collect();
    let mut best: Option<LatticeBest> = None;
    for (slab, kt) in slabs.iter().zip(-nt..=nt) {
        for (score, (a, b)) in lattice.scores(slab, kt) {
            if best.is_none_or(|x| score > x.0) {
                best = Some((score, a, b, kt));
            }
        }
    }
    let evaluated = slabs.iter().map(Vec::len).sum();
    Some(Searched {
        field,
        best: best?,
        scores: Scores::Slabs(slabs),
        evaluated,
    })
}

/// The best lattice pose, found by branch and bound (the `bound`
/// module): rotations searched from the prior's mean outwards (in
/// parallel), sharing the best score found so far; every block whose
/// bound falls below it is dropped, and kept for the rival's search
/// where within `keep_ln` (zero or negative) of it.
fn bounded<'f>(
    field: &'f LikelihoodField,
    lattice: &Lattice,
    nt: i64,
    cells_at: &(impl Fn(i64) -> Vec<(i64, i64)> + Sync),
    keep_ln: f64,
) -> Option<Searched<'f>> {
    let best = SharedBest::new();
    let nodes = AtomicUsize::new(0);
    let pyramid = lattice.pyramid(field, nt, cells_at(0).len());
    let search = |kt: i64| -> (i64, Vec<KeptPose>, Vec<Node>) {
        let mut pruned = Vec::new();
        let kept = search_in(
            lattice,
            &pyramid,
            &cells_at(kt),
            kt,
            (&best, 0.0, None),
            &nodes,
            Some((keep_ln, &mut pruned)),
        );
        (kt, kept, pruned)
    };
    // Every pose kept is kept for the rival's search too, as a node.
    let mut frontier: Vec<Vec<Node>> = vec![Vec::new(); (2 * nt + 1) as usize];
    let file = |frontier: &mut Vec<Vec<Node>>, (kt, found, mut pruned): (i64, Vec<KeptPose>, Vec<Node>)| {
        pruned.extend(found.iter().map(|&(_, k)| (k.a, k.b, 0, k.score)));
        frontier[(kt + nt) as usize] = pruned;
        found
    };
    // The prior's mean first, which finds a good bound for all the rest;
    // then outwards, a few rotations per thread at a time, dropping the
    // poses overtaken after each batch, and the nodes left beyond reach.
    let mut kept = file(&mut frontier, search(0));
    let order: Vec<i64> = (1..=nt).flat_map(|k| [k, -k]).collect();
    for batch in order.chunks(BATCH_ROTATIONS) {
        let searched: Vec<_> = batch.par_iter().map(|&kt| search(kt)).collect();
        for s in searched {
            kept.extend(file(&mut frontier, s));
        }
        let top = best.get();
        kept.retain(|(_, k)| k.score >= top);
        for nodes in &mut frontier {
            nodes.retain(|n| n.3 >= top + keep_ln);
            nodes.shrink_to_fit();
        }
    }
    // The first in lattice order among equals, as the exhaustive search.
    let &(kt, k) = kept.iter().min_by_key(|&&(kt, k)| (kt, k.b, k.a))?;
    Some(Searched {
        field,
        best: (k.score, k.a, k.b, kt),
        scores: Scores::Pyramid(pyramid, frontier),
        evaluated: nodes.into_inner(),
    })
}

/// The lattice's prior at rotation `kt`, as a search bounds it.
fn rotation_prior<'l>(lattice: &'l Lattice, kt: i64) -> impl PriorTerm + 'l {
    let prior = lattice.prior;
    let theta = prior.mean.theta + kt as f64 * lattice.theta_step;
    GaussianTerm {
        exact: move |a, b| lattice.prior_at(a, b, kt),
        theta_term: GaussianTerm::theta_term(theta, prior.mean.theta, prior.sigma_theta_rad),
        form: GaussianTerm::form(lattice.turned, prior.sigma_forward_m, prior.sigma_left_m),
        res: lattice.res,
    }
}

/// One rotation's branch-and-bound search of its endpoint `cells` (see
/// [`RotationSearch`]): the poses found at least `margin_ln` below the
/// best score (`best`, shared), `excluded` left out.
fn rotation<'a>(
    lattice: &'a Lattice,
    pyramid: &'a Pyramid,
    cells: &'a [(i64, i64)],
    kt: i64,
    (best, margin_ln, excluded): (&'a SharedBest, f64, Option<Excluded>),
    nodes: &'a AtomicUsize,
) -> RotationSearch<'a, impl PriorTerm + 'a> {
    RotationSearch {
        pyramid,
        cells,
        block: Block {
            nx: lattice.nx,
            ny: lattice.ny,
        },
        prior: rotation_prior(lattice, kt),
        best,
        margin_ln,
        excluded,
        nodes,
    }
}

/// [`RotationSearch::search`] of rotation `kt`, the poses with it.
fn search_in(
    lattice: &Lattice,
    pyramid: &Pyramid,
    cells: &[(i64, i64)],
    kt: i64,
    sharing: (&SharedBest, f64, Option<Excluded>),
    nodes: &AtomicUsize,
    pruned: Option<(f64, &mut Vec<Node>)>,
) -> Vec<KeptPose> {
    let found = rotation(lattice, pyramid, cells, kt, sharing, nodes).search(pruned);
    found.into_iter().map(|k| (kt, k)).collect()
}

/// [`RotationSearch::resume`] of rotation `kt` from the nodes `from` a
/// narrower search of it set aside; its cells are made only where one of
/// them may hold a pose within the margin.
fn resume_in(
    lattice: &Lattice,
    pyramid: &Pyramid,
    cells_at: &impl Fn(i64) -> Vec<(i64, i64)>,
    kt: i64,
    sharing: (&SharedBest, f64, Option<Excluded>),
    nodes: &AtomicUsize,
    from: &[Node],
) -> Vec<KeptPose> {
    let (best, margin_ln, _) = sharing;
    if from.iter().all(|n| n.3 < best.get() + margin_ln) {
        return Vec::new();
    }
    let cells = cells_at(kt);
    let found = rotation(lattice, pyramid, &cells, kt, sharing, nodes).resume(from);
    found.into_iter().map(|k| (kt, k)).collect()
}

impl Lattice<'_> {
    /// The field's pooled levels as this lattice's search looks them up:
    /// from blocks as wide as the window, at most [`TOP_LEVEL`].
    /// Where the top level alone reads more cells, `n` points a
    /// rotation over `2·nt + 1` rotations, than [`WINDOW_READS_PER_CELL`]
    /// times those it would copy, the levels are read from a window over
    /// every rotation's cells (within the farthest point's reach of the
    /// prior's mean) moved by every translation searched.
    fn pyramid<'f>(&self, field: &'f LikelihoodField, nt: i64, n: usize) -> Pyramid<'f> {
        let side = (2 * self.nx.max(self.ny) + 1) as u64;
        let top = (side.next_power_of_two().trailing_zeros() as usize).min(TOP_LEVEL);
        let levels = field.levels();
        let step = 1i64 << top;
        let mean = self.prior.mean;
        let centre = (floor_i64(mean.x / self.res), floor_i64(mean.y / self.res));
        let r = (self.far_m / self.res).ceil() as i64 + 1;
        let lo = (centre.0 - r - self.nx, centre.1 - r - self.ny);
        let hi = (
            centre.0 + r + self.nx + 2 * step,
            centre.1 + r + self.ny + 2 * step,
        );
        let copied = ((hi.0 - lo.0 + 1) * (hi.1 - lo.1 + 1)) as f64;
        let pairs = |half: i64| ((2 * half + 1) as f64 / (2 * step) as f64).ceil();
        let top_reads = (2 * nt + 1) as f64 * pairs(self.nx) * pairs(self.ny) * 4.0 * n as f64;
        let window =
            (top_reads >= WINDOW_READS_PER_CELL * copied).then(|| field.window(levels, top, (lo, hi)));
        Pyramid {
            field,
            levels,
            top,
            window,
        }
    }
}

impl Searched<'_> {
    /// The rival peak: the best local maximum of the lattice's scores
    /// (no lattice neighbour scores higher) apart from the best pose
    /// (beyond [`RegisterConfig::rival_apart_m`] along x or y or
    /// [`RegisterConfig::rival_apart_rad`] in heading, never within one
    /// step), within [`RegisterConfig::rival_gap_ln`] of the best; the
    /// first in lattice order among equals. `Some(None)` where there is
    /// none; `None` where more than [`RegisterConfig::max_spread_poses`]
    /// poses apart score within the gap (a match that pins no pose).
    fn rival(
        &mut self,
        lattice: &Lattice,
        nt: i64,
        cells_at: &(impl Fn(i64) -> Vec<(i64, i64)> + Sync),
        config: &RegisterConfig,
    ) -> Option<Option<KeptPose>> {
        let best = self.best;
        let steps = |apart: f64, step: f64| ((apart / step).ceil() as i64).max(1);
        let (apart_a, apart_kt) = (
            steps(config.rival_apart_m, lattice.res),
            steps(config.rival_apart_rad, lattice.theta_step),
        );
        let near = |kt: i64| {
            ((kt - best.3).abs() <= apart_kt).then_some(Excluded {
                a: (best.1 - apart_a, best.1 + apart_a),
                b: (best.2 - apart_a, best.2 + apart_a),
            })
        };
        let margin = -config.rival_gap_ln.max(0.0);
        let mut candidates: Vec<KeptPose> = match &self.scores {
            Scores::Slabs(slabs) => slabs
                .iter()
                .zip(-nt..=nt)
                .flat_map(|(slab, kt)| {
                    lattice
                        .scores(slab, kt)
                        .filter(move |&(score, (a, b))| {
                            score - best.0 >= margin && !near(kt).is_some_and(|e| e.contains(a, b))
                        })
                        .map(move |(score, (a, b))| (kt, Kept { a, b, score }))
                })
                .collect(),
            Scores::Pyramid(pyramid, frontier) => {
                let shared = SharedBest::at(best.0);
                let nodes = AtomicUsize::new(0);
                let found = (-nt..=nt)
                    .into_par_iter()
                    .flat_map_iter(|kt| {
                        let from = &frontier[(kt + nt) as usize];
                        resume_in(
                            lattice,
                            pyramid,
                            cells_at,
                            kt,
                            (&shared, margin, near(kt)),
                            &nodes,
                            from,
                        )
                    })
                    .collect();
                self.evaluated += nodes.into_inner();
                found
            }
        };
        if candidates.len() > config.max_spread_poses {
            return None;
        }
        // Best first, lattice order among equals: the first peak is the rival.
        candidates.sort_by(|x, y| {
            y.1.score
                .total_cmp(&x.1.score)
                .then((x.0, x.1.b, x.1.a).cmp(&(y.0, y.1.b, y.1.a)))
        });
        Some(
            candidates
                .into_iter()
                .find(|&c| lattice.is_peak(self.field, cells_at, nt, c)),
        )
    }
}

/// A branch and bound copies the field into a window when its top level
/// alone reads at least this many cells per cell copied: a cell copied
/// costs about what a read through the tile table costs more than a read
/// from the window, and the levels below read more than the top. On the
/// two logs tried (intel every 3rd scan without odometry, aces with noisy
/// odometry), the time is the same from half to twice this.
const WINDOW_READS_PER_CELL: f64 = 1.0;

/// Rotations searched in parallel between two checks of the poses kept.
const BATCH_ROTATIONS: usize = 64;

/// The summed field value of the endpoint cells `cells` translated by every
/// `(a, b)` in `[-nx, nx] × [-ny, ny]` cells, row-major in `b`.
fn lattice_slab(field: &LikelihoodField, cells: &[(i64, i64)], nx: i64, ny: i64) -> Vec<f32> {
    let sx = (2 * nx + 1) as usize;
    let mut slab = vec![0f32; sx * (2 * ny + 1) as usize];
    for &(ci, cj) in cells {
        for b in -ny..=ny {
            // The translations along a row add the field's row there, a
            // slice at a time (a loop the compiler vectorises).
            field.add_row(ci - nx, cj + b, &mut slab[(b + ny) as usize * sx..][..sx]);
        }
    }
    slab
}

/// `ln 10⁻⁹` with room to spare (`e⁻²¹·⁷² ≈ 3.7·10⁻¹⁰`): poses whose
/// posterior weight is below this share of the best's count for nothing;
/// a posterior spread over more than [`RegisterConfig::max_spread_poses`]
/// poses above it is not trusted.
const NEGLIGIBLE_LN: f64 = -21.72;

/// The endpoints of a refinement with their obstacle neighbourhoods about
/// the pose it starts from, so that each exact value near the start scans
/// a few candidates instead of the k-d tree.
struct Anchored<'a> {
    field: &'a LikelihoodField,
    points: &'a [Point2],
    start: Pose2,
    near: Neighbourhood,
}

/// The score of a pose with its gradient and curvature in world
/// `(x, y, θ)`.
struct Curved {
    score: f64,
    gradient: Vector3<f64>,
    /// The exact Hessian (the nearest obstacles held).
    hessian: Matrix3<f64>,
    /// Its Gauss-Newton part (negative definite or zero): without the
    /// terms by which a point beyond `σ` of its wall bends upward, and
    /// without the heading's second derivative.
    gauss_newton: Matrix3<f64>,
}

impl<'a> Anchored<'a> {
    fn new(field: &'a LikelihoodField, points: &'a [Point2], start: Pose2, reach_m: f64) -> Self {
        let starts: Vec<Point2> = points.iter().map(|p| start.transform_point(*p)).collect();
        let near = field.neighbourhood(&starts, reach_m);
        Self {
            field,
            points,
            start,
            near,
        }
    }

    /// Whether endpoint `p` at `pose` lies within the neighbourhood's reach
    /// of its start: it moves by at most the translation plus `|p|` times
    /// the turn.
    fn within(&self, pose: &Pose2, p: &Point2) -> bool {
        let shift = pose.translation().distance(self.start.translation());
        let turn = wrap_angle(pose.theta - self.start.theta).abs();
        shift + p.norm() * turn <= self.near.reach_m
    }

    /// Sum of the exact field over the endpoints at `pose`, and how many
    /// lie within two σ of a mapped obstacle.
    fn evaluate(&self, pose: &Pose2) -> (f64, usize) {
        let floor = self.field.floor() as f64;
        // ln(ε + (1−ε)·e⁻²) expressed through the floor: ε = e^floor.
        let eps = floor.exp();
        let near = (eps + (1.0 - eps) * (-2.0f64).exp()).ln();
        let mut sum = 0.0;
        let mut matched = 0;
        for (k, p) in self.points.iter().enumerate() {
            let q = pose.transform_point(*p);
            let v = if self.within(pose, p) {
                self.field.exact_near(&self.near, k, q)
            } else {
                self.field.exact(q)
            };
            sum += v;
            matched += usize::from(v >= near);
        }
        (sum, matched)
    }

    /// The exact field summed over the endpoints at `pose`, with its
    /// derivatives (see [`Slope`](crate::field::Slope)): for an endpoint
    /// `q = R(θ)p + t`, `∂q/∂(x, y, θ) = [I | (−(q − t)_y, (q − t)_x)]` and
    /// `∂²q/∂θ² = −(q − t)`. With `surfaces`, an endpoint whose nearest
    /// obstacle lies on a line of them (see
    /// [`LikelihoodField::surface_normal`]) is held by that line alone:
    /// its derivatives are those of the Gaussian in its distance to the
    /// line, so that a wall sampled point by point does not claim to pin
    /// a slide along it.
    fn curved(&self, pose: &Pose2, surfaces: bool) -> Curved {
        let s2 = self.field.sigma2();
        let radius = 2.0 * s2.sqrt().max(self.field.resolution_m());
        let mut buffer = Vec::new();
        let mut c = Curved {
            score: 0.0,
            gradient: Vector3::zeros(),
            hessian: Matrix3::zeros(),
            gauss_newton: Matrix3::zeros(),
        };
        for (k, p) in self.points.iter().enumerate() {
            let q = pose.transform_point(*p);
            let slope = self.field.slope(&self.near, k, q, self.within(pose, p));
            c.score += slope.value;
            if slope.share == 0.0 {
                continue;
            }
            let r = nalgebra::Vector2::new(slope.offset[0], slope.offset[1]);
            let o = [q.x - r.x, q.y - r.y];
            let normal = surfaces
                .then(|| self.field.surface_normal(o, radius, &mut buffer))
                .flatten();
            // The offset the Gaussian sees, its share and the directions
            // it holds.
            let (r, w, held) = match normal {
                Some([nx, ny]) => {
                    let n = nalgebra::Vector2::new(nx, ny);
                    let r = n * r.dot(&n);
                    (r, self.field.share_at(q, r.norm_squared()), n * n.transpose())
                }
                None => (r, slope.share, nalgebra::Matrix2::identity()),
            };
            let (ux, uy) = (q.x - pose.x, q.y - pose.y);
            let j = nalgebra::Matrix2x3::new(1.0, 0.0, -uy, 0.0, 1.0, ux);
            let grad_q = -w / s2 * r;
            let flat = held * (-w / s2);
            let bend = r * r.transpose() * (w * (1.0 - w) / (s2 * s2));
            let jt = j.transpose();
            c.gradient += jt * grad_q;
            let gn = jt * flat * j;
            c.gauss_newton += gn;
            c.hessian += gn + jt * bend * j;
            c.hessian[(2, 2)] -= grad_q.dot(&nalgebra::Vector2::new(ux, uy));
        }
        c
    }
}

/// Gauss-Newton ascent of the exact score plus prior from the anchored
/// start, each step at most half a lattice step (halved until it gains),
/// until a step moves the pose by less than [`REFINED`] of one; the pose and
/// the score's curvature there, each endpoint held by the surface its
/// nearest obstacle lies on (its negated Hessian: the information of
/// Laplace's approximation; the Gauss-Newton curvature where the exact one
/// is not positive definite).
fn refine(anchored: &Anchored, prior: &PosePrior, res: f64, theta_step: f64) -> (Pose2, Matrix3<f64>) {
    // The prior's information (its covariance is positive definite: `check`).
    let prior_info = prior.covariance().try_inverse().unwrap_or_else(Matrix3::zeros);
    let off = |p: &Pose2| {
        Vector3::new(
            p.x - prior.mean.x,
            p.y - prior.mean.y,
            wrap_angle(p.theta - prior.mean.theta),
        )
    };
    let curved = |p: &Pose2, surfaces: bool| {
        let mut c = anchored.curved(p, surfaces);
        c.score += prior.log_density(p.x, p.y, p.theta);
        c.gradient -= prior_info * off(p);
        c.hessian -= prior_info;
        c.gauss_newton -= prior_info;
        c
    };
    let mut pose = anchored.start;
    let mut c = curved(&pose, false);
    for _ in 0..MAX_REFINE_STEPS {
        let Some(step) = (-c.gauss_newton).cholesky().map(|l| l.solve(&c.gradient)) else {
            break;
        };
        // Within half a lattice step.
        let scale = (0.5 * res / step.xy().norm().max(1e-300))
            .min(0.5 * theta_step / step.z.abs().max(1e-300))
            .min(1.0);
        let step = scale * step;
        let mut t = 1.0;
        let mut moved = None;
        for _ in 0..8 {
            let cand = Pose2::new(pose.x + t * step.x, pose.y + t * step.y, pose.theta + t * step.z);
            let at = curved(&cand, false);
            if at.score > c.score {
                moved = Some((cand, at));
                break;
            }
            t *= 0.5;
        }
        let Some((cand, at)) = moved else { break };
        (pose, c) = (cand, at);
        if t * step.xy().norm() < res * REFINED && t * step.z.abs() < theta_step * REFINED {
            break;
        }
    }
    let c = curved(&pose, true);
    let exact = -c.hessian;
    let exact = 0.5 * (exact + exact.transpose());
    let information = if exact.cholesky().is_some() {
        exact
    } else {
        -c.gauss_newton
    };
    (pose, information)
}

/// A refinement stops after a step shorter than this share of a lattice
/// step (a tenth of a millimetre on a 5 cm lattice).
const REFINED: f64 = 2e-3;

/// Gauss-Newton steps a refinement takes at most.
const MAX_REFINE_STEPS: usize = 20;

/// How far a refinement may move the pose from the search's best, in
/// lattice steps along each axis ([`may_accept`] counts on it). Gauss-Newton's
/// steps of at most half a lattice step reach 10 at most; the pattern
/// search, taking steps down to a sixteenth, has been seen to walk 24
/// steps of a fine rotation lattice along a flat ridge.
const REFINE_REACH_STEPS: f64 = 32.0;

/// Whether `pose` lies within [`REFINE_REACH_STEPS`] lattice steps of
/// `start` along each axis.
fn within_reach(pose: &Pose2, start: &Pose2, res: f64, theta_step: f64) -> bool {
    (pose.x - start.x).abs() <= REFINE_REACH_STEPS * res
        && (pose.y - start.y).abs() <= REFINE_REACH_STEPS * res
        && wrap_angle(pose.theta - start.theta).abs() <= REFINE_REACH_STEPS * theta_step
}

mod posterior;

#[cfg(test)]
mod tests;
