//! Loop closures checked against each other before any solve: pairwise
//! consistency maximisation (Mangelson, Dominic, Eustice and Vasudevan,
//! "Pairwise Consistent Measurement Set Maximization for Robust
//! Multi-robot Map Merging", 2018).
//!
//! Two loop closures `a` (`iₐ → jₐ`) and `b` (`i_b → j_b`) close a cycle
//! with the odometry: `E = x_{iₐ} zₐ x_{jₐ}⁻¹ · x_{j_b} z_b⁻¹ x_{i_b}⁻¹`,
//! the poses `x` dead-reckoned along the odometry chain. Where both are
//! right, `E` is the identity up to the noise of the two measurements and
//! of the odometry between their ends; its squared Mahalanobis length
//! under that noise (first order, every noise moved into the world frame)
//! above a threshold says that at least one of them is wrong. The largest
//! set of loop closures consistent with each other (a maximum clique of
//! the consistency graph, found by a greedy heuristic) is kept; the rest
//! never reach a solve.
//!
//! The noise of the odometry between two poses costs one subtraction: in
//! the world frame, to first order, the dead-reckoning errors of the steps
//! add up, so the covariance of pose `k`'s error is a running sum `Pₖ`
//! and a stretch `s..e` of the chain adds `Pₑ − Pₛ`.

use crate::{log_of, GraphError, PoseGraph};
use nalgebra::{Matrix3, Vector3};
use pirouette_geom::Pose2;
use rayon::prelude::*;

/// What [`consistent_loops`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct Consistency {
    /// The candidates kept: the largest set found whose every pair is
    /// consistent (edge indices, in order).
    pub kept: Vec<usize>,
    /// The other candidates (edge indices, in order).
    pub dropped: Vec<usize>,
}

/// Checks every pair of `candidates` (loop closures: edges the odometry
/// chain can do without) for consistency at `threshold_chi2`, and keeps
/// the largest set found of candidates consistent with each other.
///
/// The odometry is the chain of edges `k → k + 1` (the first of each
/// pair), which must join every pose; `None` where it does not (the
/// consistency of a cycle is then not defined by the chain alone).
///
/// # Errors
/// A candidate that names no edge; an odometry edge whose information does
/// not invert.
///
/// # Memory
/// A bit per pair of candidates, and two 3 × 3 matrices per pose.
pub fn consistent_loops(
    graph: &PoseGraph,
    candidates: &[usize],
    threshold_chi2: f64,
) -> Result<Option<Consistency>, GraphError> {
    LoopCheck::new(threshold_chi2).check(graph, candidates)
}

/// [`consistent_loops`] for a graph that grows: each candidate is checked
/// against every one seen before once, when it is first seen, so that
/// checking a few new loop closures among many costs what the new ones
/// add, not what all of them do.
///
/// A candidate is known by its edge index; its measurement, its
/// information and the odometry chain up to its poses are taken as they
/// were when it was first seen (a graph that only grows keeps them so).
#[derive(Debug, Clone)]
pub struct LoopCheck {
    threshold_chi2: f64,
    /// The edge of each candidate seen, and where it is among them.
    edges: Vec<usize>,
    position: std::collections::HashMap<usize, usize>,
    loops: Vec<Loop>,
    /// Per candidate seen, the candidates seen consistent with it (a bit
    /// set, symmetric).
    adjacent: Vec<Vec<u64>>,
}

impl LoopCheck {
    /// No candidate seen yet; pairs consistent at `threshold_chi2`.
    pub fn new(threshold_chi2: f64) -> Self {
        Self {
            threshold_chi2,
            edges: Vec::new(),
            position: std::collections::HashMap::new(),
            loops: Vec::new(),
            adjacent: Vec::new(),
        }
    }

    /// Candidates seen so far.
    pub fn seen(&self) -> usize {
        self.loops.len()
    }

