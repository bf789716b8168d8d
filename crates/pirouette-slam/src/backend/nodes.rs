//! The pose graph of a stream of frames over some of them (the nodes):
//! the steps between two nodes are composed into one edge of the chain,
//! and every other frame hangs from the node before it at the pose the
//! steps gave it. A long log's graph, and the memory its solves take,
//! then grow with its nodes, not its frames.

use super::edge::{information, Edge as MeasuredEdge};
use super::solve::{Graph, Role};
use nalgebra::Matrix3;
use pirouette_geom::Pose2;
use pirouette_graph::Edge as GraphEdge;

/// The graph, and where each frame hangs from it.
#[derive(Debug)]
pub(crate) struct Nodes {
    /// A node per node frame at its current pose; an edge per run of
    /// steps between two nodes (the chain) and per loop.
    pub graph: Graph,
    /// The scan of each node.
    pub scans: Vec<usize>,
    /// Each node's pose in the frame of the node before, as the steps
    /// between them measured it.
    span: Vec<Pose2>,
    /// Per scan: the node it hangs from (its own, for a node) ...
    anchor: Vec<u32>,
    /// ... and its pose in that node's frame.
    offset: Vec<Pose2>,
    /// The steps since the last node: the newest scan's pose in its frame,
    /// and that pose's covariance there.
    chain: (Pose2, Matrix3<f64>),
}

impl Nodes {
    /// Scan 0, a node at the origin.
    pub fn new() -> Self {
        Self {
            graph: Graph::new(vec![Pose2::IDENTITY]),
            scans: vec![0],
            span: vec![Pose2::IDENTITY],
            anchor: vec![0],
            offset: vec![Pose2::IDENTITY],
            chain: (Pose2::IDENTITY, Matrix3::zeros()),
        }
    }

    /// The next scan, `step` after the one before (its covariance
    /// `covariance` in the frame of the one before), at world pose `pose`;
    /// a node if `node`.
    pub fn step(&mut self, step: &Pose2, covariance: &Matrix3<f64>, pose: Pose2, node: bool) {
        let (z, sigma) = &self.chain;
        // First-order propagation through the composition z ∘ step.
        let composed = *z * *step;
        let sigma = z.compose_covariance(sigma, step, covariance);
        let last = self.scans.len() - 1;
        if node {
            let edge = MeasuredEdge {
                i: last,
                j: last + 1,
                z: composed,
                info: information(&sigma),
            };
            self.graph.push_node(pose);
            self.graph.push(edge.to_graph(), Role::Chain);
            self.scans.push(self.anchor.len());
            self.span.push(composed);
            self.anchor.push((last + 1) as u32);
            self.offset.push(Pose2::IDENTITY);
            self.chain = (Pose2::IDENTITY, Matrix3::zeros());
        } else {
            self.anchor.push(last as u32);
            self.offset.push(composed);
            self.chain = (composed, sigma);
        }
    }

    /// The node of scan `k`, if it is one.
    pub fn node_of(&self, k: usize) -> Option<usize> {
        let a = *self.anchor.get(k)? as usize;
        (self.scans[a] == k).then_some(a)
    }

    /// Adds `edge` (between node scans, `i` and `j` scan numbers) as a
    /// loop between their nodes: its index, or `None` where a scan of it
    /// is not a node.
    pub fn add(&mut self, mut edge: GraphEdge) -> Option<usize> {
        edge.from = self.node_of(edge.from)?;
        edge.to = self.node_of(edge.to)?;
        Some(self.graph.push(edge, Role::Loop))
    }

