//! The joint adjustment of a map's sweeps: every two sweeps within reach
//! of each other matched (and the revisits the place index recognises),
//! the forward moves between them, and the sweeps moved together, each a
//! rigid whole, to agree with all of it.

use super::build::{last_frame, motion_prior, refine_pass};
use super::fields::{field_in, seen_by};
use super::placed::{far_reach_m, Placed};
use super::{revisits, MapConfig};
use crate::backend::edge::{information, Edge};
use crate::backend::solve::{Graph, Role};
use crate::error::Result;
use crate::frame::DatasetSweep;
use crate::frame::Frame;
use pirouette_geom::{Point2, Pose2};
use pirouette_graph::{OptimiseConfig, Solver};
use pirouette_register::{may_accept, register, LikelihoodField, PosePrior};
use rayon::prelude::*;

/// The sweeps adjusted jointly, each a rigid whole, to agree with every
/// pair's match (revisits the place index recognises among them) and the
/// forward moves, then each placed once more against the map of the
/// others: the revisits, with whether each became an edge the adjustment
/// kept.
pub(super) fn adjust_jointly(
    placed: &mut [Placed],
    input: &[Frame],
    sweeps: &[DatasetSweep],
    blind_m: f64,
    config: &MapConfig,
) -> Result<Vec<revisits::Revisit>> {
    let mut revisits = Vec::new();
    if let Some(c) = &config.revisits {
        revisits = revisits::recognise(sweeps, placed, c)?;
    }
    let (pairs, revisit_edges) = sweep_edges(placed, sweeps, input, blind_m, config, &mut revisits)?;
    let moves = motion_edges(placed, sweeps, input, config);
    let kept = adjust_sweeps(placed, moves, pairs);
    for (r, e) in revisits.iter_mut().zip(revisit_edges) {
        r.registered = e.is_some();
        r.kept = e.is_some_and(|e| kept[e]);
    }
    refine_pass(placed, sweeps, input, blind_m, config)?;
    Ok(revisits)
}

/// How far apart two sweeps are matched in the adjustment, at most
/// (metres, one standard deviation each way; their heading as far as one
/// commanded turn errs): the sweeps were already placed against each
/// other's maps, so the match looks near where they are.
const PAIR_SHIFT_M: f64 = 0.05;

/// Sweep `s`'s own map: the field of what it alone saw, its frames as
/// the heading chain placed them, in its frame.
fn own_field(
    s: usize,
    placed: &[Placed],
    sweeps: &[DatasetSweep],
    input: &[Frame],
    blind_m: f64,
    config: &MapConfig,
) -> Result<LikelihoodField> {
    let frames: Vec<(usize, Pose2)> = (0..sweeps[s].frames.len())
        .map(|k| (sweeps[s].frames[k], placed[s].rel(k)))
        .collect();
    Ok(field_in(&seen_by(&frames, input, blind_m, config)?, None, config))
}

/// The measured relative poses between every two sweeps within reach of
/// each other: each sweep (its frames as the heading chain placed them)
/// registered against what each other sweep alone saw, both ways. A
/// match's covariance includes its search prior, broad beside what the
/// match itself pins down.
fn sweep_edges(
    placed: &[Placed],
    sweeps: &[DatasetSweep],
    input: &[Frame],
    blind_m: f64,
    config: &MapConfig,
    revisits: &mut [revisits::Revisit],
) -> Result<(Vec<Edge>, Vec<Option<usize>>)> {
    // Each sweep's endpoints in its frame.
    let own_points: Vec<Vec<Point2>> = (0..sweeps.len())
        .into_par_iter()
        .map(|s| {
            placed[s].points(
                &sweeps[s],
                &(0..sweeps[s].frames.len()).collect::<Vec<_>>(),
                input,
                config,
            )
        })
        .collect();
    // Sweeps farther apart than twice the registration's reach see nothing
    // in common.
    let reach = |s: usize| {
        let rop = &input[sweeps[s].frames[0]].compared;
        far_reach_m(rop, config).max(rop.max_range_m as f64)
    };
    let near = |i: usize, j: usize| {
        let (a, b) = (placed[i].pose.translation(), placed[j].pose.translation());
        a.distance(b) <= reach(i) + reach(j)
    };
    // Every near pair from where the two were placed; a recognised revisit
    // out of reach from where the place index put it.
    let mut pairs: Vec<(usize, usize, Option<Pose2>)> = (0..sweeps.len())
        .flat_map(|i| {
            (0..sweeps.len())
                .filter(move |&j| j != i)
                .map(move |j| (i, j, None))
        })
        .filter(|&(i, j, _)| near(i, j))
        .collect();
    for r in revisits.iter_mut() {
        r.beyond_reach = !near(r.earlier, r.later);
        if r.beyond_reach {
            pairs.push((r.earlier, r.later, Some(r.relative)));
        }
    }
    // The pairs grouped by the sweep whose map the other is matched
    // against: that map is made for its pairs and dropped after them, a
    // few at a time (a long stream of frames has as many maps as frames).
    let mut by_map: Vec<Vec<usize>> = vec![Vec::new(); sweeps.len()];
    for (k, &(i, _, _)) in pairs.iter().enumerate() {
        by_map[i].push(k);
    }
    let mapped: Vec<usize> = (0..sweeps.len()).filter(|&i| !by_map[i].is_empty()).collect();
    let mut edges: Vec<Option<Edge>> = vec![None; pairs.len()];
    for chunk in mapped.chunks(rayon::current_num_threads().max(1)) {
        let fields: Vec<LikelihoodField> = chunk
            .par_iter()
            .map(|&i| own_field(i, placed, sweeps, input, blind_m, config))
            .collect::<Result<_>>()?;
        let ks: Vec<(usize, &LikelihoodField)> = chunk
            .iter()
            .zip(&fields)
            .flat_map(|(&i, f)| by_map[i].iter().map(move |&k| (k, f)))
            .collect();
        let found = ks
            .par_iter()
            .map(|&(k, field)| pair_edge(pairs[k], field, &own_points, placed, config))
            .collect::<Result<Vec<_>>>()?;
        for (&(k, _), e) in ks.iter().zip(found) {
            edges[k] = e;
        }
    }
    // Where each revisit's pair ended up among the edges kept.
    let mut at = Vec::with_capacity(edges.len());
    let mut kept_edges = Vec::new();
    for e in edges {
        at.push(e.map(|_| kept_edges.len()));
        kept_edges.extend(e);
    }
    let revisit_edges = revisits
        .iter()
        .map(|r| {
            let (i, j) = (r.earlier, r.later);
            let k = pairs
                .iter()
                .position(|&(a, b, z)| a == i && b == j && z.is_some() == r.beyond_reach)?;
            at[k]
        })
        .collect();
    Ok((kept_edges, revisit_edges))
}