    /// Forgets every candidate seen but those of `keep` (edge indices),
    /// which keep what was found of their pairs: a check over a window of
    /// the newest candidates holds memory for the window alone.
    pub fn retain(&mut self, keep: &[usize]) {
        let mut held: Vec<usize> = (keep.iter())
            .filter_map(|k| self.position.get(k).copied())
            .collect();
        held.sort_unstable();
        held.dedup();
        let words = held.len().div_ceil(64);
        let adjacent: Vec<Vec<u64>> = (held.iter())
            .map(|&p| {
                let mut row = vec![0u64; words];
                for (v, &q) in held.iter().enumerate() {
                    if self.adjacent[p][q / 64] >> (q % 64) & 1 == 1 {
                        row[v / 64] |= 1 << (v % 64);
                    }
                }
                row
            })
            .collect();
        let loops = held.iter().map(|&p| self.loops[p].clone()).collect();
        let edges: Vec<usize> = held.iter().map(|&p| self.edges[p]).collect();
        self.position = edges.iter().enumerate().map(|(p, &k)| (k, p)).collect();
        self.edges = edges;
        self.loops = loops;
        self.adjacent = adjacent;
    }

    /// The largest set found of `candidates` consistent with each other
    /// (as [`consistent_loops`]); those not seen before are first checked
    /// against every candidate seen. Candidates seen before but not among
    /// `candidates` take no part.
    ///
    /// # Errors
    /// As [`consistent_loops`]; nothing is learnt from a call that fails.
    pub fn check(
        &mut self,
        graph: &PoseGraph,
        candidates: &[usize],
    ) -> Result<Option<Consistency>, GraphError> {
        graph.check_edge_indices(candidates, "a loop closure candidate")?;
        let Some(chain) = Chain::of(graph)? else {
            return Ok(None);
        };
        // Each once, in the order asked (which breaks the clique's ties).
        let mut unique = Vec::with_capacity(candidates.len());
        let mut listed = std::collections::HashSet::new();
        unique.extend(candidates.iter().filter(|&&k| listed.insert(k)));
        let candidates = &unique[..];
        let mut new = Vec::new();
        for &k in candidates {
            if !self.position.contains_key(&k) && !new.contains(&k) {
                new.push(k);
            }
        }
        let fresh: Vec<Loop> = (new.iter())
            .map(|&k| Loop::of(graph, &chain, k))
            .collect::<Result<_, _>>()?;
        let seen = self.loops.len();
        self.loops.extend(fresh);
        let n = self.loops.len();
        // Each new candidate against every one before it.
        let loops = &self.loops;
        let threshold = self.threshold_chi2;
        let rows: Vec<Vec<u64>> = (seen..n)
            .into_par_iter()
            .map(|b| {
                let mut row = vec![0u64; n.div_ceil(64)];
                for a in 0..b {
                    if chain.cycle_chi2(&loops[a], &loops[b]) <= threshold {
                        row[a / 64] |= 1 << (a % 64);
                    }
                }
                row
            })
            .collect();
        for row in &mut self.adjacent {
            row.resize(n.div_ceil(64), 0);
        }
        self.adjacent.extend(rows);
        for b in seen..n {
            for a in 0..b {
                if self.adjacent[b][a / 64] >> (a % 64) & 1 == 1 {
                    self.adjacent[a][b / 64] |= 1 << (b % 64);
                }
            }
        }
        for (p, &k) in (seen..n).zip(&new) {
            self.edges.push(k);
            self.position.insert(k, p);
        }
        // The candidates asked about, as vertices 0..m.
        let asked: Vec<usize> = candidates.iter().map(|k| self.position[k]).collect();
        let m = asked.len();
        let sub: Vec<Vec<u64>> = (asked.iter())
            .map(|&p| {
                let mut row = vec![0u64; m.div_ceil(64)];
                for (v, &q) in asked.iter().enumerate() {
                    if p != q && self.adjacent[p][q / 64] >> (q % 64) & 1 == 1 {
                        row[v / 64] |= 1 << (v % 64);
                    }
                }
                row
            })
            .collect();
        let mut in_clique = vec![false; m];
        for c in largest_clique(&sub, m) {
            in_clique[c] = true;
        }
        let mut kept = Vec::new();
        let mut dropped = Vec::new();
        for (c, &k) in candidates.iter().enumerate() {
            if in_clique[c] {
                kept.push(k);
            } else {
                dropped.push(k);
            }
        }
        Ok(Some(Consistency { kept, dropped }))
    }
}

