//! SE(2) pose graphs and their sparse least-squares optimiser.
//!
//! - [`PoseGraph`]: poses (nodes) joined by [`Edge`]s, each a measured
//!   relative pose with its information matrix and a robust [`Kernel`].
//! - [`optimise`]: Gauss-Newton or Levenberg-Marquardt ([`Solver`]) on a
//!   sparse Cholesky factorisation (faer) whose symbolic analysis is done
//!   once; one pose held to fix the gauge; stops on a small relative
//!   decrease of the cost or an iteration cap ([`OptimiseConfig`]), and
//!   reports a [`Summary`].
//! - [`marginal_covariances`]: the covariance of chosen poses at the
//!   solution.
//! - [`GaussNewton`]: single steps on a graph whose pattern is analysed
//!   once (for benchmarks and callers that drive their own iteration).
//! - [`synthetic::grid_world`]: grid-world graphs of any size.
//! - [`outliers::reject_outliers`]: wrong loop closures found by graduated
//!   non-convexity and left out of the solve.
//! - [`init`]: starting poses from the edges (odometry chaining, or
//!   rotations first by chordal relaxation for graphs that defeat a local
//!   solver started from odometry).
//!
//! The residual of an edge `i → j` measuring `z` is g2o's:
//! `e = (x, y, θ)` of `z⁻¹ · (xᵢ⁻¹ · xⱼ)`, θ wrapped; its cost `eᵀ Ω e`,
//! and the graph's χ² the sum over edges.
//!
//! ```
//! use pirouette_geom::Pose2;
//! use pirouette_graph::{optimise, Edge, OptimiseConfig, PoseGraph};
//! // A square walked with a heading error, closed by a loop edge.
//! let step = Pose2::new(1.0, 0.0, std::f64::consts::FRAC_PI_2);
//! let mut graph = PoseGraph::new(vec![Pose2::IDENTITY; 4]);
//! for i in 0..4 {
//!     graph.edges.push(Edge::new(i, (i + 1) % 4, step, [[100.0, 0.0, 0.0], [0.0, 100.0, 0.0], [0.0, 0.0, 400.0]]));
//! }
//! pirouette_graph::init::chain(&mut graph)?;
//! let summary = optimise(&mut graph, &OptimiseConfig::default())?;
//! assert!(summary.chi2_final < 1e-12);
//! assert!((graph.poses[2].x - 1.0).abs() < 1e-9 && (graph.poses[2].y - 1.0).abs() < 1e-9);
//! # Ok::<(), pirouette_graph::GraphError>(())
//! ```
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]
// 3 × 3 blocks read most plainly with their row and column indices.
#![allow(clippy::needless_range_loop)]

pub mod consistency;
pub mod init;
pub mod outliers;
mod solve;
mod sparse;
pub mod synthetic;

pub use solve::{
    innovation_chi2, marginal_covariances, optimise, GaussNewton, OptimiseConfig, Solver, Summary,
};

use pirouette_geom::{wrap_angle, Pose2};

/// Errors of pose graphs.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GraphError {
    /// An edge names a pose the graph does not have.
    #[error("edge {edge} joins pose {from} to pose {to}, but the graph has {poses} poses")]
    DanglingEdge {
        /// The edge's index.
        edge: usize,
        /// Its first pose.
        from: usize,
        /// Its second pose.
        to: usize,
        /// How many poses the graph has.
        poses: usize,
    },
    /// An edge's measurement or information is unusable.
    #[error("edge {edge}: {problem}")]
    BadEdge {
        /// The edge's index.
        edge: usize,
        /// What is wrong.
        problem: String,
    },
    /// The held pose does not exist.
    #[error("the held pose {held} is not among the graph's {poses} poses")]
    BadHeld {
        /// The held pose.
        held: usize,
        /// How many poses the graph has.
        poses: usize,
    },
    /// Some poses cannot be reached from the held one through the edges.
    #[error("pose {pose} is not joined to pose {held} by any chain of edges")]
    Disconnected {
        /// A pose out of reach.
        pose: usize,
        /// The held pose.
        held: usize,
    },
    /// A solve was given no start to solve from.
    #[error("no start to solve from")]
    NoStart,
    /// The linear algebra failed.
    #[error("the solver failed: {problem}")]
    Solver {
        /// What failed.
        problem: String,
    },
}