/// The edge of one pair `(i, j, recognised)` of [`sweep_edges`]: sweep
/// `j`'s endpoints registered against `field`, what sweep `i` alone saw,
/// from where the two were placed or, for a recognised revisit out of
/// reach, from where the place index put it. `None` where the match is
/// not trusted.
fn pair_edge(
    (i, j, recognised): (usize, usize, Option<Pose2>),
    field: &LikelihoodField,
    own_points: &[Vec<Point2>],
    placed: &[Placed],
    config: &MapConfig,
) -> Result<Option<Edge>> {
    let (mean, shift) = match recognised {
        Some(z) => (z, REVISIT_SHIFT_M),
        None => (placed[i].pose.between(&placed[j].pose), PAIR_SHIFT_M),
    };
    let prior = PosePrior {
        mean,
        sigma_forward_m: shift,
        sigma_left_m: shift,
        sigma_theta_rad: config.sweep.commanded_sigma_rad,
    };
    let points = &own_points[j];
    // A revisit out of reach is an edge only where it passes the test of
    // a true revisit; a pair within reach where its match is trusted.
    let reg = match recognised {
        Some(_) => config.revisit.register(
            field,
            points,
            &prior,
            config.register.max_window_m,
            &config.register,
        )?,
        // Views that share nothing are not matched.
        None if !may_accept(field, points, &prior, &config.register)? => None,
        None => Some(register(field, points, &prior, &config.register)?).filter(|r| r.accepted),
    };
    Ok(reg.map(|reg| Edge {
        i,
        j,
        z: reg.pose,
        info: information(&reg.covariance),
    }))
}

/// How far from where the place index puts a revisit its pair is
/// matched, one standard deviation (metres): the index's registration is
/// good to a few centimetres.
const REVISIT_SHIFT_M: f64 = 0.15;

/// The forward moves between consecutive sweeps as edges: where the
/// previous sweep's last frame and the move put the next sweep's first
/// frame.
fn motion_edges(
    placed: &[Placed],
    sweeps: &[DatasetSweep],
    input: &[Frame],
    config: &MapConfig,
) -> Vec<Edge> {
    (1..sweeps.len())
        .map(|s| {
            let prev = &placed[s - 1];
            let (last, fallback_var) = last_frame(&sweeps[s - 1], prev, config);
            let start_sigma = (config.sweep.verified_sigma_rad.powi(2) + fallback_var).sqrt();
            let motion = input[sweeps[s].frames[0]].motion;
            let prior = motion_prior(&prev.rel(last), start_sigma, motion, config);
            Edge {
                i: s - 1,
                j: s,
                z: prior.mean * placed[s].rel(0).inverse(),
                info: information(&prior.covariance()),
            }
        })
        .collect()
}

/// Moves the sweeps (each a rigid whole) to agree best with every measured
/// relative pose at once: the moves between consecutive sweeps the
/// graph's chain, the pairs' matches its loops ([`Graph::solve`]: checked
/// against each other first, those the solution contradicts dropped).
/// Placing sweeps one at a time against the map of the others cannot turn
/// a group of sweeps that agree with each other together; a joint solve
/// can. Returns, per pair, whether the solve used it.
fn adjust_sweeps(placed: &mut [Placed], moves: Vec<Edge>, pairs: Vec<Edge>) -> Vec<bool> {
    if placed.len() < 2 {
        return vec![true; pairs.len()];
    }
    let mut graph = Graph::new(placed.iter().map(|p| p.pose).collect());
    for e in moves {
        graph.push(e.to_graph(), Role::GatedChain);
    }
    let first = graph.edges();
    for e in pairs {
        graph.push(e.to_graph(), Role::Loop);
    }
    let config = OptimiseConfig {
        solver: Solver::GaussNewton,
        max_iterations: GRAPH_ITERATIONS,
        relative_decrease: 1e-12,
        ..OptimiseConfig::default()
    };
    graph.solve(&config);
    for (p, pose) in placed.iter_mut().zip(graph.poses()) {
        p.pose = *pose;
    }
    (first..graph.edges()).map(|k| graph.kept(k)).collect()
}

/// Gauss-Newton iterations of the joint adjustment, at most.
const GRAPH_ITERATIONS: usize = 10;
