//! Gauss-Newton and Levenberg-Marquardt on the graph's sparse normal
//! equations.

use crate::sparse::{BlockAt, BlockSystem};
use crate::{quadratic, GraphError, PoseGraph};
use faer::Mat;
use pirouette_geom::Pose2;

/// The iteration of [`optimise`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Solver {
    /// Gauss-Newton: the full step each time.
    GaussNewton,
    /// Levenberg-Marquardt: a damped step, kept only where it lowers the
    /// cost; the damping falls tenfold after a kept step and rises tenfold
    /// after a rejected one.
    #[default]
    LevenbergMarquardt,
}

/// Settings of [`optimise`].
#[derive(Debug, Clone, PartialEq)]
pub struct OptimiseConfig {
    /// The iteration.
    pub solver: Solver,
    /// At most this many linearise-and-solve steps.
    pub max_iterations: usize,
    /// Stop when a step lowers the cost by less than this share of it.
    pub relative_decrease: f64,
    /// Stop when the cost falls below this.
    pub absolute_cost: f64,
}

impl Default for OptimiseConfig {
    /// Levenberg-Marquardt, at most 100 steps, stopping below a relative
    /// decrease of 10⁻⁶ (tighter than GTSAM's default 10⁻⁵, so the final
    /// cost is at least as converged) or a cost of 10⁻¹².
    fn default() -> Self {
        Self {
            solver: Solver::LevenbergMarquardt,
            max_iterations: 100,
            relative_decrease: 1e-6,
            absolute_cost: 1e-12,
        }
    }
}

/// What [`optimise`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// χ² (sum of `eᵀ Ω e`) before.
    pub chi2_initial: f64,
    /// χ² after.
    pub chi2_final: f64,
    /// The robust cost after, in the graph's residual (χ² where every
    /// kernel is squared and the residual is g2o's).
    pub cost_final: f64,
    /// Linearise-and-solve steps taken (a rejected damped step counts).
    pub iterations: usize,
    /// Whether it stopped on the decrease or cost test, not the cap.
    pub converged: bool,
}

/// Where an edge's blocks `(from, from)`, `(to, to)`, `(from, to)` live,
/// with the block each was asked for as; `None` where a pose is held.
type EdgeBlocks = [Option<(BlockAt, (usize, usize))>; 3];

/// The linear system of one linearisation: the pattern (made once), each
/// edge's block positions, and the gradient.
struct Normal {
    system: BlockSystem<3>,
    /// Per edge: the blocks `(from, from)`, `(to, to)`, `(from, to)`, each
    /// `None` where a pose is held.
    blocks: Vec<EdgeBlocks>,
    /// Unknown index of each pose (`None` for the held one).
    unknown: Vec<Option<usize>>,
    gradient: Vec<f64>,
}

impl Normal {
    fn new(graph: &PoseGraph) -> Result<Self, GraphError> {
        let unknown: Vec<Option<usize>> = (0..graph.poses.len())
            .map(|p| match p.cmp(&graph.held) {
                std::cmp::Ordering::Less => Some(p),
                std::cmp::Ordering::Equal => None,
                std::cmp::Ordering::Greater => Some(p - 1),
            })
            .collect();
        let n = graph.poses.len().saturating_sub(1);
        let pairs = graph
            .edges
            .iter()
            .filter_map(|e| Some((unknown[e.from]?, unknown[e.to]?)));
        let system = BlockSystem::<3>::new(n, pairs)?;
        let blocks = graph
            .edges
            .iter()
            .map(|e| {
                let (a, b) = (unknown[e.from], unknown[e.to]);
                let block = |r: Option<usize>, c: Option<usize>| -> Option<(BlockAt, (usize, usize))> {
                    let (r, c) = (r?, c?);
                    Some((system.at(r, c)?, (r, c)))
                };
                [block(a, a), block(b, b), block(a, b)]
            })
            .collect();
        Ok(Self {
            gradient: vec![0.0; system.dim()],
            system,
            blocks,
            unknown,
        })
    }