/// A robust kernel: how an edge's squared residual `s = eᵀ Ω e` enters the
/// cost. Large residuals of a wrong loop closure count for less under
/// Huber and Cauchy.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Kernel {
    /// `s` itself: plain least squares.
    #[default]
    Squared,
    /// `s` up to `δ²`, then `2δ√s − δ²` (linear in the residual's size).
    Huber {
        /// Where the kernel turns linear, in whitened residual units.
        delta: f64,
    },
    /// `c² ln(1 + s/c²)` (grows only logarithmically).
    Cauchy {
        /// Scale, in whitened residual units.
        c: f64,
    },
}

impl Kernel {
    /// The kernel's cost `ρ(s)` and weight `ρ'(s)` at squared residual `s`.
    pub fn cost_and_weight(&self, s: f64) -> (f64, f64) {
        match *self {
            Kernel::Squared => (s, 1.0),
            Kernel::Huber { delta } => {
                if s <= delta * delta {
                    (s, 1.0)
                } else {
                    let r = s.sqrt();
                    (2.0 * delta * r - delta * delta, delta / r)
                }
            }
            Kernel::Cauchy { c } => {
                let c2 = c * c;
                (c2 * (s / c2).ln_1p(), 1.0 / (1.0 + s / c2))
            }
        }
    }
}

/// Which residual an edge's cost is taken in. Both are zero exactly where
/// the poses agree with the measurement; they differ where the residual
/// turns, so the same poses cost differently in each, and each has its own
/// minimum.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Residual {
    /// g2o's: the `(x, y, θ)` of `z⁻¹ · (xᵢ⁻¹ · xⱼ)`. The χ² every solver
    /// reports is taken in this one.
    #[default]
    G2o,
    /// GTSAM's: the SE(2) logarithm of the same pose, whose translation is
    /// the g2o one turned and scaled by `V(θ)⁻¹`.
    Log,
}

/// The SE(2) logarithm of the pose whose `(x, y, θ)` is `e`, and its
/// derivative with respect to `e`.
fn log_of(e: [f64; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let [x, y, t] = e;
    let half = 0.5 * t;
    // a = (θ/2)·cot(θ/2), a' its derivative; their series near 0.
    let (a, da) = if t.abs() < 1e-4 {
        (1.0 - t * t / 12.0, -t / 6.0)
    } else {
        let cot = half.cos() / half.sin();
        let csc2 = 1.0 / (half.sin() * half.sin());
        (half * cot, 0.5 * cot - 0.25 * t * csc2)
    };
    let b = half;
    let log = [a * x + b * y, -b * x + a * y, t];
    let d = [
        [a, b, da * x + 0.5 * y],
        [-b, a, -0.5 * x + da * y],
        [0.0, 0.0, 1.0],
    ];
    (log, d)
}

/// A measured relative pose: pose `to` in the frame of pose `from`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edge {
    /// The pose the measurement is taken from.
    pub from: usize,
    /// The pose measured.
    pub to: usize,
    /// `from_from_to`: where `to` lies in `from`'s frame.
    pub measurement: Pose2,
    /// Information (inverse covariance) of the residual `(x, y, θ)`,
    /// symmetric positive definite.
    pub information: [[f64; 3]; 3],
    /// How the edge's residual enters the cost.
    pub kernel: Kernel,
}

impl Edge {
    /// An edge with the squared kernel.
    pub fn new(from: usize, to: usize, measurement: Pose2, information: [[f64; 3]; 3]) -> Self {
        Self {
            from,
            to,
            measurement,
            information,
            kernel: Kernel::Squared,
        }
    }

    /// The residual at poses `xi` (of `from`) and `xj` (of `to`):
    /// `(x, y, θ)` of `z⁻¹ · (xi⁻¹ · xj)`.
    pub fn residual(&self, xi: &Pose2, xj: &Pose2) -> [f64; 3] {
        let z = &self.measurement;
        let (si, ci) = xi.theta.sin_cos();
        let (sz, cz) = z.theta.sin_cos();
        let (dx, dy) = (xj.x - xi.x, xj.y - xi.y);
        // xi⁻¹ · xj's translation, then z⁻¹'s.
        let (ax, ay) = (ci * dx + si * dy, -si * dx + ci * dy);
        let (bx, by) = (ax - z.x, ay - z.y);
        [
            cz * bx + sz * by,
            -sz * bx + cz * by,
            wrap_angle(xj.theta - xi.theta - z.theta),
        ]
    }

