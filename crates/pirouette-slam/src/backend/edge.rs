//! A measured relative pose between two nodes of the graph, as a
//! sensor's match gives it: in the first node's frame, with its
//! information there.

use nalgebra::Matrix3;
use pirouette_geom::Pose2;
use pirouette_graph::Edge as GraphEdge;

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
}