    /// Fills `H = Σ w JᵀΩJ` and `b = Σ w JᵀΩe` at `poses`, each edge
    /// weighted by its kernel.
    fn linearise(&mut self, graph: &PoseGraph, poses: &[Pose2]) {
        self.system.clear();
        self.gradient.iter_mut().for_each(|g| *g = 0.0);
        for (e, blocks) in graph.edges.iter().zip(&self.blocks) {
            let (r, ji, jj) = e.linearise_in(graph.residual, &poses[e.from], &poses[e.to]);
            let (_, w) = e.kernel.cost_and_weight(quadratic(&e.information, &r));
            let omega = e.information.map(|row| row.map(|v| v * w));
            // ΩJ for both sides, then the blocks JᵀΩJ and JᵀΩe.
            let times = |j: &[[f64; 3]; 3]| {
                let mut out = [[0.0; 3]; 3];
                for a in 0..3 {
                    for k in 0..3 {
                        out[a][k] = (0..3).map(|m| omega[a][m] * j[m][k]).sum();
                    }
                }
                out
            };
            let (oi, oj) = (times(&ji), times(&jj));
            let jt_o = |j: &[[f64; 3]; 3], o: &[[f64; 3]; 3]| {
                let mut out = [[0.0; 3]; 3];
                for a in 0..3 {
                    for k in 0..3 {
                        out[a][k] = (0..3).map(|m| j[m][a] * o[m][k]).sum();
                    }
                }
                out
            };
            let parts = [jt_o(&ji, &oi), jt_o(&jj, &oj), jt_o(&ji, &oj)];
            for (block, part) in blocks.iter().zip(&parts) {
                if let Some((at, asked)) = block {
                    self.system.add(*at, *asked, part);
                }
            }
            for (pose, o) in [(e.from, &oi), (e.to, &oj)] {
                if let Some(u) = self.unknown[pose] {
                    for k in 0..3 {
                        self.gradient[3 * u + k] += (0..3).map(|m| o[m][k] * r[m]).sum::<f64>();
                    }
                }
            }
        }
    }

    /// `poses` moved by the step `delta` (the held pose stays).
    fn step(&self, poses: &[Pose2], delta: &Mat<f64>) -> Vec<Pose2> {
        poses
            .iter()
            .zip(&self.unknown)
            .map(|(p, u)| match u {
                None => *p,
                Some(u) => Pose2::new(
                    p.x + delta[(3 * u, 0)],
                    p.y + delta[(3 * u + 1, 0)],
                    p.theta + delta[(3 * u + 2, 0)],
                ),
            })
            .collect()
    }
}

/// Levenberg-Marquardt's first damping, as a share of the normal matrix's
/// mean diagonal.
const LAMBDA_INITIAL: f64 = 1e-5;

/// How damping grows on a rejected step and shrinks on an accepted one.
const LAMBDA_FACTOR: f64 = 10.0;

/// The damping (relative to the mean diagonal) beyond which steps are too
/// small to matter: the iteration stops there.
const LAMBDA_MAX: f64 = 1e10;

/// The robust cost of `graph`'s edges at `poses`.
fn cost_at(graph: &PoseGraph, poses: &[Pose2]) -> f64 {
    graph
        .edges
        .iter()
        .map(|e| {
            e.kernel
                .cost_and_weight(e.cost_in(graph.residual, &poses[e.from], &poses[e.to]))
                .0
        })
        .sum()
}

