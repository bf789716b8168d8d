//! Wrong loop closures found and left out: graduated non-convexity with a
//! truncated least-squares cost (Yang, Antonante, Tzoumas and Carlone,
//! "Graduated Non-Convexity for Robust Spatial Perception", 2020).
//!
//! A loop closure is an inlier while its squared residual `s = eᵀ Ω e`
//! stays below a threshold `c̄²`; the truncated cost `min(s, c̄²)` is not
//! convex, so it is approached through a family of surrogates, from
//! nearly convex (`μ` small) to the truncated cost itself (`μ` large).
//! Each round solves the graph weighted by the surrogate's weights
//! (`w = 1` below `μ/(μ+1)·c̄²`, `0` above `(μ+1)/μ·c̄²`,
//! `c̄·√(μ(μ+1)/s) − μ` between) from the last round's poses, then grows
//! `μ`; it stops once every weight is 0 or 1.

use crate::consistency::consistent_loops;
use crate::{innovation_chi2, optimise, GraphError, OptimiseConfig, PoseGraph, Summary};

/// χ² with 3 degrees of freedom at 99.9 %: an edge whose squared
/// residual is above it at the solution disagrees with the rest of the
/// graph beyond its stated noise.
pub const CHI2_3_999: f64 = 16.27;

/// Settings of [`reject_outliers`].
#[derive(Debug, Clone, PartialEq)]
pub struct OutlierConfig {
    /// The threshold `c̄²` on an edge's squared residual `eᵀ Ω e`.
    pub threshold_chi2: f64,
    /// `μ` grows by this factor each round.
    pub mu_factor: f64,
    /// At most this many rounds.
    pub max_rounds: usize,
    /// At most this many solver steps a round (each starts where the last
    /// ended).
    pub round_iterations: usize,
    /// The solves before and after the rounds (and the rounds' but for
    /// their steps).
    pub solve: OptimiseConfig,
    /// Before any solve, [`solve_from_starts`] checks the candidates
    /// against each other at this χ² ([`consistent_loops`]) and leaves out
    /// all but the largest consistent set; those that fit its solution
    /// come back (`None`: no check).
    pub pairwise_chi2: Option<f64>,
}

impl Default for OutlierConfig {
    /// `c̄²` χ²₃ at 99.9 % (16.27); `μ` × 1.4 a round (the paper's), at
    /// most 100 rounds of at most 20 solver steps each; loop closures
    /// checked pairwise at the same χ² first.
    fn default() -> Self {
        Self {
            threshold_chi2: CHI2_3_999,
            mu_factor: 1.4,
            max_rounds: 100,
            round_iterations: 20,
            solve: OptimiseConfig::default(),
            pairwise_chi2: Some(CHI2_3_999),
        }
    }
}

/// What [`reject_outliers`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct Rejection {
    /// The candidate edges left out (their indices in the graph), in order.
    pub rejected: Vec<usize>,
    /// Those of them left out before any solve, as inconsistent with the
    /// largest consistent set of candidates (and not fitting its
    /// solution), in order.
    pub inconsistent: Vec<usize>,
    /// Rounds of graduated non-convexity run (0 where the solution had no
    /// candidate above the threshold).
    pub rounds: usize,
    /// The last solve, over the edges kept: χ² there counts only them.
    pub summary: Summary,
}