    /// Every scan's pose from the nodes' (after a solve): a scan between
    /// two nodes at its offset from each, blended by its place between
    /// them, so that the two nodes' disagreement with the steps between
    /// them is spread along the steps instead of falling on the last.
    pub fn poses(&self) -> impl Iterator<Item = Pose2> + '_ {
        let poses = self.graph.poses();
        (self.anchor.iter().zip(&self.offset).enumerate()).map(move |(k, (&a, o))| {
            let a = a as usize;
            let from_a = poses[a] * *o;
            let Some(&b_scan) = self.scans.get(a + 1) else {
                return from_a;
            };
            let from_b = poses[a + 1] * self.span[a + 1].inverse() * *o;
            let f = (k - self.scans[a]) as f64 / (b_scan - self.scans[a]) as f64;
            let turn = pirouette_geom::wrap_angle(from_b.theta - from_a.theta);
            Pose2::new(
                from_a.x + f * (from_b.x - from_a.x),
                from_a.y + f * (from_b.y - from_a.y),
                pirouette_geom::wrap_angle(from_a.theta + f * turn),
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pirouette_graph::OptimiseConfig;

    fn cov(sx: f64, st: f64) -> Matrix3<f64> {
        Matrix3::from_diagonal(&nalgebra::Vector3::new(sx * sx, sx * sx, st * st))
    }

    #[test]
    fn scans_between_nodes_hang_from_the_one_before_at_their_steps() {
        let mut n = Nodes::new();
        let step = Pose2::new(0.5, 0.1, 0.2);
        let mut pose = Pose2::IDENTITY;
        for k in 1..=7 {
            pose = pose * step;
            n.step(&step, &cov(0.01, 0.004), pose, k % 3 == 0);
        }
        assert_eq!(n.scans, vec![0, 3, 6]);
        assert_eq!(n.graph.edges(), 2);
        assert_eq!(n.node_of(3), Some(1));
        assert_eq!(n.node_of(4), None);
        // The composed edge measures three steps.
        let three = step * step * step;
        let z = n.graph.edge(0).measurement;
        assert!((z.x - three.x).abs() < 1e-12 && (z.y - three.y).abs() < 1e-12);
        // Every scan where the steps put it.
        let mut expect = Pose2::IDENTITY;
        for (k, p) in n.poses().enumerate() {
            assert!(
                (p.x - expect.x).abs() < 1e-12 && (p.theta - expect.theta).abs() < 1e-12,
                "{k}"
            );
            expect = expect * step;
        }
    }

    #[test]
    fn a_composed_edge_carries_the_covariance_of_its_steps() {
        // Two straight steps of 1 m, heading spread σ each: the second
        // step's position spreads sideways by 1 m · σ from the first's
        // heading, on top of the two steps' own spreads.
        let mut n = Nodes::new();
        let (sx, st) = (0.01, 0.02);
        let step = Pose2::new(1.0, 0.0, 0.0);
        n.step(&step, &cov(sx, st), step, false);
        n.step(&step, &cov(sx, st), step * step, true);
        let info = n.graph.edge(0).information;
        let o = Matrix3::from_fn(|r, c| info[r][c]);
        let sigma = o.try_inverse().expect("invertible");
        assert!((sigma[(0, 0)] - 2.0 * sx * sx).abs() < 1e-12);
        assert!((sigma[(1, 1)] - (2.0 * sx * sx + st * st)).abs() < 1e-12);
        assert!((sigma[(2, 2)] - 2.0 * st * st).abs() < 1e-12);
        assert!((sigma[(1, 2)] - st * st).abs() < 1e-12);
    }

    #[test]
    fn a_solve_moves_the_scans_between_nodes_with_them() {
        // A square of 4 sides × 4 steps, the steps' turns a little short
        // (within their noise); a loop edge back to the start closes it.
        let mut n = Nodes::new();
        let mut pose = Pose2::IDENTITY;
        let mut k = 0;
        for side in 0..4 {
            for s in 0..4 {
                let turn = if s == 3 && side < 3 { 1.5 } else { 0.0 };
                let step = Pose2::new(1.0, 0.0, turn);
                pose = pose * step;
                k += 1;
                n.step(&step, &cov(0.05, 0.05), pose, k % 4 == 0);
            }
        }
        let last = k;
        let loop_z = n.graph.poses()[0].between(&Pose2::IDENTITY);
        let info = [[1e4, 0.0, 0.0], [0.0, 1e4, 0.0], [0.0, 0.0, 1e4]];
        assert!(
            n.add(GraphEdge::new(5, 0, loop_z, info)).is_none(),
            "scan 5 is not a node"
        );
        assert!(n.add(GraphEdge::new(last, 0, loop_z, info)).is_some());
        let before: Vec<Pose2> = n.poses().collect();
        assert!(n.graph.solve(&OptimiseConfig::default()));
        let after: Vec<Pose2> = n.poses().collect();
        // The last scan comes back to the start.
        assert!(after[last].translation().norm() < before[last].translation().norm());
        // A scan between two nodes sits its share of the way from where
        // the node before puts it to where the node after does.
        let p = n.graph.poses();
        for k in [1usize, 2, 5, 7, 10] {
            let (a, f) = (k / 4, (k % 4) as f64 / 4.0);
            let from_a = p[a] * n.offset[k];
            let from_b = p[a + 1] * n.span[a + 1].inverse() * n.offset[k];
            assert!((after[k].x - (from_a.x + f * (from_b.x - from_a.x))).abs() < 1e-9);
            assert!((after[k].y - (from_a.y + f * (from_b.y - from_a.y))).abs() < 1e-9);
            // And the nodes' disagreement is real: the blend moves it.
            assert!(from_a.between(&from_b).translation().norm() > 1e-6);
        }
    }
}