/// The odometry chain: every pose dead-reckoned from pose 0 and the
/// running covariance of its error in the world frame.
struct Chain {
    poses: Vec<Pose2>,
    /// `Pₖ`: the covariance of pose `k`'s dead-reckoning error (a left,
    /// world-frame perturbation), `P₀ = 0`.
    covariance: Vec<Matrix3<f64>>,
}

impl Chain {
    /// The chain of `graph`'s odometry, `None` where a step is missing.
    fn of(graph: &PoseGraph) -> Result<Option<Chain>, GraphError> {
        let n = graph.poses.len();
        let mut step: Vec<Option<usize>> = vec![None; n.saturating_sub(1)];
        for (k, e) in graph.edges.iter().enumerate() {
            if e.to == e.from + 1 && e.from < step.len() && step[e.from].is_none() {
                step[e.from] = Some(k);
            }
        }
        let mut poses = Vec::with_capacity(n);
        let mut covariance = Vec::with_capacity(n);
        if n > 0 {
            poses.push(Pose2::IDENTITY);
            covariance.push(Matrix3::zeros());
        }
        for (m, s) in step.iter().enumerate() {
            let Some(k) = *s else {
                return Ok(None);
            };
            let e = &graph.edges[k];
            let sigma = graph.edge_covariance(k)?;
            let next = poses[m] * e.measurement;
            // The step's error, taken at its end, in the world frame.
            let ad = next.adjoint();
            covariance.push(covariance[m] + ad * sigma * ad.transpose());
            poses.push(next);
        }
        Ok(Some(Chain { poses, covariance }))
    }

    /// The squared Mahalanobis length of the cycle two loop closures close
    /// with the chain.
    fn cycle_chi2(&self, a: &Loop, b: &Loop) -> f64 {
        let (r, s) = self.cycle(a, b);
        match s.try_inverse() {
            Some(info) => (r.transpose() * info * r)[(0, 0)],
            None => f64::INFINITY,
        }
    }

    /// The cycle two loop closures close with the chain: `Log(E)` and its
    /// covariance to first order about `E = I`.
    fn cycle(&self, a: &Loop, b: &Loop) -> (Vector3<f64>, Matrix3<f64>) {
        let x = &self.poses;
        // E = Dₐ · D_b⁻¹ with D = x_i z x_j⁻¹ (the identity where a loop
        // agrees with dead reckoning).
        let e = a.correction * b.correction.inverse();
        let ad_da = a.correction.adjoint();
        let ad_e = e.adjoint();
        // A step m's world-frame error w moves E by
        // ([m < iₐ] − [m < jₐ]·Ad(Dₐ) + [m < j_b]·Ad(Dₐ) − [m < i_b]·Ad(E))·w:
        // piecewise constant between the four ends.
        let coefficient = |m: usize| {
            let on = |end: usize| if m < end { 1.0 } else { 0.0 };
            Matrix3::identity() * on(a.from) + ad_da * (on(b.to) - on(a.to)) - ad_e * on(b.from)
        };
        let mut ends = [a.from, a.to, b.from, b.to];
        ends.sort_unstable();
        let mut s = Matrix3::zeros();
        let mut start = 0;
        for end in ends {
            if end > start {
                let c = coefficient(start);
                s += c * (self.covariance[end] - self.covariance[start]) * c.transpose();
                start = end;
            }
        }
        // The measurements' own noise: zₐ's error enters at x_{iₐ} zₐ, z_b's
        // (inverted) at Dₐ x_{j_b}.
        let ja = (x[a.from] * a.measurement).adjoint();
        let jb = (a.correction * x[b.to]).adjoint();
        s += ja * a.sigma * ja.transpose() + jb * b.sigma * jb.transpose();
        let (log, _) = log_of([e.x, e.y, e.theta]);
        (Vector3::from(log), s)
    }
}