    /// `eᵀ Ω e` at the given poses, `e` g2o's residual.
    pub fn chi2(&self, xi: &Pose2, xj: &Pose2) -> f64 {
        quadratic(&self.information, &self.residual(xi, xj))
    }

    /// The residual of the given kind at poses `xi`, `xj`.
    pub fn residual_in(&self, kind: Residual, xi: &Pose2, xj: &Pose2) -> [f64; 3] {
        let e = self.residual(xi, xj);
        match kind {
            Residual::G2o => e,
            Residual::Log => log_of(e).0,
        }
    }

    /// `eᵀ Ω e` with the residual of the given kind.
    pub fn cost_in(&self, kind: Residual, xi: &Pose2, xj: &Pose2) -> f64 {
        quadratic(&self.information, &self.residual_in(kind, xi, xj))
    }

    /// [`Edge::linearise`] for the residual of the given kind.
    pub(crate) fn linearise_in(
        &self,
        kind: Residual,
        xi: &Pose2,
        xj: &Pose2,
    ) -> ([f64; 3], [[f64; 3]; 3], [[f64; 3]; 3]) {
        let (e, ji, jj) = self.linearise(xi, xj);
        match kind {
            Residual::G2o => (e, ji, jj),
            Residual::Log => {
                let (l, d) = log_of(e);
                let chain = |j: &[[f64; 3]; 3]| {
                    let mut out = [[0.0; 3]; 3];
                    for r in 0..3 {
                        for c in 0..3 {
                            out[r][c] = (0..3).map(|m| d[r][m] * j[m][c]).sum();
                        }
                    }
                    out
                };
                (l, chain(&ji), chain(&jj))
            }
        }
    }

    /// The residual and its Jacobians with respect to `(x, y, θ)` of `xi`
    /// and of `xj` (poses updated by adding to each component).
    pub(crate) fn linearise(&self, xi: &Pose2, xj: &Pose2) -> ([f64; 3], [[f64; 3]; 3], [[f64; 3]; 3]) {
        let z = &self.measurement;
        let (si, ci) = xi.theta.sin_cos();
        let (sz, cz) = z.theta.sin_cos();
        let (dx, dy) = (xj.x - xi.x, xj.y - xi.y);
        // M = Rzᵀ Riᵀ, the rotation by −(θz + θi).
        let (c, s) = (cz * ci - sz * si, cz * si + sz * ci);
        let m = [[c, s], [-s, c]];
        // d(Riᵀ d)/dθi = [[−si, ci], [−ci, −si]] d, then Rzᵀ.
        let (gx, gy) = (-si * dx + ci * dy, -ci * dx - si * dy);
        let dtheta = [cz * gx + sz * gy, -sz * gx + cz * gy];
        let e = self.residual(xi, xj);
        let ji = [
            [-m[0][0], -m[0][1], dtheta[0]],
            [-m[1][0], -m[1][1], dtheta[1]],
            [0.0, 0.0, -1.0],
        ];
        let jj = [[m[0][0], m[0][1], 0.0], [m[1][0], m[1][1], 0.0], [0.0, 0.0, 1.0]];
        (e, ji, jj)
    }
}

/// `eᵀ Ω e`.
pub(crate) fn quadratic(omega: &[[f64; 3]; 3], e: &[f64; 3]) -> f64 {
    let mut s = 0.0;
    for a in 0..3 {
        for b in 0..3 {
            s += e[a] * omega[a][b] * e[b];
        }
    }
    s
}

/// A pose graph: poses, the edges between them, and the pose held fixed.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseGraph {
    /// `world_from_pose` of every node.
    pub poses: Vec<Pose2>,
    /// The measurements.
    pub edges: Vec<Edge>,
    /// The pose held where it is, which fixes the gauge.
    pub held: usize,
    /// The residual the optimiser minimises (χ² is always reported in
    /// g2o's).
    pub residual: Residual,
}

impl PoseGraph {
    /// A graph of `poses` without edges, holding the first pose.
    pub fn new(poses: Vec<Pose2>) -> Self {
        Self {
            poses,
            edges: Vec::new(),
            held: 0,
            residual: Residual::G2o,
        }
    }

    /// χ², the sum over edges of `eᵀ Ω e`.
    pub fn chi2(&self) -> f64 {
        self.edges
            .iter()
            .map(|e| e.chi2(&self.poses[e.from], &self.poses[e.to]))
            .sum()
    }

