//! Starting poses for a graph from its edges alone.
//!
//! - [`chain`]: odometry chaining: each pose reached from the held one
//!   by the edges, `i → i + 1` first (breadth first over the rest).
//! - [`chordal`]: rotations first, by the chordal relaxation (each heading
//!   a free 2-vector, `rⱼ = R(θ_z) rᵢ` solved by linear least squares and
//!   normalised), then positions by linear least squares with those
//!   rotations: no error accumulated along a long chain, so a local solver
//!   started there finds the basin that odometry misses.

use crate::sparse::BlockSystem;
use crate::{GraphError, PoseGraph};
use faer::Mat;
use pirouette_geom::Pose2;

/// Sets every pose but the held one by composing measurements outward from
/// the held pose: first along `i → i + 1` edges, then through any edge that
/// reaches a pose not yet set (breadth first, in edge order).
pub fn chain(graph: &mut PoseGraph) -> Result<(), GraphError> {
    graph.check()?;
    let n = graph.poses.len();
    let mut set = vec![false; n];
    set[graph.held] = true;
    // Odometry first: i → i + 1, forwards and backwards from the held pose.
    let mut next: Vec<Option<usize>> = vec![None; n];
    for (k, e) in graph.edges.iter().enumerate() {
        if e.to == e.from + 1 && next[e.from].is_none() {
            next[e.from] = Some(k);
        }
    }
    for i in graph.held..n.saturating_sub(1) {
        match next[i] {
            Some(k) if set[i] && !set[i + 1] => {
                graph.poses[i + 1] = graph.poses[i] * graph.edges[k].measurement;
                set[i + 1] = true;
            }
            _ => {}
        }
    }
    for i in (0..graph.held).rev() {
        if let Some(k) = next[i] {
            if set[i + 1] && !set[i] {
                graph.poses[i] = graph.poses[i + 1] * graph.edges[k].measurement.inverse();
                set[i] = true;
            }
        }
    }
    // The rest through any edge, until nothing changes.
    loop {
        let mut changed = false;
        for e in &graph.edges {
            if set[e.from] && !set[e.to] {
                graph.poses[e.to] = graph.poses[e.from] * e.measurement;
                set[e.to] = true;
                changed = true;
            } else if set[e.to] && !set[e.from] {
                graph.poses[e.from] = graph.poses[e.to] * e.measurement.inverse();
                set[e.from] = true;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    match set.iter().position(|s| !s) {
        Some(pose) => Err(GraphError::Disconnected {
            pose,
            held: graph.held,
        }),
        None => Ok(()),
    }
}

/// Sets every pose but the held one from the edges by the chordal
/// relaxation: headings first, each edge weighted by its heading
/// information, then positions with those headings, each edge weighted by
/// its translation information turned into the world frame.
pub fn chordal(graph: &mut PoseGraph) -> Result<(), GraphError> {
    graph.check()?;
    let n = graph.poses.len();
    let held = graph.held;
    let unknown: Vec<Option<usize>> = (0..n)
        .map(|p| match p.cmp(&held) {
            std::cmp::Ordering::Less => Some(p),
            std::cmp::Ordering::Equal => None,
            std::cmp::Ordering::Greater => Some(p - 1),
        })
        .collect();
    let pairs: Vec<(usize, usize)> = graph
        .edges
        .iter()
        .filter_map(|e| Some((unknown[e.from]?, unknown[e.to]?)))
        .collect();
    // Headings first, then positions with them.
    let theta = chordal_headings(graph, &unknown, &pairs)?;
    let t = chordal_positions(graph, &unknown, &pairs, &theta)?;
    for p in 0..n {
        if let Some(u) = unknown[p] {
            graph.poses[p] = Pose2::new(t[2 * u], t[2 * u + 1], theta[p]);
        }
    }
    Ok(())
}

/// Every pose's heading by the chordal relaxation: for each edge,
/// rⱼ − R(θ_z) rᵢ = 0 with r = (cos θ, sin θ), weight w = the heading
/// information; the held pose's r is known (`unknown`: each pose's
/// unknown's index, `None` for the held one; `pairs`: the edges'
/// unknowns).
fn chordal_headings(
    graph: &PoseGraph,
    unknown: &[Option<usize>],
    pairs: &[(usize, usize)],
) -> Result<Vec<f64>, GraphError> {
    let n = graph.poses.len();
    let known = |p: usize| -> [f64; 2] {
        let (s, c) = graph.poses[p].theta.sin_cos();
        [c, s]
    };
    let mut system = BlockSystem::<2>::new(n - 1, pairs.iter().copied())?;
    let mut rhs = vec![0.0; 2 * (n - 1)];
    for e in &graph.edges {
        let w = e.information[2][2];
        let (s, c) = e.measurement.theta.sin_cos();
        // Residual rⱼ − A rᵢ, A = R(θ_z): Jacobians I (for j) and −A (for
        // i).
        let ident = [[1.0, 0.0], [0.0, 1.0]];
        let neg_a = [[-c, s], [-s, -c]];
        let known_i = known_term(unknown, e.from, &neg_a, &known);
        let known_j = known_term(unknown, e.to, &ident, &known);
        accumulate(
            &mut system,
            &mut rhs,
            unknown,
            (e.from, neg_a),
            (e.to, ident),
            w,
            [0.0, 0.0],
            &known_i,
            &known_j,
        );
    }
    let r = solve2(&system, rhs)?;
    Ok((0..n)
        .map(|p| match unknown[p] {
            None => graph.poses[p].theta,
            Some(u) => r[2 * u + 1].atan2(r[2 * u]),
        })
        .collect())
}

/// Every unknown pose's position (x, y interleaved, by unknown) by the
/// chordal relaxation with the headings `theta`: tⱼ − tᵢ = R(θᵢ) t_z,
/// weighted by R(θᵢ) Ω_t R(θᵢ)ᵀ.
fn chordal_positions(
    graph: &PoseGraph,
    unknown: &[Option<usize>],
    pairs: &[(usize, usize)],
    theta: &[f64],
) -> Result<Vec<f64>, GraphError> {
    let n = graph.poses.len();
    let mut system = BlockSystem::<2>::new(n - 1, pairs.iter().copied())?;
    let mut rhs = vec![0.0; 2 * (n - 1)];
    let known_t = |p: usize| [graph.poses[p].x, graph.poses[p].y];
    for e in &graph.edges {
        let (s, c) = theta[e.from].sin_cos();
        let z = e.measurement.translation().rotated(theta[e.from]);
        let z = [z.x, z.y];
        let o = e.information;
        let rot = [[c, -s], [s, c]];
        // W = R Ω_t Rᵀ.
        let mut w = [[0.0; 2]; 2];
        for a in 0..2 {
            for b in 0..2 {
                w[a][b] = (0..2)
                    .map(|k| (0..2).map(|m| rot[a][k] * o[k][m] * rot[b][m]).sum::<f64>())
                    .sum();
            }
        }
        let ident = [[1.0, 0.0], [0.0, 1.0]];
        let neg = [[-1.0, 0.0], [0.0, -1.0]];
        accumulate_weighted(
            &mut system,
            &mut rhs,
            unknown,
            (e.from, neg),
            (e.to, ident),
            &w,
            z,
            &known_term(unknown, e.from, &neg, &known_t),
            &known_term(unknown, e.to, &ident, &known_t),
        );
    }
    solve2(&system, rhs)
}

/// `J x` for a held pose (whose value is known), zero for an unknown one.
fn known_term(
    unknown: &[Option<usize>],
    p: usize,
    j: &[[f64; 2]; 2],
    value: &impl Fn(usize) -> [f64; 2],
) -> [f64; 2] {
    if unknown[p].is_some() {
        return [0.0, 0.0];
    }
    let v = value(p);
    [j[0][0] * v[0] + j[0][1] * v[1], j[1][0] * v[0] + j[1][1] * v[1]]
}

/// Adds one linear residual `Jᵢ xᵢ + Jⱼ xⱼ − target` with scalar weight `w`
/// to the normal equations (held poses moved to the right-hand side).
#[allow(clippy::too_many_arguments)]
fn accumulate(
    system: &mut BlockSystem<2>,
    rhs: &mut [f64],
    unknown: &[Option<usize>],
    i: (usize, [[f64; 2]; 2]),
    j: (usize, [[f64; 2]; 2]),
    w: f64,
    target: [f64; 2],
    known_i: &[f64; 2],
    known_j: &[f64; 2],
) {
    let weight = [[w, 0.0], [0.0, w]];
    accumulate_weighted(system, rhs, unknown, i, j, &weight, target, known_i, known_j);
}

/// [`accumulate`] with a 2 × 2 weight matrix.
#[allow(clippy::too_many_arguments)]
fn accumulate_weighted(
    system: &mut BlockSystem<2>,
    rhs: &mut [f64],
    unknown: &[Option<usize>],
    i: (usize, [[f64; 2]; 2]),
    j: (usize, [[f64; 2]; 2]),
    w: &[[f64; 2]; 2],
    target: [f64; 2],
    known_i: &[f64; 2],
    known_j: &[f64; 2],
) {
    // The residual's constant part: what the held poses contribute, less
    // the target.
    let c = [
        known_i[0] + known_j[0] - target[0],
        known_i[1] + known_j[1] - target[1],
    ];
    let jt_w = |m: &[[f64; 2]; 2]| {
        let mut out = [[0.0; 2]; 2];
        for a in 0..2 {
            for b in 0..2 {
                out[a][b] = (0..2).map(|k| m[k][a] * w[k][b]).sum();
            }
        }
        out
    };
    let times = |a: &[[f64; 2]; 2], b: &[[f64; 2]; 2]| {
        let mut out = [[0.0; 2]; 2];
        for r in 0..2 {
            for k in 0..2 {
                out[r][k] = (0..2).map(|m| a[r][m] * b[m][k]).sum();
            }
        }
        out
    };
    let (ui, uj) = (unknown[i.0], unknown[j.0]);
    let (wi, wj) = (jt_w(&i.1), jt_w(&j.1));
    for (u, jw, jac) in [(ui, &wi, &i.1), (uj, &wj, &j.1)] {
        let Some(u) = u else { continue };
        if let Some(at) = system.at(u, u) {
            system.add(at, (u, u), &times(jw, jac));
        }
        for r in 0..2 {
            rhs[2 * u + r] -= jw[r][0] * c[0] + jw[r][1] * c[1];
        }
    }
    if let (Some(a), Some(b)) = (ui, uj) {
        if let Some(at) = system.at(a, b) {
            system.add(at, (a, b), &times(&wi, &j.1));
        }
    }
}

/// Solves a [`BlockSystem`] for one right-hand side.
fn solve2(system: &BlockSystem<2>, rhs: Vec<f64>) -> Result<Vec<f64>, GraphError> {
    let n = rhs.len();
    let mut x = Mat::from_fn(n, 1, |i, _| rhs[i]);
    if n > 0 {
        system.factor()?.solve(&mut x);
    }
    Ok((0..n).map(|i| x[(i, 0)]).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Edge;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn info() -> [[f64; 3]; 3] {
        [[50.0, 5.0, 0.0], [5.0, 80.0, 0.0], [0.0, 0.0, 300.0]]
    }

    /// Exact measurements: both initialisations give back the true poses.
    #[test]
    fn exact_measurements_give_back_the_poses() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let truth: Vec<Pose2> = (0..30)
            .map(|k| {
                if k == 0 {
                    Pose2::IDENTITY
                } else {
                    Pose2::new(
                        rng.random_range(-4.0..4.0),
                        rng.random_range(-4.0..4.0),
                        rng.random_range(-3.1..3.1),
                    )
                }
            })
            .collect();
        let mut graph = PoseGraph::new(vec![Pose2::IDENTITY; 30]);
        for i in 0..29 {
            graph
                .edges
                .push(Edge::new(i, i + 1, truth[i].between(&truth[i + 1]), info()));
        }
        for i in (0..25).step_by(3) {
            graph
                .edges
                .push(Edge::new(i + 5, i, truth[i + 5].between(&truth[i]), info()));
        }
        for init in [chain, chordal] {
            let mut g = graph.clone();
            init(&mut g).unwrap();
            for (p, t) in g.poses.iter().zip(&truth) {
                assert!(
                    (p.x - t.x).abs() < 1e-9 && (p.y - t.y).abs() < 1e-9,
                    "{p:?} {t:?}"
                );
                assert!(pirouette_geom::wrap_angle(p.theta - t.theta).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn a_pose_out_of_reach_is_found_before_any_solve() {
        let mut graph = PoseGraph::new(vec![Pose2::IDENTITY; 5]);
        for (a, b) in [(0, 1), (2, 3), (3, 4)] {
            graph
                .edges
                .push(Edge::new(a, b, Pose2::new(1.0, 0.0, 0.0), info()));
        }
        assert_eq!(graph.unreached(), Some(2));
        graph.held = 3;
        assert_eq!(graph.unreached(), Some(0));
        graph
            .edges
            .push(Edge::new(4, 1, Pose2::new(1.0, 0.0, 0.0), info()));
        assert_eq!(graph.unreached(), None);
    }

    #[test]
    fn a_pose_out_of_reach_is_reported() {
        let mut graph = PoseGraph::new(vec![Pose2::IDENTITY; 4]);
        graph
            .edges
            .push(Edge::new(0, 1, Pose2::new(1.0, 0.0, 0.0), info()));
        graph
            .edges
            .push(Edge::new(2, 3, Pose2::new(1.0, 0.0, 0.0), info()));
        assert_eq!(
            chain(&mut graph),
            Err(GraphError::Disconnected { pose: 2, held: 0 })
        );
    }

    /// A long loop with a small heading bias per step: chaining drifts,
    /// the chordal rotations spread the loop's error.
    #[test]
    fn chordal_rotations_do_not_drift_round_a_loop() {
        let n = 200;
        let step = std::f64::consts::TAU / n as f64;
        let truth: Vec<Pose2> = (0..n)
            .map(|k| {
                Pose2::new(0.0, 0.0, 0.0)
                    * Pose2::new(
                        (k as f64 * step).sin() * 10.0,
                        10.0 - (k as f64 * step).cos() * 10.0,
                        k as f64 * step,
                    )
            })
            .collect();
        let mut graph = PoseGraph::new(vec![Pose2::IDENTITY; n]);
        for i in 0..n {
            let j = (i + 1) % n;
            let mut z = truth[i].between(&truth[j]);
            z.theta += 0.01;
            graph.edges.push(Edge::new(i, j, z, info()));
        }
        let heading_error = |g: &PoseGraph| {
            g.poses
                .iter()
                .zip(&truth)
                .map(|(p, t)| pirouette_geom::wrap_angle(p.theta - t.theta).abs())
                .fold(0.0, f64::max)
        };
        let mut chained = graph.clone();
        chain(&mut chained).unwrap();
        let mut relaxed = graph.clone();
        chordal(&mut relaxed).unwrap();
        assert!(heading_error(&chained) > 1.5, "{}", heading_error(&chained));
        assert!(
            heading_error(&relaxed) < 0.1 * heading_error(&chained),
            "{}",
            heading_error(&relaxed)
        );
    }
}
