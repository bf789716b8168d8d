//! Synthetic pose graphs for tests and benchmarks.

use crate::{Edge, PoseGraph};
use pirouette_geom::Pose2;
use std::collections::HashMap;

/// A grid world of `n` poses, as in the pose-graph literature's synthetic
/// benchmarks (Olson's M3500 is one): a walk of 1 m steps on a square
/// lattice that turns left, right or not at random; an odometry edge per
/// step; and a loop edge from each pose to the latest earlier pose (three
/// or more steps back) on the same lattice point. Measurements carry
/// Gaussian noise of `sigma_m` and `sigma_rad`, and information to match.
/// Poses start at the origin. Returns the graph and the true poses.
///
/// # Memory
/// About 200 bytes per pose (the graph's poses and edges, and a hash map of
/// visited lattice points).
pub fn grid_world(n: usize, sigma_m: f64, sigma_rad: f64, seed: u64) -> (PoseGraph, Vec<Pose2>) {
    let mut rng = SplitMix(seed);
    let info = [
        [sigma_m.powi(-2), 0.0, 0.0],
        [0.0, sigma_m.powi(-2), 0.0],
        [0.0, 0.0, sigma_rad.powi(-2)],
    ];
    // The walk on integers, so that revisits are exact.
    let mut cells: Vec<(i64, i64, u8)> = Vec::with_capacity(n);
    let (mut x, mut y, mut dir) = (0i64, 0i64, 0u8);
    for k in 0..n {
        if k > 0 {
            dir = (dir + [0, 1, 3][(rng.next() % 3) as usize]) % 4;
            let (dx, dy) = [(1, 0), (0, 1), (-1, 0), (0, -1)][dir as usize];
            x += dx;
            y += dy;
        }
        cells.push((x, y, dir));
    }
    let truth: Vec<Pose2> = cells
        .iter()
        .map(|&(x, y, d)| Pose2::new(x as f64, y as f64, f64::from(d) * std::f64::consts::FRAC_PI_2))
        .collect();
    let mut noisy = |z: Pose2| {
        Pose2::new(
            z.x + sigma_m * rng.gaussian(),
            z.y + sigma_m * rng.gaussian(),
            z.theta + sigma_rad * rng.gaussian(),
        )
    };
    let mut graph = PoseGraph::new(vec![Pose2::IDENTITY; n]);
    graph.edges.reserve(2 * n);
    let mut last_at: HashMap<(i64, i64), usize> = HashMap::with_capacity(n);
    for k in 0..n {
        if k > 0 {
            graph
                .edges
                .push(Edge::new(k - 1, k, noisy(truth[k - 1].between(&truth[k])), info));
        }
        let at = (cells[k].0, cells[k].1);
        if let Some(&j) = last_at.get(&at) {
            if j + 3 <= k {
                graph
                    .edges
                    .push(Edge::new(j, k, noisy(truth[j].between(&truth[k])), info));
            }
        }
        last_at.insert(at, k);
    }
    (graph, truth)
}

/// Adds `count` loop edges to `graph`, each measuring a relative pose drawn
/// at random (metres apart, any heading) between poses at least two apart,
/// with the information of its first edge: the wrong edges' indices.
#[cfg(test)]
pub(crate) fn add_wrong_loops(graph: &mut PoseGraph, count: usize, seed: u64) -> Vec<usize> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let n = graph.poses.len();
    let info = graph.edges[0].information;
    let mut wrong = Vec::new();
    for _ in 0..count {
        let i = rng.random_range(0..n - 2);
        let j = rng.random_range(i + 2..n);
        let z = Pose2::new(
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
            rng.random_range(-3.0..3.0),
        );
        wrong.push(graph.edges.len());
        graph.edges.push(Edge::new(i, j, z, info));
    }
    wrong
}

/// SplitMix64: a small, seeded, portable generator.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `(0, 1]`.
    fn uniform(&mut self) -> f64 {
        ((self.next() >> 11) + 1) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal (Box-Muller).
    fn gaussian(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grid_world_has_odometry_and_loops_on_revisits() {
        let (graph, truth) = grid_world(2000, 1e-9, 1e-9, 3);
        assert_eq!(graph.poses.len(), 2000);
        let odometry = graph.edges.iter().filter(|e| e.to == e.from + 1).count();
        assert_eq!(odometry, 1999);
        assert!(graph.edges.len() > 2400, "{} edges", graph.edges.len());
        // Almost noise-free: every edge fits the truth to its noise.
        for e in &graph.edges {
            let r = e.residual(&truth[e.from], &truth[e.to]);
            assert!(r.iter().all(|v| v.abs() < 1e-7), "{r:?}");
        }
    }
}