    /// The robust cost: the sum over edges of their kernel's `ρ(eᵀ Ω e)`.
    pub fn robust_cost(&self) -> f64 {
        self.edges
            .iter()
            .map(|e| {
                e.kernel
                    .cost_and_weight(e.chi2(&self.poses[e.from], &self.poses[e.to]))
                    .0
            })
            .sum()
    }

    /// The first pose that no chain of edges joins to the held one
    /// (`None`: the graph is one piece). Such a pose's place relative to
    /// the held one is unknown: an optimiser can only leave it where it
    /// started.
    pub fn unreached(&self) -> Option<usize> {
        let n = self.poses.len();
        let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); n];
        for e in self.edges.iter().filter(|e| e.from < n && e.to < n) {
            neighbours[e.from].push(e.to);
            neighbours[e.to].push(e.from);
        }
        let mut reached = vec![false; n];
        let mut stack: Vec<usize> = (self.held < n).then_some(self.held).into_iter().collect();
        while let Some(p) = stack.pop() {
            if !std::mem::replace(&mut reached[p], true) {
                stack.extend(neighbours[p].iter().copied().filter(|&q| !reached[q]));
            }
        }
        reached.iter().position(|r| !r)
    }

    /// Checks that every index in `edges` names an edge of the graph (the
    /// error says they were `asked_as`).
    pub(crate) fn check_edge_indices(&self, edges: &[usize], asked_as: &str) -> Result<(), GraphError> {
        match edges.iter().find(|&&k| k >= self.edges.len()) {
            Some(&bad) => Err(GraphError::BadEdge {
                edge: bad,
                problem: format!("{asked_as}, but the graph has {} edges", self.edges.len()),
            }),
            None => Ok(()),
        }
    }

    /// The covariance of edge `k`'s measurement: its information inverted.
    pub(crate) fn edge_covariance(&self, k: usize) -> Result<nalgebra::Matrix3<f64>, GraphError> {
        let o = self.edges[k].information;
        nalgebra::Matrix3::from_fn(|r, c| o[r][c])
            .try_inverse()
            .ok_or_else(|| GraphError::BadEdge {
                edge: k,
                problem: "its information does not invert".into(),
            })
    }

    /// Checks that edges name existing poses, measurements are finite and
    /// information matrices symmetric positive definite, and that the held
    /// pose exists.
    pub fn check(&self) -> Result<(), GraphError> {
        let poses = self.poses.len();
        if self.held >= poses {
            return Err(GraphError::BadHeld {
                held: self.held,
                poses,
            });
        }
        for (k, e) in self.edges.iter().enumerate() {
            if e.from >= poses || e.to >= poses {
                return Err(GraphError::DanglingEdge {
                    edge: k,
                    from: e.from,
                    to: e.to,
                    poses,
                });
            }
            let bad = |problem: String| GraphError::BadEdge { edge: k, problem };
            if e.from == e.to {
                return Err(bad(format!("joins pose {} to itself", e.from)));
            }
            if !e.measurement.is_finite() {
                return Err(bad("the measurement is not finite".into()));
            }
            check_information(&e.information).map_err(bad)?;
        }
        Ok(())
    }
}