/// Solves `graph` from its poses, and where a `candidates` edge (loop
/// closures: edges the rest of the graph can do without) then lies above
/// the threshold, finds the inliers by graduated non-convexity and solves
/// again over them alone. The graph keeps every edge as it was; its poses
/// are the solution over the edges kept.
///
/// # Errors
/// As [`optimise`] (the graph's own check; a system that is not positive
/// definite).
pub fn reject_outliers(
    graph: &mut PoseGraph,
    candidates: &[usize],
    config: &OutlierConfig,
) -> Result<Rejection, GraphError> {
    graph.check()?;
    graph.check_edge_indices(candidates, "an outlier candidate")?;
    let summary = optimise(graph, &config.solve)?;
    let chi2 = |g: &PoseGraph, k: usize| {
        let e = &g.edges[k];
        e.chi2(&g.poses[e.from], &g.poses[e.to])
    };
    let c2 = config.threshold_chi2;
    let worst = candidates.iter().map(|&k| chi2(graph, k)).fold(0.0, f64::max);
    if worst <= c2 {
        return Ok(Rejection {
            rejected: Vec::new(),
            inconsistent: Vec::new(),
            rounds: 0,
            summary,
        });
    }
    let original: Vec<[[f64; 3]; 3]> = graph.edges.iter().map(|e| e.information).collect();
    let mut weights = vec![1.0; candidates.len()];
    // The first surrogate is convex over every residual seen (μ such that
    // the largest lies at the edge of its convex range).
    let mut mu = c2 / (2.0 * worst - c2);
    let mut rounds = 0;
    while rounds < config.max_rounds {
        rounds += 1;
        for (w, &k) in weights.iter_mut().zip(candidates) {
            let s = chi2(graph, k);
            *w = if s <= mu / (mu + 1.0) * c2 {
                1.0
            } else if s >= (mu + 1.0) / mu * c2 {
                0.0
            } else {
                ((c2 * mu * (mu + 1.0) / s).sqrt() - mu).clamp(0.0, 1.0)
            };
        }
        if weights.iter().all(|&w| w == 0.0 || w == 1.0) && rounds > 1 {
            break;
        }
        weigh(graph, candidates, &weights, &original);
        let solved = optimise(graph, &config.round());
        restore(graph, &original);
        solved?;
        mu *= config.mu_factor;
    }
    let rejected: Vec<usize> = (candidates.iter().zip(&weights))
        .filter(|(_, &w)| w < 0.5)
        .map(|(&k, _)| k)
        .collect();
    // The inliers' own least squares, to convergence.
    let kept: Vec<f64> = weights.iter().map(|&w| if w < 0.5 { 0.0 } else { 1.0 }).collect();
    weigh(graph, candidates, &kept, &original);
    let summary = optimise(graph, &config.solve);
    restore(graph, &original);
    Ok(Rejection {
        rejected,
        inconsistent: Vec::new(),
        rounds,
        summary: summary?,
    })
}

impl OutlierConfig {
    /// A round's solve.
    fn round(&self) -> OptimiseConfig {
        OptimiseConfig {
            max_iterations: self.round_iterations.min(self.solve.max_iterations),
            ..self.solve.clone()
        }
    }
}

/// The smallest weight an edge is given: an edge left out keeps a trace
/// of its information so that every information matrix stays positive
/// definite (a solve's check), too small to move any pose.
const LEFT_OUT: f64 = 1e-12;

/// Scales each candidate edge's information by its weight.
fn weigh(graph: &mut PoseGraph, candidates: &[usize], weights: &[f64], original: &[[[f64; 3]; 3]]) {
    for (&k, &w) in candidates.iter().zip(weights) {
        let w = w.max(LEFT_OUT);
        graph.edges[k].information = original[k].map(|row| row.map(|v| v * w));
    }
}

/// Puts every edge's information back.
fn restore(graph: &mut PoseGraph, original: &[[[f64; 3]; 3]]) {
    for (e, o) in graph.edges.iter_mut().zip(original) {
        e.information = *o;
    }
}

