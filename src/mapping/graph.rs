//! A small 2D pose graph: poses joined by measured relative poses, solved
//! by least squares with the first pose held.

use nalgebra::{Matrix3, Vector3};
use pirouette_geom::Pose2;

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

impl Edge {
    /// The edge's residual at poses `xi`, `xj`.
    fn residual(&self, xi: &Pose2, xj: &Pose2) -> Vector3<f64> {
        let pred = xi.between(xj);
        Vector3::new(
            pred.x - self.z.x,
            pred.y - self.z.y,
            pirouette_geom::wrap_angle(pred.theta - self.z.theta),
        )
    }

    fn chi2(&self, poses: &[Pose2]) -> f64 {
        let r = self.residual(&poses[self.i], &poses[self.j]);
        (r.transpose() * self.info * r)[0]
    }
}

/// An edge whose squared Mahalanobis residual exceeds this after the first
/// solve (three degrees of freedom, 99.9 %) is dropped: a wrong match.
const EDGE_GATE: f64 = 16.27;

/// The poses (the first held, which fixes the frame) that agree best with
/// `edges` in the least-squares sense: Gauss-Newton from the given poses,
/// then once more without the edges the first solution contradicts
/// ([`EDGE_GATE`]).
pub(crate) fn adjust(poses: &mut [Pose2], mut edges: Vec<Edge>) {
    let n = poses.len();
    if n < 2 {
        return;
    }
    let dim = 3 * (n - 1);
    for round in 0..2 {
        for _iter in 0..GRAPH_ITERATIONS {
            let mut h = nalgebra::DMatrix::<f64>::zeros(dim, dim);
            let mut g = nalgebra::DVector::<f64>::zeros(dim);
            for e in &edges {
                let r = e.residual(&poses[e.i], &poses[e.j]);
                // Jacobians by central differences, per node (the first is
                // held).
                let (pi, pj) = (poses[e.i], poses[e.j]);
                let nudged = |p: Pose2, c: usize, d: f64| match c {
                    0 => Pose2::new(p.x + d, p.y, p.theta),
                    1 => Pose2::new(p.x, p.y + d, p.theta),
                    _ => Pose2::new(p.x, p.y, p.theta + d),
                };
                let mut jac = [Matrix3::zeros(); 2];
                for c in 0..3 {
                    let di = |d: f64| e.residual(&nudged(pi, c, d), &pj);
                    let dj = |d: f64| e.residual(&pi, &nudged(pj, c, d));
                    jac[0].set_column(c, &((di(GRAPH_STEP) - di(-GRAPH_STEP)) / (2.0 * GRAPH_STEP)));
                    jac[1].set_column(c, &((dj(GRAPH_STEP) - dj(-GRAPH_STEP)) / (2.0 * GRAPH_STEP)));
                }
                for (a, &na) in [e.i, e.j].iter().enumerate() {
                    if na == 0 {
                        continue;
                    }
                    let mut ga = g.rows_mut(3 * (na - 1), 3);
                    ga += jac[a].transpose() * e.info * r;
                    for (b, &nb) in [e.i, e.j].iter().enumerate() {
                        if nb == 0 {
                            continue;
                        }
                        let mut hab = h.view_mut((3 * (na - 1), 3 * (nb - 1)), (3, 3));
                        hab += jac[a].transpose() * e.info * jac[b];
                    }
                }
            }
            let Some(step) = h.cholesky().map(|c| c.solve(&(-g))) else {
                return;
            };
            for (s, p) in poses.iter_mut().enumerate().skip(1) {
                let d = step.fixed_rows::<3>(3 * (s - 1));
                *p = Pose2::new(p.x + d[0], p.y + d[1], p.theta + d[2]);
            }
            if step.amax() < 1e-9 {
                break;
            }
        }
        let before = edges.len();
        if round == 0 {
            edges.retain(|e| e.chi2(poses) <= EDGE_GATE);
        }
        if edges.len() == before {
            break;
        }
    }
}

/// Gauss-Newton iterations, at most.
const GRAPH_ITERATIONS: usize = 10;

/// Finite-difference step of the Jacobians.
const GRAPH_STEP: f64 = 1e-6;

#[cfg(test)]
mod tests {
    use super::*;

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
