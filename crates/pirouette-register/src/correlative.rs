//! Correlative registration of a sweep against a map: an exhaustive search
//! over translation and rotation, then a local refinement below one cell,
//! with the covariance of the pose from the spread of the search.

use crate::bound::{search_rotation, Block, GaussianTerm, Kept, Pyramid, SharedBest, TOP_LEVEL};
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
        let r = self.mean.tangent_rotation();
        let d = Matrix3::from_diagonal(&Vector3::new(
            self.sigma_forward_m.powi(2),
            self.sigma_left_m.powi(2),
            self.sigma_theta_rad.powi(2),
        ));
        r * d * r.transpose()
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
    /// The most lattice poses the posterior may spread over (weights of
    /// at least `10⁻⁹` of the best's) for the match to be trusted: one
    /// that loose does not pin the pose (a featureless view, or a wide
    /// search through look-alike places), and holding its poses would
    /// take 32 MB per million. The branch-and-bound search counts, after
    /// every batch of rotations, the poses near the best found so far (a
    /// superset of the final ones): it may give up on a posterior just
    /// under the limit that the exhaustive search keeps.
    pub max_spread_poses: usize,
}

/// How [`register`] searches its lattice. Both find the same best pose and
/// the same posterior (every pose whose weight counts, scored alike and
/// summed in the same order); they differ only in time (and, near
/// [`RegisterConfig::max_spread_poses`], in when they give up).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Search {
    /// Score every pose: the reference.
    Exhaustive,
    /// Score blocks of poses by an upper bound first and drop those that
    /// cannot count (max-pooled levels of the field bound each block).
    #[default]
    BranchAndBound,
}