/// Solves the graph; where a candidate then lies above the threshold,
/// [`reject_outliers`] with the candidates the pairwise check finds
/// inconsistent (made once into `checked`) left out, then those of them
/// that the rest predicts within both uncertainties taken back and
/// rejection run again from there.
fn reject_after_check(
    graph: &mut PoseGraph,
    candidates: &[usize],
    checked: &mut Option<Vec<usize>>,
    config: &OutlierConfig,
) -> Result<Rejection, GraphError> {
    let Some(pairwise_chi2) = config.pairwise_chi2 else {
        return reject_outliers(graph, candidates, config);
    };
    graph.check()?;
    let start = graph.poses.clone();
    let summary = optimise(graph, &config.solve)?;
    let above = |g: &PoseGraph, k: usize| {
        let e = &g.edges[k];
        e.chi2(&g.poses[e.from], &g.poses[e.to]) > config.threshold_chi2
    };
    if !candidates.iter().any(|&k| above(graph, k)) {
        return Ok(Rejection {
            rejected: Vec::new(),
            inconsistent: Vec::new(),
            rounds: 0,
            summary,
        });
    }
    graph.poses = start;
    if checked.is_none() {
        *checked =
            Some(consistent_loops(graph, candidates, pairwise_chi2)?.map_or_else(Vec::new, |c| c.dropped));
    }
    let inconsistent: &[usize] = checked.as_deref().unwrap_or_default();
    if inconsistent.is_empty() {
        return reject_outliers(graph, candidates, config);
    }
    let original: Vec<[[f64; 3]; 3]> = graph.edges.iter().map(|e| e.information).collect();
    let left_out = |graph: &mut PoseGraph, out: &[usize]| {
        weigh(graph, out, &vec![0.0; out.len()], &original);
    };
    let rest: Vec<usize> = (candidates.iter().copied())
        .filter(|k| !inconsistent.contains(k))
        .collect();
    left_out(graph, inconsistent);
    let first = reject_outliers(graph, &rest, config);
    restore(graph, &original);
    let first = first?;
    // Those whose measurement the solution without them predicts within
    // both uncertainties come back (a true loop closure the first-order
    // pairwise test failed).
    left_out(graph, &first.rejected);
    let innovation = innovation_chi2(graph, inconsistent);
    restore(graph, &original);
    let innovation = innovation?;
    let fits = |c: usize| innovation[c] <= config.threshold_chi2;
    let back: Vec<usize> = (0..inconsistent.len())
        .filter(|&c| fits(c))
        .map(|c| inconsistent[c])
        .collect();
    let out: Vec<usize> = (0..inconsistent.len())
        .filter(|&c| !fits(c))
        .map(|c| inconsistent[c])
        .collect();
    let last = if back.is_empty() {
        first
    } else {
        let mut again: Vec<usize> = rest.iter().chain(&back).copied().collect();
        again.sort_unstable();
        left_out(graph, &out);
        let second = reject_outliers(graph, &again, config);
        restore(graph, &original);
        let second = second?;
        Rejection {
            rounds: first.rounds + second.rounds,
            ..second
        }
    };
    let mut rejected: Vec<usize> = last.rejected.iter().chain(&out).copied().collect();
    rejected.sort_unstable();
    Ok(Rejection {
        rejected,
        inconsistent: out,
        ..last
    })
}

/// The graph as it came, the candidates `rejection` left out weighed out,
/// started from the chordal relaxation and solved; then those of them
/// that fit taken back and solved again. `None` where a solve fails.
fn chordal_of_kept(
    graph: &PoseGraph,
    candidates: &[usize],
    rejection: &Rejection,
    config: &OutlierConfig,
) -> Option<(PoseGraph, Tried, Rejection)> {
    let mut h = graph.clone();
    let original: Vec<[[f64; 3]; 3]> = h.edges.iter().map(|e| e.information).collect();
    let out = &rejection.rejected;
    weigh(&mut h, out, &vec![0.0; out.len()], &original);
    crate::init::chordal(&mut h).ok()?;
    let chi2_start = h.chi2();
    let mut summary = optimise(&mut h, &config.solve).ok()?;
    restore(&mut h, &original);
    let fits = |h: &PoseGraph, k: usize| {
        let e = &h.edges[k];
        e.chi2(&h.poses[e.from], &h.poses[e.to]) <= config.threshold_chi2
    };
    let still: Vec<usize> = out.iter().copied().filter(|&k| !fits(&h, k)).collect();
    if still.len() < out.len() {
        weigh(&mut h, &still, &vec![0.0; still.len()], &original);
        summary = optimise(&mut h, &config.solve).ok()?;
        restore(&mut h, &original);
    }
    let inconsistent = (rejection.inconsistent.iter().copied())
        .filter(|k| still.contains(k))
        .collect();
    let this = Tried {
        start: Start::ChordalOfKept,
        chi2_start,
        cost: truncated_cost(&h, candidates, config.threshold_chi2),
    };
    let r = Rejection {
        rejected: still,
        inconsistent,
        rounds: rejection.rounds,
        summary,
    };
    Some((h, this, r))
}

/// Where a solve starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// The graph's poses as they are (a file's vertices).
    Given,
    /// Odometry chaining ([`crate::init::chain`]).
    Chain,
    /// The chordal relaxation ([`crate::init::chordal`]).
    Chordal,
    /// The chordal relaxation of the edges a rejection kept: with the
    /// wrong loop closures out, the relaxation the outliers had misled
    /// holds again ([`solve_from_starts`] tries it after the others).
    ChordalOfKept,
}

impl Start {
    /// The start's name, as the command line spells it.
    pub fn name(self) -> &'static str {
        match self {
            Start::Given => "file",
            Start::Chain => "chain",
            Start::Chordal => "chordal",
            Start::ChordalOfKept => "chordal-of-kept",
        }
    }
}