/// Moves `graph`'s poses (all but the held one) to where the robust cost
/// is least, from where they are. The sparsity pattern and its symbolic
/// Cholesky factorisation are made once; each step refills the values.
///
/// # Errors
/// A graph that fails [`PoseGraph::check`], or a system that is not
/// positive definite (a pose tied to the held one by no chain of edges).
pub fn optimise(graph: &mut PoseGraph, config: &OptimiseConfig) -> Result<Summary, GraphError> {
    graph.check()?;
    let chi2_initial = graph.chi2();
    let mut normal = Normal::new(graph)?;
    let mut poses = graph.poses.clone();
    let mut cost = cost_at(graph, &poses);
    // Levenberg-Marquardt's damping and its ceiling, set at the first
    // linearisation from the normal matrix's mean diagonal.
    let mut lambda: Option<f64> = None;
    let mut lambda_max = f64::INFINITY;
    let mut iterations = 0;
    let mut converged = cost <= config.absolute_cost;
    let n = normal.system.dim();
    let small = |before: f64, after: f64| {
        (before - after).abs() <= config.relative_decrease * before || after <= config.absolute_cost
    };
    while !converged && iterations < config.max_iterations && n > 0 {
        iterations += 1;
        normal.linearise(graph, &poses);
        if config.solver == Solver::LevenbergMarquardt && lambda.is_none() {
            let diagonal = normal.system.diagonal();
            let mean = diagonal.iter().sum::<f64>() / diagonal.len() as f64;
            lambda = Some(LAMBDA_INITIAL * mean);
            lambda_max = LAMBDA_MAX * mean.max(f64::MIN_POSITIVE);
        }
        // A damped step that raises the cost is tried again from the same
        // linearisation with ten times the damping (each try counts as an
        // iteration); an accepted one divides the damping by ten.
        loop {
            let lam = lambda.unwrap_or(0.0);
            normal.system.add_to_diagonal(lam);
            let factor = normal.system.factor();
            normal.system.add_to_diagonal(-lam);
            let mut delta = Mat::from_fn(n, 1, |i, _| -normal.gradient[i]);
            factor?.solve(&mut delta);
            let candidate = normal.step(&poses, &delta);
            let new_cost = cost_at(graph, &candidate);
            if config.solver == Solver::GaussNewton || new_cost < cost {
                converged = small(cost, new_cost);
                poses = candidate;
                cost = new_cost;
                lambda = lambda.map(|l| (l / LAMBDA_FACTOR).max(f64::MIN_POSITIVE));
                break;
            }
            let more = lam * LAMBDA_FACTOR;
            // Damped until the step is negligible and still no better: a
            // minimum, to rounding.
            if more.is_nan() || more >= lambda_max || iterations >= config.max_iterations {
                converged = small(cost, new_cost);
                break;
            }
            lambda = Some(more);
            iterations += 1;
        }
        if lambda.is_some_and(|l| l * LAMBDA_FACTOR >= lambda_max) {
            break;
        }
    }
    graph.poses = poses;
    Ok(Summary {
        chi2_initial,
        chi2_final: graph.chi2(),
        cost_final: cost,
        iterations,
        converged,
    })
}

/// A graph's normal equations made ready for repeated steps: the sparsity
/// pattern and its symbolic Cholesky factorisation, made once for the
/// graph's edges (what [`optimise`] does before its first step).
pub struct GaussNewton {
    normal: Normal,
}

impl GaussNewton {
    /// The pattern and symbolic factorisation of `graph`'s edges.
    pub fn new(graph: &PoseGraph) -> Result<Self, GraphError> {
        graph.check()?;
        Ok(Self {
            normal: Normal::new(graph)?,
        })
    }

    /// One Gauss-Newton step on `graph` (whose edges must be those this
    /// was made for): linearise, factor, solve, move. Returns the robust
    /// cost after the step.
    pub fn step(&mut self, graph: &mut PoseGraph) -> Result<f64, GraphError> {
        let n = self.normal.system.dim();
        self.normal.linearise(graph, &graph.poses);
        let mut delta = Mat::from_fn(n, 1, |i, _| -self.normal.gradient[i]);
        self.normal.system.factor()?.solve(&mut delta);
        graph.poses = self.normal.step(&graph.poses, &delta);
        Ok(graph.robust_cost())
    }
}

/// The 3 × 3 covariance of each pose in `which` (`(x, y, θ)`, world frame)
/// at the graph's current poses: blocks of the inverse of the normal
/// equations' matrix (kernels' weights included) with the held pose fixed
/// (its own covariance is zero).
pub fn marginal_covariances(graph: &PoseGraph, which: &[usize]) -> Result<Vec<[[f64; 3]; 3]>, GraphError> {
    graph.check()?;
    let mut normal = Normal::new(graph)?;
    normal.linearise(graph, &graph.poses);
    let factor = normal.system.factor()?;
    let n = normal.system.dim();
    which
        .iter()
        .map(|&p| {
            if p >= graph.poses.len() {
                return Err(GraphError::BadHeld {
                    held: p,
                    poses: graph.poses.len(),
                });
            }
            let Some(u) = normal.unknown[p] else {
                return Ok([[0.0; 3]; 3]);
            };
            let mut cols = Mat::from_fn(n, 3, |i, k| f64::from(u8::from(i == 3 * u + k)));
            factor.solve(&mut cols);
            let mut out = [[0.0; 3]; 3];
            for a in 0..3 {
                for k in 0..3 {
                    out[a][k] = cols[(3 * u + a, k)];
                }
            }
            Ok(out)
        })
        .collect()
}

