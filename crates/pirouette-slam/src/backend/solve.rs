//! The one gated solve of both sensors' graphs: the loop closures checked
//! against each other first (pairwise consistency, [`LoopCheck`]: the
//! largest set that agree with each other and the chain goes on), the
//! graph solved by least squares over what passed, and the edges the
//! solution contradicts ([`GATE`]) dropped for good before it is solved
//! once more.
//!
//! A camera map solves its sweeps' graph once; a laser log solves its
//! graph whenever a loop disagrees with it, and each solve checks only
//! the loops new since the last against the rest.

use pirouette_geom::Pose2;
use pirouette_graph::consistency::LoopCheck;
use pirouette_graph::outliers::CHI2_3_999;
use pirouette_graph::{optimise, Edge as GraphEdge, OptimiseConfig, PoseGraph};

/// An edge whose squared Mahalanobis residual exceeds this after a solve
/// (three degrees of freedom, 99.9 %) is dropped: a wrong match. Two loop
/// closures whose cycle with the chain exceeds it do not agree.
pub(crate) const GATE: f64 = CHI2_3_999;

/// The newest loops (not dropped) checked against each other before a
/// solve, at most: older ones passed the checks of the solves before,
/// and are used while the solution does not contradict them. The check
/// then holds at most a bit per pair of twice this many (512 kB), and its
/// time stays bounded however many loops a long log closes.
pub(crate) const CHECK_WINDOW: usize = 1024;

/// What an edge is to the solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Role {
    /// A step of the chain, from node `k` to node `k + 1`: always kept,
    /// the spine the loops are checked along.
    Chain,
    /// A step of the chain that the solution may contradict (a commanded
    /// move the wheels did not make): dropped where it does.
    GatedChain,
    /// A loop closure: checked against the others before the solve, and
    /// dropped where the solution contradicts it.
    Loop,
}

/// A pose graph and what each edge is to its solve.
#[derive(Debug)]
pub(crate) struct Graph {
    graph: PoseGraph,
    roles: Vec<Role>,
    /// Per edge: dropped by the gate, for good.
    dropped: Vec<bool>,
    /// Per edge: whether the last solve used it (every edge not dropped,
    /// before any solve).
    used: Vec<bool>,
    check: LoopCheck,
}

impl Graph {
    /// Nodes at `poses`, no edges.
    pub fn new(poses: Vec<Pose2>) -> Self {
        Self {
            graph: PoseGraph::new(poses),
            roles: Vec::new(),
            dropped: Vec::new(),
            used: Vec::new(),
            check: LoopCheck::new(GATE),
        }
    }

    /// Adds a node at `pose`.
    pub fn push_node(&mut self, pose: Pose2) {
        self.graph.poses.push(pose);
    }

    /// Adds `edge` as `role`: its index.
    pub fn push(&mut self, edge: GraphEdge, role: Role) -> usize {
        self.graph.edges.push(edge);
        self.roles.push(role);
        self.dropped.push(false);
        self.used.push(true);
        self.graph.edges.len() - 1
    }

    /// The nodes' poses.
    pub fn poses(&self) -> &[Pose2] {
        &self.graph.poses
    }

    /// Edge `k`.
    #[cfg(test)]
    pub fn edge(&self, k: usize) -> &GraphEdge {
        &self.graph.edges[k]
    }

    /// How many edges.
    pub fn edges(&self) -> usize {
        self.graph.edges.len()
    }

    /// Whether the last solve used edge `k`: it was neither dropped nor
    /// left out as inconsistent with the other loops.
    pub fn kept(&self, k: usize) -> bool {
        self.used[k]
    }

    /// The graph with only the edges the last solve used.
    pub fn into_kept(self) -> PoseGraph {
        let PoseGraph { poses, edges, .. } = self.graph;
        let mut graph = PoseGraph::new(poses);
        graph.edges = (edges.into_iter().zip(&self.used))
            .filter(|(_, &u)| u)
            .map(|(e, _)| e)
            .collect();
        graph
    }