/// A loop closure as the consistency check uses it.
#[derive(Debug, Clone)]
struct Loop {
    from: usize,
    to: usize,
    measurement: Pose2,
    sigma: Matrix3<f64>,
    /// `D = x_from · z · x_to⁻¹` at the dead-reckoned poses.
    correction: Pose2,
}

impl Loop {
    fn of(graph: &PoseGraph, chain: &Chain, k: usize) -> Result<Loop, GraphError> {
        let e = &graph.edges[k];
        let x = &chain.poses;
        Ok(Loop {
            from: e.from,
            to: e.to,
            measurement: e.measurement,
            sigma: graph.edge_covariance(k)?,
            correction: x[e.from] * e.measurement * x[e.to].inverse(),
        })
    }
}

/// A large clique of the graph whose rows `adjacent` (bit sets over `n`
/// vertices) hold each vertex's neighbours: from each vertex in turn (the
/// best-connected first), neighbours added greedily, the best-connected
/// of those still adjacent to all first (Pattabiraman et al.'s heuristic);
/// vertices that cannot beat the best so far are skipped. Sorted.
fn largest_clique(adjacent: &[Vec<u64>], n: usize) -> Vec<usize> {
    let degree: Vec<usize> = (adjacent.iter())
        .map(|row| row.iter().map(|w| w.count_ones() as usize).sum())
        .collect();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&v| (std::cmp::Reverse(degree[v]), v));
    let mut best: Vec<usize> = Vec::new();
    for &v in &order {
        if degree[v] < best.len() {
            break;
        }
        let mut clique = vec![v];
        let mut open = adjacent[v].clone();
        // The open vertex of highest degree (the first of equals) is the
        // first open one in `order`; open vertices only close, so the
        // search for it goes on from where it last stopped.
        let mut next_in_order = 0;
        loop {
            // A clique that cannot outgrow the best so far is given up.
            let left: usize = open.iter().map(|w| w.count_ones() as usize).sum();
            if clique.len() + left <= best.len() {
                break;
            }
            let is_open = |u: usize| open[u / 64] >> (u % 64) & 1 == 1;
            while next_in_order < n && !is_open(order[next_in_order]) {
                next_in_order += 1;
            }
            let Some(&u) = order.get(next_in_order) else { break };
            clique.push(u);
            for (o, a) in open.iter_mut().zip(&adjacent[u]) {
                *o &= a;
            }
        }
        if clique.len() > best.len() {
            best = clique;
        }
    }
    best.sort_unstable();
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::outliers::CHI2_3_999;
    use crate::synthetic::grid_world;
    use crate::Edge;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The cycle's covariance is its first-order one: for loops that agree
    /// with dead reckoning, what a finite-difference Jacobian of `Log(E)`
    /// over every step's and both loops' noise gives.
    #[test]
    fn the_cycle_covariance_is_the_jacobian_s() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut checked = 0;
        for case in 0..20 {
            let n = 12;
            let mut graph = PoseGraph::new(vec![Pose2::IDENTITY; n]);
            let sigma_of = |rng: &mut ChaCha8Rng| {
                let mut v = [0.0; 3];
                v.iter_mut()
                    .for_each(|v| *v = rng.random_range(0.01f64..0.1).powi(2));
                Matrix3::from_diagonal(&Vector3::from(v))
            };
            let info_of = |s: &Matrix3<f64>| {
                [
                    [1.0 / s[(0, 0)], 0.0, 0.0],
                    [0.0, 1.0 / s[(1, 1)], 0.0],
                    [0.0, 0.0, 1.0 / s[(2, 2)]],
                ]
            };
            let mut sigmas = Vec::new();
            for k in 0..n - 1 {
                let z = Pose2::new(
                    rng.random_range(0.2..1.0),
                    rng.random_range(-0.3..0.3),
                    rng.random_range(-1.0..1.0),
                );
                let s = sigma_of(&mut rng);
                graph.edges.push(Edge::new(k, k + 1, z, info_of(&s)));
                sigmas.push(s);
            }
            // Loops that measure what dead reckoning says: E is the identity.
            let dead = Chain::of(&graph).unwrap().unwrap().poses;
            let mut pick = |rng: &mut ChaCha8Rng| {
                let i = rng.random_range(0..n - 3);
                let j = rng.random_range(i + 2..n);
                let s = sigma_of(rng);
                graph
                    .edges
                    .push(Edge::new(i, j, dead[i].between(&dead[j]), info_of(&s)));
                (graph.edges.len() - 1, s)
            };
            let (ka, sa) = pick(&mut rng);
            let (kb, sb) = pick(&mut rng);
            let cycle = |g: &PoseGraph| {
                let c = Chain::of(g).unwrap().unwrap();
                c.cycle(&Loop::of(g, &c, ka).unwrap(), &Loop::of(g, &c, kb).unwrap())
            };
            let (base, s) = cycle(&graph);
            assert!(base.norm() < 1e-9);
            let h = 1e-7;
            let mut want = Matrix3::zeros();
            let noisy: Vec<(usize, Matrix3<f64>)> = (0..n - 1)
                .map(|k| (k, sigmas[k]))
                .chain([(ka, sa), (kb, sb)])
                .collect();
            for (k, sigma) in noisy {
                let mut j = Matrix3::zeros();
                for d in 0..3 {
                    let mut g = graph.clone();
                    let mut t = [0.0; 3];
                    t[d] = h;
                    g.edges[k].measurement = g.edges[k].measurement * Pose2::new(t[0], t[1], t[2]);
                    j.set_column(d, &((cycle(&g).0 - base) / h));
                }
                want += j * sigma * j.transpose();
            }
            assert!(
                (s - want).norm() <= 1e-5 * want.norm(),
                "case {case}: {s} against {want}"
            );
            checked += 1;
        }
        assert_eq!(checked, 20);
    }

    /// A grid world's true loops are consistent with each other and random
    /// wrong ones are not: every wrong one is dropped, and all but a few
    /// true ones kept (a pair of true loops may fail the first-order
    /// test, and the set kept must pass every pair).
    #[test]
    fn wrong_loop_closures_are_left_out_of_the_largest_consistent_set() {
        for seed in [1, 2] {
            let (mut graph, _) = grid_world(400, 0.02, 0.01, seed);
            let loops: Vec<usize> = (graph.edges.iter().enumerate())
                .filter(|(_, e)| e.to != e.from + 1)
                .map(|(k, _)| k)
                .collect();
            let wrong = crate::synthetic::add_wrong_loops(&mut graph, loops.len() / 10 + 1, seed + 50);
            let candidates: Vec<usize> = loops.iter().chain(&wrong).copied().collect();
            let c = consistent_loops(&graph, &candidates, CHI2_3_999)
                .unwrap()
                .unwrap();
            assert!(wrong.iter().all(|w| c.dropped.contains(w)), "seed {seed}: {c:?}");
            let true_dropped = c.dropped.len() - wrong.len();
            assert!(
                loops.len() > 50 && true_dropped * 10 <= loops.len(),
                "seed {seed}: {true_dropped} of {} true dropped",
                loops.len()
            );
        }
    }

    /// Candidates checked a few at a time as the graph grows give what
    /// one check of them all gives; one seen before but not asked about
    /// takes no part.
    #[test]
    fn a_check_as_the_graph_grows_gives_what_one_check_gives() {
        let (mut graph, _) = grid_world(300, 0.02, 0.01, 4);
        let loops: Vec<usize> = (graph.edges.iter().enumerate())
            .filter(|(_, e)| e.to != e.from + 1)
            .map(|(k, _)| k)
            .collect();
        let wrong = crate::synthetic::add_wrong_loops(&mut graph, loops.len() / 8 + 1, 60);
        let mut all: Vec<usize> = loops.iter().chain(&wrong).copied().collect();
        all.sort_by_key(|&k| (graph.edges[k].from.max(graph.edges[k].to), k));
        let once = consistent_loops(&graph, &all, CHI2_3_999).unwrap().unwrap();
        assert!(!once.dropped.is_empty() && once.kept.len() > 20);
        let mut check = LoopCheck::new(CHI2_3_999);
        for end in (7..all.len()).step_by(7).chain([all.len()]) {
            // Listed twice: one candidate still.
            let mut asked = all[..end].to_vec();
            asked.push(all[0]);
            let grown = check.check(&graph, &asked).unwrap().unwrap();
            let fresh = consistent_loops(&graph, &all[..end], CHI2_3_999)
                .unwrap()
                .unwrap();
            assert_eq!(grown, fresh, "first {end}");
        }
        // Without the first true loop: as if it had never been seen.
        let rest: Vec<usize> = all.iter().copied().filter(|&k| k != once.kept[0]).collect();
        assert_eq!(
            check.check(&graph, &rest).unwrap(),
            consistent_loops(&graph, &rest, CHI2_3_999).unwrap()
        );
        // Forgetting all but the newest half keeps what was found of them.
        let newest = &all[all.len() / 2..];
        check.retain(newest);
        assert_eq!(check.seen(), newest.len());
        assert_eq!(
            check.check(&graph, newest).unwrap(),
            consistent_loops(&graph, newest, CHI2_3_999).unwrap()
        );
        assert_eq!(check.seen(), newest.len());
    }

    #[test]
    fn a_graph_whose_odometry_breaks_is_not_checked() {
        let (mut graph, _) = grid_world(50, 0.02, 0.01, 3);
        let candidates: Vec<usize> = (graph.edges.iter().enumerate())
            .filter(|(_, e)| e.to != e.from + 1)
            .map(|(k, _)| k)
            .collect();
        assert!(consistent_loops(&graph, &candidates, CHI2_3_999)
            .unwrap()
            .is_some());
        graph.edges.retain(|e| !(e.from == 20 && e.to == 21));
        assert_eq!(consistent_loops(&graph, &[], CHI2_3_999).unwrap(), None);
        let k = graph.edges.len();
        assert!(matches!(
            consistent_loops(&graph, &[k], CHI2_3_999),
            Err(GraphError::BadEdge { edge, .. }) if edge == k
        ));
    }

    /// The largest clique of small graphs is found (brute force over every
    /// subset as the oracle).
    #[test]
    fn the_clique_heuristic_finds_small_graphs_largest() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut exact = 0;
        for _ in 0..200 {
            let n = rng.random_range(1..11);
            let mut adjacent = vec![vec![0u64; 1]; n];
            for a in 0..n {
                for b in a + 1..n {
                    if rng.random_bool(0.6) {
                        adjacent[a][0] |= 1 << b;
                        adjacent[b][0] |= 1 << a;
                    }
                }
            }
            let found = largest_clique(&adjacent, n);
            let is_clique = |set: &[usize]| {
                set.iter()
                    .all(|&a| set.iter().all(|&b| a == b || adjacent[a][0] >> b & 1 == 1))
            };
            assert!(is_clique(&found));
            let largest = (0u32..1 << n)
                .filter(|m| is_clique(&(0..n).filter(|v| m >> v & 1 == 1).collect::<Vec<_>>()))
                .map(|m| m.count_ones() as usize)
                .max()
                .unwrap();
            assert!(found.len() <= largest);
            exact += usize::from(found.len() == largest);
        }
        // A heuristic: nearly always the largest on graphs this small.
        assert!(exact >= 190, "{exact} of 200");
    }
}