/// For each edge in `which`, its innovation χ²: how far its measurement
/// lies from what the rest of the graph predicts at the current poses,
/// under both uncertainties, `eᵀ (Ω⁻¹ + J C Jᵀ)⁻¹ e` (`C` the joint
/// covariance of its two poses from the normal equations, `J` the
/// residual's Jacobian), the edges asked about left out of the prediction.
/// An edge the rest can barely pin scores less than its `eᵀ Ω e`.
///
/// # Errors
/// As [`marginal_covariances`]; an edge beyond the graph's.
pub fn innovation_chi2(graph: &PoseGraph, which: &[usize]) -> Result<Vec<f64>, GraphError> {
    graph.check()?;
    graph.check_edge_indices(which, "asked about")?;
    // The rest: the edges asked about kept with a trace of their weight
    // (the system stays positive definite, and they move nothing).
    let mut rest = graph.clone();
    for &k in which {
        rest.edges[k].information = graph.edges[k].information.map(|row| row.map(|v| v * 1e-12));
    }
    let mut normal = Normal::new(&rest)?;
    normal.linearise(&rest, &rest.poses);
    let factor = normal.system.factor()?;
    let n = normal.system.dim();
    let mut out = Vec::with_capacity(which.len());
    // The inverse's columns for both ends of a batch of edges at once (one
    // solve of many right-hand sides is far cheaper than many of six).
    for batch in which.chunks(INNOVATION_BATCH) {
        let ends: Vec<[Option<usize>; 2]> = (batch.iter())
            .map(|&k| {
                [
                    normal.unknown[graph.edges[k].from],
                    normal.unknown[graph.edges[k].to],
                ]
            })
            .collect();
        let mut cols = Mat::from_fn(n, 6 * batch.len(), |i, c| match ends[c / 6][c % 6 / 3] {
            Some(u) => f64::from(u8::from(i == 3 * u + c % 3)),
            None => 0.0,
        });
        factor.solve(&mut cols);
        for (b, &k) in batch.iter().enumerate() {
            let edge = &graph.edges[k];
            let (e, ji, jj) = edge.linearise(&graph.poses[edge.from], &graph.poses[edge.to]);
            let j = nalgebra::Matrix3x6::from_fn(|r, c| if c < 3 { ji[r][c] } else { jj[r][c - 3] });
            let c = nalgebra::Matrix6::from_fn(|r, q| match (ends[b][r / 3], ends[b][q / 3]) {
                (Some(u), Some(_)) => cols[(3 * u + r % 3, 6 * b + q)],
                _ => 0.0,
            });
            let s = graph.edge_covariance(k)? + j * c * j.transpose();
            let e = nalgebra::Vector3::from(e);
            out.push(
                s.try_inverse()
                    .map_or(f64::INFINITY, |i| (e.transpose() * i * e)[(0, 0)]),
            );
        }
    }
    Ok(out)
}