    /// Solves the graph (the first pose held) with `config`: the newest
    /// loops not dropped ([`CHECK_WINDOW`]) checked pairwise and only the
    /// largest consistent set of them used; the edges the solution
    /// contradicts beyond [`GATE`] (but the chain's) dropped for good, and
    /// the graph solved again without them (where that fails, the first
    /// solution stands). Where the first solve fails, the poses stay as
    /// they were: `false`.
    ///
    /// Loops are checked along the chain of edges `k → k + 1` (the first
    /// of each pair); where that does not join every node, or an edge's
    /// information does not invert, every loop not dropped is used.
    pub fn solve(&mut self, config: &OptimiseConfig) -> bool {
        let n = self.graph.edges.len();
        let loops: Vec<usize> = (0..n)
            .filter(|&k| self.roles[k] == Role::Loop && !self.dropped[k])
            .collect();
        // The newest loops are checked; older ones passed checks before.
        let checked = &loops[loops.len().saturating_sub(CHECK_WINDOW)..];
        if self.check.seen() >= 2 * CHECK_WINDOW {
            self.check.retain(checked);
        }
        let mut used: Vec<bool> = self.dropped.iter().map(|d| !d).collect();
        if let Ok(Some(c)) = self.check.check(&self.graph, checked) {
            for k in c.dropped {
                used[k] = false;
            }
        }
        let mut first = self.subgraph(&used);
        if optimise(&mut first.0, config).is_err() {
            self.used = used;
            return false;
        }
        let mut contradicted = false;
        for (e, &k) in first.0.edges.iter().zip(&first.1) {
            let p = &first.0.poses;
            if self.roles[k] != Role::Chain && e.chi2(&p[e.from], &p[e.to]) > GATE {
                self.dropped[k] = true;
                used[k] = false;
                contradicted = true;
            }
        }
        self.graph.poses = first.0.poses;
        if contradicted {
            let mut again = self.subgraph(&used);
            if optimise(&mut again.0, config).is_ok() {
                self.graph.poses = again.0.poses;
            }
        }
        self.used = used;
        true
    }

    /// The graph of the edges `used` at the current poses, and the index
    /// of each of its edges here.
    fn subgraph(&self, used: &[bool]) -> (PoseGraph, Vec<usize>) {
        let mut graph = PoseGraph::new(self.graph.poses.clone());
        let index: Vec<usize> = (0..used.len()).filter(|&k| used[k]).collect();
        graph.edges = index.iter().map(|&k| self.graph.edges[k]).collect();
        (graph, index)
    }
}

#[cfg(test)]
mod tests {
    use super::super::edge::Edge;
    use super::*;
    use nalgebra::{Matrix3, Vector3};
    use pirouette_graph::Solver;

    fn gauss_newton() -> OptimiseConfig {
        OptimiseConfig {
            solver: Solver::GaussNewton,
            max_iterations: 10,
            relative_decrease: 1e-12,
            ..OptimiseConfig::default()
        }
    }

    fn close(a: &Pose2, b: &Pose2, tol: f64) -> bool {
        let d = a.between(b);
        d.x.hypot(d.y) < tol && d.theta.abs() < tol
    }

    #[test]
    fn the_adjustment_turns_a_group_of_sweeps_back_and_drops_a_wrong_match() {
        let truth = [
            Pose2::IDENTITY,
            Pose2::from_deg(1.0, 0.0, 30.0),
            Pose2::from_deg(1.5, 0.8, 100.0),
            Pose2::from_deg(0.3, 1.0, 200.0),
        ];
        // Every pair measured exactly, to 1 cm and 2°; one match 10 cm and
        // 5° wrong.
        let info = Matrix3::from_diagonal(&Vector3::new(1e4, 1e4, 1.0 / 2f64.to_radians().powi(2)));
        // Sweeps 2 and 3 start turned 3° about sweep 1 and 5 cm off,
        // agreeing with each other.
        let about_1 = truth[1] * Pose2::from_deg(0.05, 0.0, 3.0) * truth[1].inverse();
        let mut graph = Graph::new(vec![truth[0], truth[1], about_1 * truth[2], about_1 * truth[3]]);
        let edge = |i: usize, j: usize, z: Pose2| Edge { i, j, z, info }.to_graph();
        for i in 0..3 {
            graph.push(edge(i, i + 1, truth[i].between(&truth[i + 1])), Role::GatedChain);
        }
        for (i, j) in [(0, 2), (0, 3), (1, 3)] {
            graph.push(edge(i, j, truth[i].between(&truth[j])), Role::Loop);
        }
        let wrong = graph.push(
            edge(0, 2, truth[0].between(&truth[2]) * Pose2::from_deg(0.1, 0.0, 5.0)),
            Role::Loop,
        );
        assert!(graph.solve(&gauss_newton()));
        for (p, t) in graph.poses().iter().zip(&truth) {
            assert!(close(p, t, 1e-6), "{p:?} vs {t:?}");
        }
        assert!(!graph.kept(wrong));
        assert!((0..wrong).all(|k| graph.kept(k)));
        assert_eq!(graph.into_kept().edges.len(), wrong);
    }

