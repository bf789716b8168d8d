//! The headings of a sweep's frames: a chain of the turns as the sweep
//! measured them, anchored by each frame's own registration.

use super::placed::Placed;
use super::MapConfig;
use crate::error::Result;
use crate::frame::DatasetSweep;
use crate::frame::Frame;
use pirouette_geom::Point2;
use pirouette_register::{register, LikelihoodField, PosePrior};
use rayon::prelude::*;

/// The weak pull of each heading to its current value in the chain solve
/// (only keeps the system well posed).
const CHAIN_WEAK_RAD: f64 = 10.0 * std::f64::consts::PI / 180.0;

/// How far a frame may lie from where turning about the robot's pivot puts
/// it, metres (one standard deviation).
const TURN_SHIFT_M: f64 = 0.002;

/// Solves the headings of a sweep's frames (each turned about the robot's
/// pivot) from the turns between them and what the map says of each frame
/// alone: a chain of relative headings as the sweep measured them
/// (verified links to a match's accuracy, fallback turns to a command's),
/// anchored where a frame's own registration (a turn about the pivot,
/// searched within one command's error) pins its heading to better than
/// half that. Every heading also keeps a weak pull (10°) to its current
/// value, so a frame without anchors or links stays. Linear least squares
/// ([`solve_chain`]); anchors more than three standard deviations from the
/// solution are dropped and it is solved again.
pub(super) fn chain_headings<'f>(
    placed: &mut Placed,
    sweep: &DatasetSweep,
    input: &[Frame],
    field: impl Fn(usize) -> &'f LikelihoodField + Sync,
    config: &MapConfig,
) -> Result<()> {
    let n = sweep.frames.len();
    let cur = placed.heading_rad.clone();
    let sigma_cmd = config.sweep.commanded_sigma_rad;
    let sigma_ver = config.sweep.verified_sigma_rad;
    // A frame's own registration searches as far as one command errs: the
    // command of the turn into it where no verified link reaches it, a
    // pirouette's turn's otherwise.
    let measured = &sweep.sweep.heading_rad;
    let reached = |k: usize| sweep.sweep.links.iter().any(|&(_, b)| b == k);
    let anchor_window = |k: usize| {
        if k == 0 || reached(k) {
            sigma_cmd
        } else {
            config.command_sigma(measured[k] - measured[k - 1])
        }
    };
    // Each frame's registration is independent of the others': in parallel,
    // collected in frame order.
    let placed_now: &Placed = placed;
    let anchor_of = |k: usize| -> Result<Option<(usize, f64, f64)>> {
        let heading = cur[k];
        let to_frame = placed_now.rel(k).inverse();
        let pts: Vec<Point2> = placed_now
            .points(sweep, &[k], input, config)
            .into_iter()
            .map(|p| to_frame.transform_point(p))
            .collect();
        let prior = PosePrior {
            mean: placed_now.frame_pose(k),
            sigma_forward_m: TURN_SHIFT_M,
            sigma_left_m: TURN_SHIFT_M,
            sigma_theta_rad: anchor_window(k),
        };
        let reg = register(field(k), &pts, &prior, &config.turn)?;
        let sd = reg.covariance[(2, 2)].sqrt().max(sigma_ver);
        Ok((reg.accepted && sd < anchor_window(k) / 2.0).then(|| {
            (
                k,
                heading + pirouette_geom::wrap_angle(reg.pose.theta - prior.mean.theta),
                sd,
            )
        }))
    };
    let anchors: Vec<(usize, f64, f64)> = (0..n)
        .into_par_iter()
        .map(anchor_of)
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .flatten()
        .collect();
    let links = chain_links(measured, &sweep.sweep.links, sigma_ver, |turn| {
        config.command_sigma(turn)
    });
    if let Some(x) = solve_chain(&cur, &links, anchors) {
        placed.heading_rad = x;
    }
    Ok(())
}

/// The links of a sweep's heading chain, `(i, j, heading j − heading i,
/// σ)`: its verified links (`links`) to `sigma_ver`, and every frame no
/// verified link reaches joined to the one before it by its fallback turn,
/// to `sigma_cmd` of that turn's angle. The differences are those of
/// `measured`, the headings as the sweep measured them, never of a later
/// solution: solved again and again from the last solution's differences,
/// the links would give way a little to the anchors each time, and one
/// wrong anchor would end up bending verified turns by degrees.
pub(super) fn chain_links(
    measured: &[f64],
    links: &[(usize, usize)],
    sigma_ver: f64,
    sigma_cmd: impl Fn(f64) -> f64,
) -> Vec<(usize, usize, f64, f64)> {
    let mut out: Vec<(usize, usize, f64, f64)> = links
        .iter()
        .map(|&(a, b)| (a, b, measured[b] - measured[a], sigma_ver))
        .collect();
    for k in 1..measured.len() {
        if !links.iter().any(|&(_, b)| b == k) {
            let turn = measured[k] - measured[k - 1];
            out.push((k - 1, k, turn, sigma_cmd(turn)));
        }
    }
    out
}