/// A start [`solve_from_starts`] tried.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tried {
    /// Where it started.
    pub start: Start,
    /// χ² of the poses it started from.
    pub chi2_start: f64,
    /// Its solution's truncated cost (see [`truncated_cost`]; the robust
    /// cost where rejection is off).
    pub cost: f64,
}

/// What [`solve_from_starts`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct Solved {
    /// The start whose solution was kept.
    pub start: Start,
    /// χ² of the poses it started from.
    pub chi2_start: f64,
    /// Every start tried that could be solved, in order.
    pub tried: Vec<Tried>,
    /// The kept solution's rejection (none rejected where rejection is off).
    pub rejection: Rejection,
}

/// The truncated least-squares cost of the graph's poses: every edge's
/// `eᵀ Ω e`, a `candidates` edge's at most `threshold_chi2`. Where no
/// candidate lies above the threshold, χ².
pub fn truncated_cost(graph: &PoseGraph, candidates: &[usize], threshold_chi2: f64) -> f64 {
    (graph.edges.iter().enumerate())
        .map(|(k, e)| {
            let s = e.chi2(&graph.poses[e.from], &graph.poses[e.to]);
            if candidates.contains(&k) {
                s.min(threshold_chi2)
            } else {
                s
            }
        })
        .sum()
}

