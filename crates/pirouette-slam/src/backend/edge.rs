//! The sweeps' pose graph: poses joined by measured relative poses, solved
//! by least squares ([`pirouette_graph`]) with the first pose held.

use nalgebra::Matrix3;
use pirouette_geom::Pose2;
use pirouette_graph::{optimise, Edge as GraphEdge, OptimiseConfig, PoseGraph, Solver};

/// A relative pose measured between two nodes: node `j`'s pose in node
/// `i`'s frame, with its information in `i`'s `(x, y, θ)`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Edge {
    /// The node the measurement is taken from.
    pub i: usize,
    /// The node measured.
    pub j: usize,
    /// `j`'s pose in `i`'s frame.
    pub z: Pose2,
    /// Information (inverse covariance) of `z`, in `i`'s `(x, y, θ)`.
    pub info: Matrix3<f64>,
}

/// The information of a measurement with covariance `covariance`: its
/// inverse, made symmetric to the bit; where the covariance does not
/// invert, the inverse of its variances alone (none where a variance is
/// not positive), so that a degenerate measurement still weighs what its
/// spreads say and never more.
pub(crate) fn information(covariance: &Matrix3<f64>) -> Matrix3<f64> {
    let info = covariance.try_inverse().unwrap_or_else(|| {
        Matrix3::from_diagonal(&covariance.diagonal().map(|v| if v > 0.0 { 1.0 / v } else { 0.0 }))
    });
    0.5 * (info + info.transpose())
}

impl Edge {
    /// The edge for [`pirouette_graph`], whose residual is taken in `z`'s
    /// frame (`z⁻¹ · xᵢ⁻¹ · xⱼ`): the information turned into that frame,
    /// so that the cost of any poses is the same.
    pub(crate) fn to_graph(self) -> GraphEdge {
        // The residual in i's frame is R(θ_z) times the one in z's frame.
        let r = self.z.tangent_rotation();
        let o = r.transpose() * self.info * r;
        // Symmetric to the bit, as the graph checks.
        let o = 0.5 * (o + o.transpose());
        let information = [
            [o[(0, 0)], o[(0, 1)], o[(0, 2)]],
            [o[(1, 0)], o[(1, 1)], o[(1, 2)]],
            [o[(2, 0)], o[(2, 1)], o[(2, 2)]],
        ];
        GraphEdge::new(self.i, self.j, self.z, information)
    }
}

/// An edge whose squared Mahalanobis residual exceeds this after the first
/// solve (three degrees of freedom, 99.9 %) is dropped: a wrong match.
pub(crate) const EDGE_GATE: f64 = 16.27;

/// The poses (the first held, which fixes the frame) that agree best with
/// `edges` in the least-squares sense: Gauss-Newton from the given poses
/// ([`pirouette_graph::optimise`]), then once more without the edges the
/// first solution contradicts ([`EDGE_GATE`]). Poses stay as they were
/// where the graph cannot be solved (a pose no edge reaches). Returns, per
/// edge, whether it was kept.
pub(crate) fn adjust(poses: &mut [Pose2], edges: Vec<Edge>) -> Vec<bool> {
    let mut kept = vec![true; edges.len()];
    if poses.len() < 2 {
        return kept;
    }
    let mut graph = PoseGraph::new(poses.to_vec());
    graph.edges = edges.into_iter().map(Edge::to_graph).collect();
    let config = OptimiseConfig {
        solver: Solver::GaussNewton,
        max_iterations: GRAPH_ITERATIONS,
        relative_decrease: 1e-12,
        ..OptimiseConfig::default()
    };
    if optimise(&mut graph, &config).is_err() {
        return kept;
    }
    let poses_now = &graph.poses;
    for (k, e) in graph.edges.iter().enumerate() {
        kept[k] = e.chi2(&poses_now[e.from], &poses_now[e.to]) <= EDGE_GATE;
    }
    if kept.iter().any(|k| !k) {
        let mut i = 0;
        graph.edges.retain(|_| {
            i += 1;
            kept[i - 1]
        });
        if optimise(&mut graph, &config).is_err() {
            return kept;
        }
    }
    poses.copy_from_slice(&graph.poses);
    kept
}

/// Gauss-Newton iterations, at most.
const GRAPH_ITERATIONS: usize = 10;

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn information_inverts_or_falls_back_to_the_variances() {
        let c = Matrix3::new(4.0, 1.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 0.5);
        let i = information(&c);
        assert!((i * c - Matrix3::identity()).norm() < 1e-12);
        assert_eq!(i, i.transpose());
        // Rank one: the variances' inverses alone, and none for a zero one.
        let singular = Matrix3::new(1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0);
        assert_eq!(
            information(&singular),
            Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 0.0))
        );
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
        let mut edges = Vec::new();
        for i in 0..4 {
            for j in (i + 1)..4 {
                let z = truth[i].between(&truth[j]);
                edges.push(Edge { i, j, z, info });
            }
        }
        edges.push(Edge {
            i: 0,
            j: 2,
            z: truth[0].between(&truth[2]) * Pose2::from_deg(0.1, 0.0, 5.0),
            info,
        });
        // Sweeps 2 and 3 start turned 3° about sweep 1 and 5 cm off,
        // agreeing with each other.
        let about_1 = truth[1] * Pose2::from_deg(0.05, 0.0, 3.0) * truth[1].inverse();
        let mut poses = vec![truth[0], truth[1], about_1 * truth[2], about_1 * truth[3]];
        adjust(&mut poses, edges);
        for (p, t) in poses.iter().zip(&truth) {
            let d = t.between(p);
            assert!(d.x.hypot(d.y) < 1e-6 && d.theta.abs() < 1e-6, "{p:?} vs {t:?}");
        }
    }
}