/// The headings that agree best with the chain's `links` (see
/// [`chain_links`]) and the `anchors` (`(frame, heading, σ)`), each heading
/// also pulled weakly ([`CHAIN_WEAK_RAD`]) to `cur`: linear least squares,
/// solved again without the anchors more than three standard deviations
/// from the solution. `None` when the system cannot be solved.
pub(super) fn solve_chain(
    cur: &[f64],
    links: &[(usize, usize, f64, f64)],
    mut anchors: Vec<(usize, f64, f64)>,
) -> Option<Vec<f64>> {
    let n = cur.len();
    let weak = CHAIN_WEAK_RAD;
    let mut solution = None;
    for _round in 0..2 {
        let mut a = nalgebra::DMatrix::<f64>::zeros(n, n);
        let mut b = nalgebra::DVector::<f64>::zeros(n);
        for k in 0..n {
            a[(k, k)] += 1.0 / (weak * weak);
            b[k] += cur[k] / (weak * weak);
        }
        for &(i, j, d, s) in links {
            let w = 1.0 / (s * s);
            a[(i, i)] += w;
            a[(j, j)] += w;
            a[(i, j)] -= w;
            a[(j, i)] -= w;
            b[i] -= w * d;
            b[j] += w * d;
        }
        for &(k, v, s) in &anchors {
            let w = 1.0 / (s * s);
            a[(k, k)] += w;
            b[k] += w * v;
        }
        let Some(chol) = a.cholesky() else { break };
        let x = chol.solve(&b);
        let before = anchors.len();
        anchors.retain(|&(k, v, s)| (x[k] - v).abs() <= 3.0 * s);
        solution = Some(x.iter().copied().collect());
        if anchors.len() == before {
            break;
        }
    }
    solution
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fallback turn's link is as loose as its command errs: 3° for a
    /// pirouette's 30° turn, a tenth of the angle for the wide turn toward
    /// the next spot; verified links keep a match's accuracy.
    #[test]
    fn wide_fallback_turns_get_links_as_loose_as_their_commands() {
        let config = MapConfig::default();
        let deg = |d: f64| d.to_radians();
        let measured = [0.0, deg(30.0), deg(60.0), deg(238.0)];
        let links = chain_links(&measured, &[(0, 1)], deg(0.5), |t| config.command_sigma(t));
        let sigma_into = |k: usize| {
            let l: Vec<_> = links.iter().filter(|l| l.1 == k).collect();
            assert_eq!(l.len(), 1, "one link into frame {k}");
            l[0].3.to_degrees()
        };
        assert!((sigma_into(1) - 0.5).abs() < 1e-9, "verified");
        assert!((sigma_into(2) - 3.0).abs() < 1e-9, "a 30° command");
        assert!((sigma_into(3) - 17.8).abs() < 1e-9, "a 178° command");
    }

    /// The mapping solves a sweep's headings again and again as its
    /// registration improves. Every solve weighs the turns as the sweep
    /// measured them, so the verified turns bend no further than one solve
    /// bends them, however many follow, even toward an anchor that is off
    /// and never dropped.
    #[test]
    fn repeated_chain_solves_keep_the_measured_turns() {
        let deg = |d: f64| d.to_radians();
        let measured: Vec<f64> = (0..6).map(|k| deg(30.0 * k as f64)).collect();
        let links: Vec<(usize, usize)> = (1..6).map(|k| (k - 1, k)).collect();
        let (ver, cmd) = (deg(0.5), deg(3.0));
        // Frame 0's own registration is 1.2° off, with a σ that keeps it
        // inside the three-σ gate; the others agree with the turns.
        let anchors: Vec<(usize, f64, f64)> = std::iter::once((0, measured[0] + deg(1.2), deg(0.5)))
            .chain((1..6).map(|k| (k, measured[k], deg(1.0))))
            .collect();
        let bend = |x: &[f64]| {
            links
                .iter()
                .map(|&(i, j)| ((x[j] - x[i]) - (measured[j] - measured[i])).abs())
                .fold(0.0, f64::max)
        };
        let chain = chain_links(&measured, &links, ver, |_| cmd);
        let once = solve_chain(&measured, &chain, anchors.clone()).unwrap();
        let mut cur = once.clone();
        for _ in 0..10 {
            cur = solve_chain(
                &cur,
                &chain_links(&measured, &links, ver, |_| cmd),
                anchors.clone(),
            )
            .unwrap();
        }
        assert!(bend(&once) > deg(0.05), "the anchor bends the chain at all");
        assert!(
            bend(&cur) <= bend(&once) + deg(0.01),
            "bent {:.3}° after one solve, {:.3}° after eleven",
            bend(&once).to_degrees(),
            bend(&cur).to_degrees()
        );
        // Each solve's differences taken as the next one's turns would have
        // given way to the anchor further at every solve.
        let mut drifting = once.clone();
        for _ in 0..10 {
            drifting = solve_chain(
                &drifting,
                &chain_links(&drifting, &links, ver, |_| cmd),
                anchors.clone(),
            )
            .unwrap();
        }
        assert!(bend(&drifting) > 2.0 * bend(&once));
    }
}
