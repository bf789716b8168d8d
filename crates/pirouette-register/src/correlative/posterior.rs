//! The registration whose covariance is its lattice's whole posterior
//! ([`Covariance::Posterior`](super::Covariance::Posterior)): every lattice
//! pose within `10⁻⁹` of the best's weight found (by branch and bound or
//! exhaustively), their weighted spread the covariance, the best refined
//! by a shrinking pattern search on the exact field. Broad and
//! many-peaked posteriors (a camera frame's narrow view) keep their whole
//! spread here, which Laplace's curvature at one peak does not.

use super::*;
use crate::field::POOLED_LEVELS;

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
pub(super) fn register_posterior(
    field: &LikelihoodField,
    points_robot: &[Point2],
    prior: &PosePrior,
    config: &RegisterConfig,
) -> Result<Registration, RegisterError> {
    let points = thinned(field, points_robot, prior, config)?;
    let res = field.resolution_m();
    let fallback = |mean_ll, matched, evaluated| untrusted(prior, points.len(), mean_ll, matched, evaluated);
    if points.len() < config.min_matched || field.obstacle_points() == 0 {
        return Ok(fallback(field.floor() as f64, 0, 0));
    }
    // The lattice about the prior's mean, searched for every pose whose
    // posterior weight counts.
    let (lattice, nt) = Lattice::around(prior, &points, res, config);
    let cells_at = |kt: i64| lattice.cells_at(&points, kt);
    // Both searches keep the same poses. Branch and bound needs the
    // field's pooled levels: where they are not made yet and scoring every
    // pose looks up fewer cells than making them would write, every pose
    // is scored (a small window over a wide field: a camera's frame).
    let poses = (2 * lattice.nx + 1) * (2 * lattice.ny + 1) * (2 * nt + 1);
    let scoring_all = (poses as u64).saturating_mul(points.len() as u64);
    let making_levels = (field.level_cells() * POOLED_LEVELS) as u64;
    let exhaustive = match config.search {
        Search::Exhaustive => true,
        Search::BranchAndBound => false,
        Search::Cheaper => !field.has_levels() && scoring_all <= making_levels,
    };
    let found = if exhaustive {
        exhaustive_posterior(field, &lattice, nt, &cells_at, config.max_spread_poses)
    } else {
        bounded_posterior(field, &lattice, nt, &cells_at, config.max_spread_poses)
    };
    let (kept, evaluated) = match found {
        Found::Poses(kept, evaluated) => (kept, evaluated),
        Found::SpreadOut(evaluated) => return Ok(fallback(field.floor() as f64, 0, evaluated)),
    };
    // Its best pose, spread and rival peak.
    let (best, covariance, rival) = posterior(&lattice, kept, config);
    let theta_step = lattice.theta_step;
    let start = Pose2::new(
        prior.mean.x + best.1 as f64 * res,
        prior.mean.y + best.2 as f64 * res,
        prior.mean.theta + best.3 as f64 * theta_step,
    );
    // Refinement moves the pose by about a cell: the obstacles near each
    // endpoint's start decide its exact values there.
    let anchored = Anchored::new(field, &points, start, res);
    let pose = pattern_refine(&anchored, prior, res, theta_step);
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

/// The posterior of the poses a search kept: its best (the first of
/// equal scores in lattice order), covariance and rival peak.
fn posterior(
    lattice: &Lattice,
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
    let posterior = kept.iter().map(|&(kt, k)| (k.score, lattice.pose(k.a, k.b, kt)));
    let covariance = lattice_covariance(posterior, best.0, lattice.res, lattice.theta_step);
    let steps = |apart: f64, step: f64| ((apart / step).ceil() as i64).max(1);
    let apart = Apart {
        a: steps(config.rival_apart_m, lattice.res),
        kt: steps(config.rival_apart_rad, lattice.theta_step),
    };
    let rival = rival_peak(&kept, best, lattice.nx, lattice.ny, apart).map(|(kt, k)| {
        let x = lattice.pose(k.a, k.b, kt);
        Rival {
            pose: Pose2::new(x[0], x[1], x[2]),
            below_best_ln: best.0 - k.score,
        }
    });
    (best, covariance, rival)
}

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
fn exhaustive_posterior(
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
fn bounded_posterior(
    field: &LikelihoodField,
    lattice: &Lattice,
    nt: i64,
    cells_at: &(impl Fn(i64) -> Vec<(i64, i64)> + Sync),
    max_kept: usize,
) -> Found {
    let best = SharedBest::new();
    let nodes = AtomicUsize::new(0);
    let pyramid = lattice.pyramid(field, nt, cells_at(0).len());
    let search = |kt: i64| -> Vec<KeptPose> {
        search_in(
            lattice,
            &pyramid,
            &cells_at(kt),
            kt,
            (&best, NEGLIGIBLE_LN, None),
            &nodes,
            None,
        )
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

/// The smallest posterior weight `exp(score − best)` a lattice pose adds
/// to the covariance with.
const NEGLIGIBLE: f64 = 1e-9;

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

/// Pattern search on the exact score plus prior, from `start`,
/// with steps halving from half a lattice step to 1/16 of it, within
/// [`REFINE_REACH_STEPS`](super::REFINE_REACH_STEPS) lattice steps of
/// `start` along each axis.
fn pattern_refine(anchored: &Anchored, prior: &PosePrior, res: f64, theta_step: f64) -> Pose2 {
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
                    if !super::within_reach(&cand, &anchored.start, res, theta_step) {
                        continue;
                    }
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