impl Default for RegisterConfig {
    /// σ 1.5 cm (a 1 cm map cell's quantisation and the profile's few
    /// millimetres of range noise); ε 0.2 on unknown ground; ε 0.02 on seen
    /// floor (a profile's false ranges are a few per cent of its bins);
    /// obstacles above and floor below `map_server`'s 0.65 and 0.196;
    /// a ±3σ window of at most ±1 m; endpoints counted once per 3 cm (2σ:
    /// closer ones share their error); at least 10 of them (30 cm of edge)
    /// on mapped obstacles; the branch-and-bound search; any peak beyond the
    /// best one's lattice neighbours a rival; a posterior over more than 2²⁰
    /// poses not trusted.
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
            search: Search::BranchAndBound,
            rival_apart_m: 0.0,
            rival_apart_rad: 0.0,
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
/// of the lattice's scores that is not the best pose or its neighbour,
/// among the poses whose posterior weight counts (at least `10⁻⁹` of the
/// best's). Its weight is in the covariance already; how far it falls
/// below the best says how ambiguous the match is (a gap of a few nats on
/// a wide search means a look-alike pose nearly as good).
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
/// cell, translations one cell apart. It finds every lattice pose whose
/// posterior weight (score plus prior, exponentiated) is at least `10⁻⁹` of
/// the best's, by branch and bound or exhaustively
/// ([`RegisterConfig::search`]). The best lattice pose is then refined by a
/// shrinking pattern search on the exact field down to 1/16 cell. The
/// covariance is that of the lattice's posterior, so that it grows along a
/// corridor and with few endpoints, and a rival peak within the posterior
/// is reported ([`Registration::rival`]).
pub fn register(
    field: &LikelihoodField,
    points_robot: &[Point2],
    prior: &PosePrior,
    config: &RegisterConfig,
) -> Result<Registration, RegisterError> {
    prior.check()?;
    let res = field.resolution_m();
    let points = thin_points(points_robot, config.spacing_m.max(res));
    let fallback = |mean_ll: f64, matched: usize, evaluated: usize| Registration {
        pose: prior.mean,
        covariance: prior.covariance(),
        mean_log_likelihood: mean_ll,
        points: points.len(),
        matched,
        accepted: false,
        evaluated,
        rival: None,
    };
    if points.len() < config.min_matched || field.obstacle_points() == 0 {
        return Ok(fallback(field.floor() as f64, 0, 0));
    }
    // The lattice about the prior's mean, searched for every pose whose
    // posterior weight counts.
    let (lattice, nt) = Lattice::around(prior, &points, res, config);
    let cells_at = |kt: i64| lattice.cells_at(&points, kt);
    let found = match config.search {
        Search::Exhaustive => exhaustive(field, &lattice, nt, &cells_at, config.max_spread_poses),
        Search::BranchAndBound => bounded(field, &lattice, nt, &cells_at, config.max_spread_poses),
    };
    let (kept, evaluated) = match found {
        Found::Poses(kept, evaluated) => (kept, evaluated),
        Found::SpreadOut(evaluated) => return Ok(fallback(field.floor() as f64, 0, evaluated)),
    };
    // Its best pose, spread and rival peak.
    let (best, covariance, rival) = lattice.posterior(kept, config);
    let theta_step = lattice.theta_step;
    let start = Pose2::new(
        prior.mean.x + best.1 as f64 * res,
        prior.mean.y + best.2 as f64 * res,
        prior.mean.theta + best.3 as f64 * theta_step,
    );
    // Refinement moves the pose by about a cell: the obstacles near each
    // endpoint's start decide its exact values there.
    let anchored = Anchored::new(field, &points, start, res);
    let pose = refine(&anchored, prior, res, theta_step);
    let (sum, matched) = anchored.evaluate(&pose);
    let mean_ll = sum / points.len() as f64;
    if matched < config.min_matched {
        return Ok(fallback(mean_ll, matched, evaluated));
    }
    Ok(Registration {
        pose,
        covariance,
        mean_log_likelihood: mean_ll,
        points: points.len(),
        matched,
        accepted: true,
        evaluated,
        rival,
    })
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

    /// The posterior of the poses a search kept: its best (the first of
    /// equal scores in lattice order), covariance and rival peak.
    fn posterior(
        &self,
        mut kept: Vec<KeptPose>,
        config: &RegisterConfig,
    ) -> (LatticeBest, Matrix3<f64>, Option<Rival>) {
        // In lattice order, rotation by rotation, row by row: the order of
        // the exhaustive search's sums.
        kept.sort_by_key(|&(kt, k)| (kt, k.b, k.a));
        let best = kept.iter().fold((f64::NEG_INFINITY, 0, 0, 0), |b, &(kt, k)| {
            if k.score > b.0 {
                (k.score, k.a, k.b, kt)
            } else {
                b
            }
        });
        let posterior = kept.iter().map(|&(kt, k)| (k.score, self.pose(k.a, k.b, kt)));
        let covariance = lattice_covariance(posterior, best.0, self.res, self.theta_step);
        let steps = |apart: f64, step: f64| ((apart / step).ceil() as i64).max(1);
        let apart = Apart {
            a: steps(config.rival_apart_m, self.res),
            kt: steps(config.rival_apart_rad, self.theta_step),
        };
        let rival = rival_peak(&kept, best, self.nx, self.ny, apart).map(|(kt, k)| {
            let x = self.pose(k.a, k.b, kt);
            Rival {
                pose: Pose2::new(x[0], x[1], x[2]),
                below_best_ln: best.0 - k.score,
            }
        });
        (best, covariance, rival)
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
}

/// A lattice pose kept for the posterior, with its rotation step.
type KeptPose = (i64, Kept);

/// What a search of the lattice found.
enum Found {
    /// The poses whose posterior weight counts (unsorted), and the count
    /// of poses and blocks scored.
    Poses(Vec<KeptPose>, usize),
    /// More than [`RegisterConfig::max_spread_poses`] poses count: the count scored so
    /// far.
    SpreadOut(usize),
}

/// Every lattice pose scored, one slab of sx·sy per rotation; kept are those
/// whose posterior weight can count ([`NEGLIGIBLE_LN`] below the best at
/// most), unsorted, and the count of poses scored.
fn exhaustive(
    field: &LikelihoodField,
    lattice: &Lattice,
    nt: i64,
    cells_at: &(impl Fn(i64) -> Vec<(i64, i64)> + Sync),
    max_kept: usize,
) -> Found {
    let (nx, ny) = (lattice.nx, lattice.ny);
    let slabs: Vec<(Vec<f32>, f64)> = (-nt..=nt)
        .into_par_iter()
        .map(|kt| {
            let slab = lattice_slab(field, &cells_at(kt), nx, ny);
            let best = lattice
                .scores(&slab, kt)
                .fold(f64::NEG_INFINITY, |b, (s, _)| b.max(s));
            (slab, best)
        })
        .collect();
    let best = slabs.iter().fold(f64::NEG_INFINITY, |b, s| b.max(s.1));
    let evaluated = slabs.iter().map(|s| s.0.len()).sum();
    let counts = |(slab, kt): (&(Vec<f32>, f64), i64)| {
        lattice
            .scores(&slab.0, kt)
            .filter(|(score, _)| score - best >= NEGLIGIBLE_LN)
            .count()
    };
    if slabs.iter().zip(-nt..=nt).map(counts).sum::<usize>() > max_kept {
        return Found::SpreadOut(evaluated);
    }
    // The poses are kept in a second pass over the slabs, which a rotation
    // whose best pose is negligible beside the best of all skips: storing
    // all (32 bytes each) would take hundreds of megabytes on a wide
    // search.
    let kept = slabs
        .iter()
        .zip(-nt..=nt)
        .filter(|((_, own), _)| own - best >= NEGLIGIBLE_LN)
        .flat_map(|((slab, _), kt)| {
            lattice
                .scores(slab, kt)
                .filter(|(score, _)| score - best >= NEGLIGIBLE_LN)
                .map(move |(score, (a, b))| (kt, Kept { a, b, score }))
        })
        .collect();
    Found::Poses(kept, evaluated)
}

/// The poses the exhaustive search keeps, found by branch and bound
/// (the `bound` module): rotations searched from the prior's mean outwards
/// (in parallel), sharing the best score found so far.
fn bounded(
    field: &LikelihoodField,
    lattice: &Lattice,
    nt: i64,
    cells_at: &(impl Fn(i64) -> Vec<(i64, i64)> + Sync),
    max_kept: usize,
) -> Found {
    let best = SharedBest::new();
    let nodes = AtomicUsize::new(0);
    let block = Block {
        nx: lattice.nx,
        ny: lattice.ny,
    };
    // The cells every rotation's endpoints fall in, and those the search
    // can reach from them: the pyramid's block. A rotation's cells are
    // made again for its search rather than all held at once (a wide
    // search turns through hundreds of rotations: tens of megabytes).
    let empty = ((i64::MAX, i64::MAX), (i64::MIN, i64::MIN));
    let (lo, hi) = (-nt..=nt)
        .into_par_iter()
        .map(|kt| {
            cells_at(kt).iter().fold(empty, |(lo, hi), &(i, j)| {
                ((lo.0.min(i), lo.1.min(j)), (hi.0.max(i), hi.1.max(j)))
            })
        })
        .reduce(
            || empty,
            |(lo, hi), (l, h)| ((lo.0.min(l.0), lo.1.min(l.1)), (hi.0.max(h.0), hi.1.max(h.1))),
        );
    if lo.0 > hi.0 {
        return Found::Poses(Vec::new(), 0);
    }
    let side = (2 * block.nx.max(block.ny) + 1) as u64;
    let top = (side.next_power_of_two().trailing_zeros() as usize).min(TOP_LEVEL);
    // Only the part of that block a level's block can reach the field
    // from: every other look-up is of cells beyond the field, at its floor
    // (the pyramid answers the floor beyond its block). Far endpoints swept
    // over the rotations span a far larger block than the field holds.
    let (min, width, height, _) = field.raw();
    let pad = (1i64 << top) - 1;
    let lo = (
        (lo.0 - block.nx).max(min.0 - pad),
        (lo.1 - block.ny).max(min.1 - pad),
    );
    let hi = (
        (hi.0 + block.nx).min(min.0 + width as i64 - 1).max(lo.0),
        (hi.1 + block.ny).min(min.1 + height as i64 - 1).max(lo.1),
    );
    let pyramid = Pyramid::new(field, lo, hi, top);
    let prior = lattice.prior;
    let form = GaussianTerm::form(lattice.turned, prior.sigma_forward_m, prior.sigma_left_m);
    let search = |kt: i64| -> Vec<KeptPose> {
        let theta = prior.mean.theta + kt as f64 * lattice.theta_step;
        let term = GaussianTerm {
            exact: |a, b| lattice.prior_at(a, b, kt),
            theta_term: GaussianTerm::theta_term(theta, prior.mean.theta, prior.sigma_theta_rad),
            form,
            res: lattice.res,
        };
        let cells = cells_at(kt);
        search_rotation(&pyramid, &cells, &block, &term, &best, NEGLIGIBLE_LN, &nodes)
            .into_iter()
            .map(|k| (kt, k))
            .collect()
    };
    // The prior's mean first, which finds a good bound for all the rest;
    // then outwards, a few rotations per thread at a time. A pose kept
    // before the best was known may lie below its margin: those are
    // dropped after each batch, and the search gives up once more poses
    // than a trusted match spreads over still count.
    let mut kept = search(0);
    let order: Vec<i64> = (1..=nt).flat_map(|k| [k, -k]).collect();
    for batch in order.chunks(BATCH_ROTATIONS) {
        kept.extend(
            batch
                .par_iter()
                .flat_map_iter(|&kt| search(kt))
                .collect::<Vec<_>>(),
        );
        let top = best.get();
        kept.retain(|(_, k)| k.score - top >= NEGLIGIBLE_LN);
        if kept.len() > max_kept {
            return Found::SpreadOut(nodes.into_inner());
        }
    }
    Found::Poses(kept, nodes.into_inner())
}

/// Rotations searched in parallel between two checks of the poses kept.
const BATCH_ROTATIONS: usize = 64;

/// How far apart in lattice steps two poses are different answers: more
/// than `a` translation steps along either axis, or more than `kt`
/// rotation steps.
#[derive(Debug, Clone, Copy)]
struct Apart {
    a: i64,
    kt: i64,
}

impl Apart {
    /// Whether lattice pose `(kt, a, b)` is the best pose's own answer.
    fn near(&self, best: LatticeBest, kt: i64, a: i64, b: i64) -> bool {
        (kt - best.3).abs() <= self.kt && (a - best.1).abs() <= self.a && (b - best.2).abs() <= self.a
    }
}

/// The best local maximum of the kept poses' scores (no kept lattice
/// neighbour scores higher) that is `apart` from the best pose; the
/// first in lattice order among equals. `kept` is sorted in
/// lattice order (rotation, then row, then column), every pose within the
/// `nx × ny` translation steps of `lattice`.
///
/// Neighbours are looked up in dense slabs of three rotations at a time
/// (a wide search keeps a million poses: a map of them all would cost
/// tens of megabytes).
fn rival_peak(kept: &[KeptPose], best: LatticeBest, nx: i64, ny: i64, apart: Apart) -> Option<KeptPose> {
    let (sx, sy) = ((2 * nx + 1) as usize, (2 * ny + 1) as usize);
    let near = |kt: i64, a: i64, b: i64| apart.near(best, kt, a, b);
    // Each rotation's run of `kept`.
    let mut runs: Vec<(i64, std::ops::Range<usize>)> = Vec::new();
    for (i, &(kt, _)) in kept.iter().enumerate() {
        match runs.last_mut() {
            Some((t, r)) if *t == kt => r.end = i + 1,
            _ => runs.push((kt, i..i + 1)),
        }
    }
    // Slab `kt mod 3` holds run `held[kt mod 3]`'s scores (the floor of
    // the scores elsewhere): a rotation's two neighbours are in the others.
    let mut slabs = [(); 3].map(|()| vec![f64::NEG_INFINITY; sx * sy]);
    let mut held: [Option<usize>; 3] = [None; 3];
    let at = |a: i64, b: i64| (b + ny) as usize * sx + (a + nx) as usize;
    let mut rival: Option<KeptPose> = None;
    for (n, (kt, run)) in runs.iter().enumerate() {
        let kt = *kt;
        let wanted = [n.checked_sub(1), Some(n), Some(n + 1)]
            .map(|m| m.filter(|&m| runs.get(m).is_some_and(|r| (r.0 - kt).abs() <= 1)));
        for m in wanted.into_iter().flatten() {
            let slot = runs[m].0.rem_euclid(3) as usize;
            if held[slot] != Some(m) {
                if let Some(old) = held[slot] {
                    for &(_, k) in &kept[runs[old].1.clone()] {
                        slabs[slot][at(k.a, k.b)] = f64::NEG_INFINITY;
                    }
                }
                for &(_, k) in &kept[runs[m].1.clone()] {
                    slabs[slot][at(k.a, k.b)] = k.score;
                }
                held[slot] = Some(m);
            }
        }
        // The slabs of rotations kt − 1, kt, kt + 1 that hold kept poses.
        let neighbours: Vec<&Vec<f64>> = (kt - 1..=kt + 1)
            .filter_map(|t| {
                let slot = t.rem_euclid(3) as usize;
                held[slot].filter(|&m| runs[m].0 == t).map(|_| &slabs[slot])
            })
            .collect();
        for &(_, k) in &kept[run.clone()] {
            if near(kt, k.a, k.b) || rival.is_some_and(|r| r.1.score >= k.score) {
                continue;
            }
            let peak = neighbours.iter().all(|slab| {
                (-1..=1).all(|db: i64| {
                    (-1..=1).all(|da: i64| {
                        let (a, b) = (k.a + da, k.b + db);
                        a < -nx || a > nx || b < -ny || b > ny || slab[at(a, b)] <= k.score
                    })
                })
            });
            if peak {
                rival = Some((kt, k));
            }
        }
    }
    rival
}

/// The summed field value of the endpoint cells `cells` translated by every
/// `(a, b)` in `[-nx, nx] × [-ny, ny]` cells, row-major in `b`.
fn lattice_slab(field: &LikelihoodField, cells: &[(i64, i64)], nx: i64, ny: i64) -> Vec<f32> {
    let (min_cell, width, height, values) = field.raw();
    let floor = field.floor();
    let sx = (2 * nx + 1) as usize;
    let mut slab = vec![0f32; sx * (2 * ny + 1) as usize];
    for &(ci, cj) in cells {
        let (x0, y0) = (ci - min_cell.0, cj - min_cell.1);
        for b in -ny..=ny {
            let y = y0 + b;
            let row = &mut slab[(b + ny) as usize * sx..][..sx];
            if y < 0 || y >= height as i64 {
                row.iter_mut().for_each(|v| *v += floor);
                continue;
            }
            let field_row = &values[y as usize * width..][..width];
            // The translations that land this endpoint inside the field's
            // row (`a_lo..a_hi`) add its values, slice to slice (a loop the
            // compiler vectorises); the others add the floor.
            let a_lo = (-x0).clamp(-nx, nx + 1);
            let a_hi = (width as i64 - x0).clamp(a_lo, nx + 1);
            let (left, rest) = row.split_at_mut((a_lo + nx) as usize);
            let (inside, right) = rest.split_at_mut((a_hi - a_lo) as usize);
            left.iter_mut().chain(right.iter_mut()).for_each(|v| *v += floor);
            if !inside.is_empty() {
                let from = &field_row[(x0 + a_lo) as usize..][..inside.len()];
                inside.iter_mut().zip(from).for_each(|(v, f)| *v += f);
            }
        }
    }
    slab
}

/// The smallest posterior weight `exp(score − best)` a lattice pose adds
/// to the covariance with.
const NEGLIGIBLE: f64 = 1e-9;

/// A log weight below which a pose's weight is below [`NEGLIGIBLE`] with
/// room to spare (`e⁻²¹·⁷² ≈ 3.7·10⁻¹⁰`): such poses are skipped without
/// their `exp`, which leaves the sums exactly as they were.
const NEGLIGIBLE_LN: f64 = -21.72;

/// The covariance of the lattice's posterior `exp(score − best)`, with the
/// lattice's own quantisation (a uniform cell) added so that a sharp peak
/// still has a honest, non-zero spread.
fn lattice_covariance(
    posterior: impl IntoIterator<Item = (f64, Vector3<f64>)>,
    best: f64,
    res: f64,
    theta_step: f64,
) -> Matrix3<f64> {
    let mut w_sum = 0.0;
    let mut mean = Vector3::zeros();
    let mut second = Matrix3::zeros();
    for (score, x) in posterior {
        // (Far below the best, no `exp` is needed to know.)
        if score - best < NEGLIGIBLE_LN {
            continue;
        }
        let w = (score - best).exp();
        if w < NEGLIGIBLE {
            continue;
        }
        w_sum += w;
        mean += w * x;
        second += w * x * x.transpose();
    }
    mean /= w_sum;
    let cov = second / w_sum - mean * mean.transpose();
    let quant = Matrix3::from_diagonal(&Vector3::new(
        res * res / 12.0,
        res * res / 12.0,
        theta_step * theta_step / 12.0,
    ));
    // Symmetrised against rounding.
    0.5 * (cov + cov.transpose()) + quant
}

/// The endpoints of a refinement with their obstacle neighbourhoods about
/// the pose it starts from, so that each exact value near the start scans
/// a few candidates instead of the k-d tree.
struct Anchored<'a> {
    field: &'a LikelihoodField,
    points: &'a [Point2],
    start: Pose2,
    near: Neighbourhood,
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

    /// Sum of the exact field over the endpoints at `pose`, and how many
    /// lie within two σ of a mapped obstacle.
    fn evaluate(&self, pose: &Pose2) -> (f64, usize) {
        let floor = self.field.floor() as f64;
        // ln(ε + (1−ε)·e⁻²) expressed through the floor: ε = e^floor.
        let eps = floor.exp();
        let near = (eps + (1.0 - eps) * (-2.0f64).exp()).ln();
        // An endpoint `p` moves from its start by at most the translation
        // plus `|p|` times the turn.
        let shift = pose.translation().distance(self.start.translation());
        let turn = wrap_angle(pose.theta - self.start.theta).abs();
        let mut sum = 0.0;
        let mut matched = 0;
        for (k, p) in self.points.iter().enumerate() {
            let q = pose.transform_point(*p);
            let v = if shift + p.norm() * turn <= self.near.reach_m {
                self.field.exact_near(&self.near, k, q)
            } else {
                self.field.exact(q)
            };
            sum += v;
            matched += usize::from(v >= near);
        }
        (sum, matched)
    }
}

/// Pattern search on the exact score plus prior, from `start`,
/// with steps halving from half a lattice step to 1/16 of it.
fn refine(anchored: &Anchored, prior: &PosePrior, res: f64, theta_step: f64) -> Pose2 {
    // A third of the candidates are poses scored before (the same bits,
    // reached again after a move): each is scored once.
    let mut scored = std::collections::HashMap::new();
    let mut score = |p: &Pose2| {
        *scored
            .entry((p.x.to_bits(), p.y.to_bits(), p.theta.to_bits()))
            .or_insert_with(|| anchored.evaluate(p).0 + prior.log_density(p.x, p.y, p.theta))
    };
    let mut pose = anchored.start;
    let mut best = score(&pose);
    let (mut step_xy, mut step_t) = (0.5 * res, 0.5 * theta_step);
    while step_xy >= res / 16.0 {
        let mut moved = false;
        for dt in [-1.0, 0.0, 1.0] {
            for dy in [-1.0, 0.0, 1.0] {
                for dx in [-1.0, 0.0, 1.0] {
                    if dx == 0.0 && dy == 0.0 && dt == 0.0 {
                        continue;
                    }
                    let cand = Pose2::new(
                        pose.x + dx * step_xy,
                        pose.y + dy * step_xy,
                        pose.theta + dt * step_t,
                    );
                    let s = score(&cand);
                    if s > best {
                        best = s;
                        pose = cand;
                        moved = true;
                    }
                }
            }
        }
        if !moved {
            step_xy *= 0.5;
            step_t *= 0.5;
        }
    }
    pose
}

#[cfg(test)]
mod tests;