/// Checks that `omega` is finite, symmetric and positive definite (a
/// Cholesky factorisation succeeds).
pub fn check_information(omega: &[[f64; 3]; 3]) -> Result<(), String> {
    if omega.iter().flatten().any(|v| !v.is_finite()) {
        return Err("the information matrix is not finite".into());
    }
    for a in 0..3 {
        for b in 0..a {
            let scale = omega[a][b].abs().max(omega[b][a].abs()).max(1e-300);
            if (omega[a][b] - omega[b][a]).abs() > 1e-9 * scale {
                return Err("the information matrix is not symmetric".into());
            }
        }
    }
    let mut l = [[0.0f64; 3]; 3];
    for j in 0..3 {
        let d = omega[j][j] - (0..j).map(|k| l[j][k] * l[j][k]).sum::<f64>();
        if d.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Err("the information matrix is not positive definite".into());
        }
        l[j][j] = d.sqrt();
        for i in j + 1..3 {
            l[i][j] = (omega[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>()) / l[j][j];
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Random poses and measurements: `linearise_in(kind)` gives the
    /// residual `residual_in(kind)` gives, and Jacobians that agree with
    /// central differences of it. Returns the cases checked.
    fn check_jacobians(kind: Residual, seed: u64) -> usize {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut cases = 0;
        for _ in 0..200 {
            let mut pose = || {
                Pose2::new(
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.1..3.1),
                )
            };
            let (xi, xj, z) = (pose(), pose(), pose());
            let edge = Edge::new(0, 1, z, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
            let (e, ji, jj) = edge.linearise_in(kind, &xi, &xj);
            assert_eq!(e, edge.residual_in(kind, &xi, &xj));
            let h = 1e-6;
            for k in 0..3 {
                let bump = |p: &Pose2, d: f64| {
                    let mut v = [p.x, p.y, p.theta];
                    v[k] += d;
                    Pose2 {
                        x: v[0],
                        y: v[1],
                        theta: v[2],
                    }
                };
                let diff = |a: [f64; 3], b: [f64; 3], r: usize| {
                    let d = a[r] - b[r];
                    (if r == 2 { wrap_angle(d) } else { d }) / (2.0 * h)
                };
                let (ai, bi) = (
                    edge.residual_in(kind, &bump(&xi, h), &xj),
                    edge.residual_in(kind, &bump(&xi, -h), &xj),
                );
                let (aj, bj) = (
                    edge.residual_in(kind, &xi, &bump(&xj, h)),
                    edge.residual_in(kind, &xi, &bump(&xj, -h)),
                );
                for r in 0..3 {
                    assert!((diff(ai, bi, r) - ji[r][k]).abs() < 1e-5, "{kind:?} ∂e{r}/∂xi{k}");
                    assert!((diff(aj, bj, r) - jj[r][k]).abs() < 1e-5, "{kind:?} ∂e{r}/∂xj{k}");
                }
            }
            cases += 1;
        }
        cases
    }

    #[test]
    fn jacobians_match_finite_differences() {
        assert_eq!(check_jacobians(Residual::G2o, 1), 200);
        assert_eq!(check_jacobians(Residual::Log, 2), 200);
    }

    /// The log residual is the SE(2) logarithm: its exponential gives g2o's
    /// residual pose back.
    #[test]
    fn the_log_residual_is_the_logarithm() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..200 {
            let e = [
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(-3.1..3.1),
            ];
            let (l, _) = log_of(e);
            let (t, u) = (l[2], [l[0], l[1]]);
            let (v00, v01) = if t.abs() < 1e-9 {
                (1.0, 0.0)
            } else {
                (t.sin() / t, -(1.0 - t.cos()) / t)
            };
            let back = [v00 * u[0] + v01 * u[1], -v01 * u[0] + v00 * u[1]];
            assert!(
                (back[0] - e[0]).abs() < 1e-9 && (back[1] - e[1]).abs() < 1e-9,
                "{back:?} {e:?}"
            );
            assert_eq!(l[2], e[2]);
        }
    }

    #[test]
    fn the_residual_is_zero_at_the_measurement() {
        let xi = Pose2::new(1.0, 2.0, 0.5);
        let z = Pose2::new(0.3, -0.2, 0.4);
        let xj = xi * z;
        let e = Edge::new(0, 1, z, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).residual(&xi, &xj);
        assert!(e.iter().all(|v| v.abs() < 1e-12), "{e:?}");
    }

    #[test]
    fn kernels_weigh_large_residuals_down() {
        let huber = Kernel::Huber { delta: 1.0 };
        assert_eq!(huber.cost_and_weight(0.25), (0.25, 1.0));
        assert_eq!(huber.cost_and_weight(9.0), (5.0, 1.0 / 3.0));
        let (cost, w) = Kernel::Cauchy { c: 1.0 }.cost_and_weight(3.0);
        assert!((cost - 4f64.ln()).abs() < 1e-12 && (w - 0.25).abs() < 1e-12);
    }

    #[test]
    fn bad_information_is_refused() {
        let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(check_information(&id).is_ok());
        assert!(check_information(&[[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).is_err());
        assert!(check_information(&[[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).is_err());
        assert!(check_information(&[[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).is_err());
        let mut g = PoseGraph::new(vec![Pose2::IDENTITY; 2]);
        g.edges.push(Edge::new(0, 2, Pose2::IDENTITY, id));
        assert!(matches!(g.check(), Err(GraphError::DanglingEdge { edge: 0, .. })));
    }
}