/// Solves `graph` from each of `starts` (each set from the graph as it
/// came), with wrong `candidates` found and left out where `outliers` is
/// given (else every edge kept, its kernel as set); keeps the solution
/// of least truncated cost (the first of equals) in `graph`.
///
/// # Errors
/// No start given; as [`reject_outliers`] or [`optimise`] for every start
/// (a start that fails is passed over while another succeeds).
pub fn solve_from_starts(
    graph: &mut PoseGraph,
    starts: &[Start],
    candidates: &[usize],
    outliers: Option<&OutlierConfig>,
    solve: &OptimiseConfig,
) -> Result<Solved, GraphError> {
    let threshold = outliers.map_or(f64::INFINITY, |o| o.threshold_chi2);
    // The pairwise check needs no start: made once, where a start's
    // solution first holds a candidate above the threshold.
    let mut inconsistent: Option<Vec<usize>> = None;
    let mut best: Option<(PoseGraph, Tried, Rejection)> = None;
    let mut tried = Vec::new();
    let mut failure = None;
    for &start in starts {
        let mut g = graph.clone();
        let mut chi2_start = f64::NAN;
        let solved = match start {
            Start::Given => Ok(()),
            Start::Chain => crate::init::chain(&mut g),
            Start::Chordal | Start::ChordalOfKept => crate::init::chordal(&mut g),
        }
        .and_then(|()| {
            chi2_start = g.chi2();
            match outliers {
                Some(config) => reject_after_check(&mut g, candidates, &mut inconsistent, config),
                None => optimise(&mut g, solve).map(|summary| Rejection {
                    rejected: Vec::new(),
                    inconsistent: Vec::new(),
                    rounds: 0,
                    summary,
                }),
            }
        });
        let rejection = match solved {
            Ok(r) => r,
            Err(e) => {
                failure.get_or_insert(e);
                continue;
            }
        };
        let cost = match outliers {
            Some(_) => truncated_cost(&g, candidates, threshold),
            None => rejection.summary.cost_final,
        };
        let this = Tried {
            start,
            chi2_start,
            cost,
        };
        tried.push(this);
        if best.as_ref().is_none_or(|b| cost < b.1.cost) {
            best = Some((g, this, rejection));
        }
    }
    let Some((mut g, mut kept, mut rejection)) = best else {
        return Err(failure.unwrap_or(GraphError::NoStart));
    };
    // With the wrong loop closures found, the chordal relaxation of the
    // rest from the graph as it came; those left out that fit its solution
    // come back. Kept where its truncated cost is lower.
    if let (Some(config), false) = (outliers, rejection.rejected.is_empty()) {
        if starts.contains(&Start::Chordal) {
            if let Some((h, this, r)) = chordal_of_kept(graph, candidates, &rejection, config) {
                tried.push(this);
                if this.cost < kept.cost {
                    (g, kept, rejection) = (h, this, r);
                }
            }
        }
    }
    *graph = g;
    Ok(Solved {
        start: kept.start,
        chi2_start: kept.chi2_start,
        tried,
        rejection,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::grid_world;

    /// A grid world's graph with `share` more loop edges, each measuring a
    /// relative pose drawn at random (metres apart, any heading): the
    /// graph, chained from its odometry, and the wrong edges' indices.
    fn with_outliers(share: f64, seed: u64) -> (PoseGraph, Vec<usize>) {
        let (mut graph, _) = grid_world(300, 0.02, 0.01, seed);
        crate::init::chain(&mut graph).unwrap();
        let loops = graph.edges.iter().filter(|e| e.to != e.from + 1).count();
        let count = ((loops as f64 * share).ceil() as usize).max(1);
        let wrong = crate::synthetic::add_wrong_loops(&mut graph, count, seed + 100);
        (graph, wrong)
    }

    fn loops_of(graph: &PoseGraph) -> Vec<usize> {
        (graph.edges.iter().enumerate())
            .filter(|(_, e)| e.to != e.from + 1)
            .map(|(k, _)| k)
            .collect()
    }

    #[test]
    fn a_tenth_of_wrong_loop_closures_are_all_found_and_the_poses_are_the_inliers() {
        for seed in [1, 2, 3] {
            let (mut graph, wrong) = with_outliers(0.1, seed);
            let candidates = loops_of(&graph);
            let r = reject_outliers(&mut graph, &candidates, &OutlierConfig::default()).unwrap();
            assert_eq!(r.rejected, wrong, "seed {seed}");
            assert!(r.rounds > 0 && r.summary.converged, "seed {seed}: {r:?}");
            // The same poses as the graph without them solved alone.
            // The graph without them solved alone: the same χ² (to the
            // solver's convergence) and poses within its spread.
            let (mut clean, _) = with_outliers(0.1, seed);
            clean.edges.truncate(wrong[0]);
            let alone = optimise(&mut clean, &OptimiseConfig::default()).unwrap();
            let (a, b) = (r.summary.chi2_final, alone.chi2_final);
            assert!((a - b).abs() <= 1e-5 * b, "seed {seed}: χ² {a} against {b}");
            for (a, b) in graph.poses.iter().zip(&clean.poses) {
                let d = a.between(b);
                assert!(
                    d.translation().norm() < 0.01 && d.theta.abs() < 1e-3,
                    "seed {seed}: {d:?}"
                );
            }
        }
    }

    /// With the pairwise check first, the wrong loop closures never reach
    /// a solve, the few true ones the check drops come back, and the
    /// answer is the same as graduated non-convexity's alone.
    #[test]
    fn the_pairwise_check_leaves_the_wrong_loops_out_before_any_solve() {
        for seed in [1, 2, 3] {
            let (mut graph, wrong) = with_outliers(0.1, seed);
            let candidates = loops_of(&graph);
            let config = OutlierConfig::default();
            assert!(config.pairwise_chi2.is_some());
            let solved = solve_from_starts(
                &mut graph,
                &[Start::Given],
                &candidates,
                Some(&config),
                &OptimiseConfig::default(),
            )
            .unwrap();
            let r = &solved.rejection;
            assert_eq!(r.rejected, wrong, "seed {seed}");
            assert_eq!(r.inconsistent, wrong, "seed {seed}: all caught before a solve");
            assert!(r.summary.converged);
        }
    }

    #[test]
    fn a_graph_without_outliers_is_solved_once_and_keeps_every_edge() {
        let (mut graph, _) = grid_world(300, 0.02, 0.01, 4);
        crate::init::chain(&mut graph).unwrap();
        let mut plain = graph.clone();
        let candidates = loops_of(&graph);
        let r = reject_outliers(&mut graph, &candidates, &OutlierConfig::default()).unwrap();
        assert!(r.rejected.is_empty() && r.rounds == 0, "{r:?}");
        optimise(&mut plain, &OptimiseConfig::default()).unwrap();
        assert_eq!(graph.poses, plain.poses);
        assert_eq!(graph.edges, plain.edges);
    }

    #[test]
    fn a_candidate_beyond_the_edges_is_refused() {
        let (mut graph, _) = grid_world(10, 0.02, 0.01, 5);
        let k = graph.edges.len();
        let err = reject_outliers(&mut graph, &[k], &OutlierConfig::default()).unwrap_err();
        assert!(
            matches!(err, GraphError::BadEdge { edge, .. } if edge == k),
            "{err:?}"
        );
    }
}