    /// Two loops of a long chain that agree with each other and one that
    /// pulls the other way: the one is left out before any solve, and a
    /// solve without the check would have bent the chain towards it.
    #[test]
    fn a_loop_the_others_contradict_is_left_out_before_the_solve() {
        // A square of 4 m sides walked in 16 steps of 1 m, the steps to
        // 1 cm and 0.5°; loops to 1 cm and 0.5° too.
        let step_info = Matrix3::from_diagonal(&Vector3::new(1e4, 1e4, 1.0 / 0.5f64.to_radians().powi(2)));
        let truth: Vec<Pose2> = (0..=16)
            .scan(Pose2::IDENTITY, |p, k| {
                let here = *p;
                let turn = if k % 4 == 3 { 90.0 } else { 0.0 };
                *p = *p * Pose2::from_deg(1.0, 0.0, turn);
                Some(here)
            })
            .collect();
        let build = || {
            let mut g = Graph::new(truth.clone());
            for k in 0..16 {
                let z = truth[k].between(&truth[k + 1]);
                g.push(
                    Edge {
                        i: k,
                        j: k + 1,
                        z,
                        info: step_info,
                    }
                    .to_graph(),
                    Role::Chain,
                );
            }
            g
        };
        let loop_edge = |i: usize, j: usize, off: Pose2| {
            Edge {
                i,
                j,
                z: truth[i].between(&truth[j]) * off,
                info: step_info,
            }
            .to_graph()
        };
        let good = [(0, 16), (1, 15)];
        let mut graph = build();
        for (i, j) in good {
            graph.push(loop_edge(i, j, Pose2::IDENTITY), Role::Loop);
        }
        // Says node 12 lies 1.5 m from node 4's place: both 2.9 m and 1 m
        // on from where it is.
        let wrong = graph.push(loop_edge(4, 12, Pose2::from_deg(1.5, 0.0, 20.0)), Role::Loop);
        assert!(graph.solve(&OptimiseConfig::default()));
        assert!(!graph.kept(wrong));
        for (p, t) in graph.poses().iter().zip(&truth) {
            assert!(close(p, t, 1e-6), "{p:?} vs {t:?}");
        }
        // Not dropped for good: a later solve checks it again.
        let again = graph.push(loop_edge(2, 14, Pose2::IDENTITY), Role::Loop);
        assert!(graph.solve(&OptimiseConfig::default()));
        assert!(graph.kept(again) && !graph.kept(wrong));
        // Unchecked, the wrong loop bends the chain.
        let mut unchecked = build();
        for (i, j) in good {
            unchecked.push(loop_edge(i, j, Pose2::IDENTITY), Role::GatedChain);
        }
        unchecked.push(
            loop_edge(4, 12, Pose2::from_deg(1.5, 0.0, 20.0)),
            Role::GatedChain,
        );
        let mut plain = PoseGraph::new(truth.clone());
        plain.edges = (0..unchecked.edges()).map(|k| *unchecked.edge(k)).collect();
        optimise(&mut plain, &OptimiseConfig::default()).unwrap();
        assert!(!close(&plain.poses[12], &truth[12], 0.05));
    }

    /// An edge the gate drops stays dropped at later solves; where the
    /// first solve fails, the poses stay as they were.
    #[test]
    fn a_dropped_edge_stays_dropped_and_a_failed_solve_moves_nothing() {
        let info = Matrix3::from_diagonal(&Vector3::new(1e4, 1e4, 1e4));
        let truth = [
            Pose2::IDENTITY,
            Pose2::new(1.0, 0.0, 0.0),
            Pose2::new(2.0, 0.0, 0.0),
        ];
        let mut graph = Graph::new(truth.to_vec());
        let edge = |i: usize, j: usize, z: Pose2| Edge { i, j, z, info }.to_graph();
        for i in 0..2 {
            graph.push(edge(i, i + 1, truth[i].between(&truth[i + 1])), Role::Chain);
        }
        graph.push(edge(0, 2, truth[0].between(&truth[2])), Role::Loop);
        // Half a metre off, to 10 cm: the solution hardly heeds it, and it
        // lies 5σ off that.
        let loose = Matrix3::from_diagonal(&Vector3::new(1e2, 1e2, 1e2));
        let off = Edge {
            i: 0,
            j: 2,
            z: Pose2::new(2.5, 0.0, 0.0),
            info: loose,
        };
        let bad = graph.push(off.to_graph(), Role::GatedChain);
        assert!(graph.solve(&gauss_newton()));
        assert!(!graph.kept(bad));
        assert!(graph.solve(&gauss_newton()));
        assert!(!graph.kept(bad) && graph.kept(0) && graph.kept(2));
        for (p, t) in graph.poses().iter().zip(&truth) {
            assert!(close(p, t, 1e-6), "{p:?} vs {t:?}");
        }
        // A measurement that is not a number: the graph's check refuses it.
        graph.push_node(Pose2::new(7.0, 7.0, 1.0));
        graph.push(edge(2, 3, Pose2::new(f64::NAN, 0.0, 0.0)), Role::Chain);
        let before = graph.poses().to_vec();
        assert!(!graph.solve(&gauss_newton()));
        assert_eq!(graph.poses(), &before[..]);
    }
}