/// Edges whose innovations are solved for at once: 96 right-hand sides,
/// 768 bytes per pose of the graph.
const INNOVATION_BATCH: usize = 16;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{init, Edge, Kernel};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Two measurements of one step: at the poses the first alone gives,
    /// the second's innovation is their difference under both variances;
    /// at the poses the second gives, the first's is the same; asked
    /// together, neither has a rest to be predicted by.
    #[test]
    fn an_innovation_weighs_both_uncertainties() {
        let z = Pose2::new(1.0, 0.5, 0.3);
        let mut graph = PoseGraph::new(vec![Pose2::IDENTITY, z]);
        let (s1, s2) = (0.02f64, 0.05f64);
        let info = |s: f64| {
            [
                [1.0 / (s * s), 0.0, 0.0],
                [0.0, 1.0 / (s * s), 0.0],
                [0.0, 0.0, 1.0 / (s * s)],
            ]
        };
        graph.edges.push(Edge::new(0, 1, z, info(s1)));
        graph
            .edges
            .push(Edge::new(0, 1, z * Pose2::new(0.1, 0.0, 0.0), info(s2)));
        let want = 0.01 / (s1 * s1 + s2 * s2);
        let second = innovation_chi2(&graph, &[1]).unwrap()[0];
        assert!((second - want).abs() < 1e-9 * want, "{second} against {want}");
        graph.poses[1] = graph.edges[1].measurement;
        let first = innovation_chi2(&graph, &[0]).unwrap()[0];
        assert!((first - want).abs() < 1e-9 * want, "{first} against {want}");
        let both = innovation_chi2(&graph, &[0, 1]).unwrap();
        assert!(both.iter().all(|&c| c < 1e-6), "{both:?}");
        assert!(matches!(
            innovation_chi2(&graph, &[2]),
            Err(GraphError::BadEdge { edge: 2, .. })
        ));
    }
    use rand_distr::{Distribution, Normal as Gauss};

    const INFO: [[f64; 3]; 3] = [[100.0, 0.0, 0.0], [0.0, 100.0, 0.0], [0.0, 0.0, 1000.0]];

    /// A grid-world walk of `n` poses with noisy odometry and loop edges
    /// between poses that revisit a place, and its true poses.
    fn grid_world(n: usize, seed: u64) -> (PoseGraph, Vec<Pose2>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut truth = vec![Pose2::IDENTITY];
        for _ in 1..n {
            let turn =
                [0.0, std::f64::consts::FRAC_PI_2, -std::f64::consts::FRAC_PI_2][rng.random_range(0..3)];
            let last = *truth.last().unwrap();
            truth.push(last * Pose2::new(1.0, 0.0, turn));
        }
        let noise_t = Gauss::new(0.0, 0.1).unwrap();
        let noise_r = Gauss::new(0.0, 0.03).unwrap();
        let noisy = |z: Pose2, rng: &mut ChaCha8Rng| {
            Pose2::new(
                z.x + noise_t.sample(rng),
                z.y + noise_t.sample(rng),
                z.theta + noise_r.sample(rng),
            )
        };
        let mut graph = PoseGraph::new(vec![Pose2::IDENTITY; n]);
        for i in 0..n - 1 {
            let z = noisy(truth[i].between(&truth[i + 1]), &mut rng);
            graph.edges.push(Edge::new(i, i + 1, z, INFO));
        }
        for j in 0..n {
            for i in 0..j.saturating_sub(2) {
                let d = truth[i].between(&truth[j]);
                if d.x.hypot(d.y) < 0.5 {
                    graph.edges.push(Edge::new(i, j, noisy(d, &mut rng), INFO));
                }
            }
        }
        (graph, truth)
    }

    #[test]
    fn gauss_newton_and_levenberg_marquardt_reach_the_same_minimum() {
        let (mut graph, _) = grid_world(300, 2);
        assert!(
            graph.edges.len() > 320,
            "{} edges: too few loops",
            graph.edges.len()
        );
        init::chain(&mut graph).unwrap();
        let mut gn = graph.clone();
        let lm_summary = optimise(&mut graph, &OptimiseConfig::default()).unwrap();
        let gn_summary = optimise(
            &mut gn,
            &OptimiseConfig {
                solver: Solver::GaussNewton,
                ..OptimiseConfig::default()
            },
        )
        .unwrap();
        assert!(lm_summary.converged && gn_summary.converged);
        assert!(lm_summary.chi2_final < 0.1 * lm_summary.chi2_initial);
        let rel = (lm_summary.chi2_final - gn_summary.chi2_final).abs() / gn_summary.chi2_final;
        assert!(rel < 1e-4, "{lm_summary:?} {gn_summary:?}");
        // At the minimum the gradient vanishes: no step lowers χ².
        let before = graph.chi2();
        let mut again = graph.clone();
        optimise(&mut again, &OptimiseConfig::default()).unwrap();
        assert!(again.chi2() >= before * (1.0 - 1e-6));
    }

    #[test]
    fn a_consistent_graph_is_solved_exactly() {
        // Exact measurements of random poses: χ² goes to zero and the
        // poses come back (the first held).
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let truth: Vec<Pose2> = (0..40)
            .map(|k| {
                if k == 0 {
                    Pose2::IDENTITY
                } else {
                    Pose2::new(
                        rng.random_range(-3.0..3.0),
                        rng.random_range(-3.0..3.0),
                        rng.random_range(-3.0..3.0),
                    )
                }
            })
            .collect();
        let mut graph = PoseGraph::new(
            truth
                .iter()
                .map(|t| Pose2::new(t.x + 0.2, t.y - 0.1, t.theta + 0.1))
                .collect(),
        );
        graph.poses[0] = Pose2::IDENTITY;
        for i in 0..40 {
            for j in [(i + 1) % 40, (i + 7) % 40] {
                graph
                    .edges
                    .push(Edge::new(i, j, truth[i].between(&truth[j]), INFO));
            }
        }
        let s = optimise(&mut graph, &OptimiseConfig::default()).unwrap();
        assert!(s.chi2_final < 1e-12, "{s:?}");
        for (p, t) in graph.poses.iter().zip(&truth) {
            assert!((p.x - t.x).abs() < 1e-7 && (p.y - t.y).abs() < 1e-7 && (p.theta - t.theta).abs() < 1e-7);
        }
    }

    #[test]
    fn a_robust_kernel_keeps_a_wrong_loop_closure_from_bending_the_graph() {
        let (mut graph, truth) = grid_world(120, 6);
        // A loop edge that puts pose 100 5 m and a radian off.
        let mut wrong = Edge::new(
            10,
            100,
            truth[10].between(&truth[100]) * Pose2::new(4.0, -3.0, 1.0),
            INFO,
        );
        let mut plain_error = |kernel: Kernel| {
            let mut g = graph.clone();
            wrong.kernel = kernel;
            g.edges.push(wrong);
            init::chain(&mut g).unwrap();
            optimise(&mut g, &OptimiseConfig::default()).unwrap();
            g.poses
                .iter()
                .zip(&truth)
                .map(|(p, t)| (p.x - t.x).hypot(p.y - t.y))
                .fold(0.0, f64::max)
        };
        let squared = plain_error(Kernel::Squared);
        let cauchy = plain_error(Kernel::Cauchy { c: 1.0 });
        init::chain(&mut graph).unwrap();
        optimise(&mut graph, &OptimiseConfig::default()).unwrap();
        let clean = graph
            .poses
            .iter()
            .zip(&truth)
            .map(|(p, t)| (p.x - t.x).hypot(p.y - t.y))
            .fold(0.0, f64::max);
        assert!(
            squared > clean + 0.5,
            "the wrong edge should bend plain least squares: {squared} vs {clean}"
        );
        assert!(
            cauchy < clean + 0.2,
            "Cauchy should shrug it off: {cauchy} vs {clean}"
        );
    }

    /// A chain of poses: each marginal covariance is the sum of the
    /// odometry covariances before it (exact for translation-free turns).
    #[test]
    fn marginal_covariances_add_up_along_a_chain() {
        let n = 6;
        let mut graph = PoseGraph::new((0..n).map(|k| Pose2::new(k as f64, 0.0, 0.0)).collect());
        for i in 0..n - 1 {
            graph.edges.push(Edge::new(
                i,
                i + 1,
                Pose2::new(1.0, 0.0, 0.0),
                [[4.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 100.0]],
            ));
        }
        let cov = marginal_covariances(&graph, &[0, 1, 5]).unwrap();
        assert_eq!(cov[0], [[0.0; 3]; 3]);
        assert!((cov[1][0][0] - 0.25).abs() < 1e-12 && (cov[1][2][2] - 0.01).abs() < 1e-12);
        // x: 5 × 0.25; θ: 5 × 0.01; y grows with the heading's lever arm too.
        assert!((cov[2][0][0] - 1.25).abs() < 1e-9 && (cov[2][2][2] - 0.05).abs() < 1e-9);
        let lever: f64 = (1..=4).map(|k| (k as f64).powi(2) * 0.01).sum();
        assert!((cov[2][1][1] - (1.25 + lever)).abs() < 1e-9, "{}", cov[2][1][1]);
    }
}
