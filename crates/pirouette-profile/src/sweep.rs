//! Radial sweeps: the profiles of one pirouette joined into 360°.

use crate::matching::{match_turn, Evidence, MatchConfig, TurnEstimate};
use crate::{ColourTag, Rop};
use std::f64::consts::{PI, TAU};

/// Settings of sweep assembly.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepConfig {
    /// Rotation matching.
    pub matching: MatchConfig,
    /// Close the loop when the last view overlaps the first.
    pub close_loop: bool,
    /// Standard deviation of a verified turn, radians (weights the loop
    /// residual's share).
    pub verified_sigma_rad: f64,
    /// Standard deviation of a commanded turn, radians (fallback turns).
    pub commanded_sigma_rad: f64,
    /// The largest loop residual that is spread over the turns, in standard
    /// deviations of the loop; a larger one means a wrong match and is
    /// left as measured.
    pub max_residual_sigmas: f64,
}

impl Default for SweepConfig {
    /// Verified turns to 0.5° (a Gaussian whose 95th percentile is 1°, the
    /// most a verified turn may err 95 times in 100; measured over the
    /// shared sets and renders: a median of 0.10° and a 95th percentile of
    /// 0.40°, but tails out to 1.5°, which a narrower Gaussian would trust
    /// too far), commanded ones to 3° (the paper's robot); loops closed;
    /// residuals beyond 3 standard deviations left alone.
    fn default() -> Self {
        Self {
            matching: MatchConfig::default(),
            close_loop: true,
            verified_sigma_rad: 0.5f64.to_radians(),
            commanded_sigma_rad: 3f64.to_radians(),
            max_residual_sigmas: 3.0,
        }
    }
}

/// The loop closure of a pirouette.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopClosure {
    /// The frame whose view was matched against the first.
    pub frame: usize,
    /// The closing match (from that frame back round to the first).
    pub closing: TurnEstimate,
    /// Sum of the turns round the loop minus 360°, radians, before spreading.
    pub residual_rad: f64,
    /// Whether the residual was spread over the turns.
    pub applied: bool,
}

/// One pirouette, assembled.
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    /// Per frame: the verified turn since the previous frame (`None` for
    /// the first), after loop closure.
    pub turns: Vec<Option<TurnEstimate>>,
    /// Per frame: heading relative to the first frame, radians.
    pub heading_rad: Vec<f64>,
    /// The loop closure, when the pirouette came round.
    pub closure: Option<LoopClosure>,
    /// The 360° radial sweep in the first frame's robot frame.
    pub rop: Rop,
    /// Pairs of frames `(a, b)`, `a < b`, whose relative heading a verified
    /// match measured: consecutive frames joined by a verified turn, the
    /// loop closure, and frames after the loop matched against an earlier
    /// one. Sorted.
    pub links: Vec<(usize, usize)>,
}

/// Joins the profiles of one pirouette. `commanded_rad[k]` is the commanded
/// turn before frame `k` (`None` for the first frame). All profiles share
/// one bin width.
pub fn assemble(rops: &[Rop], commanded_rad: &[Option<f64>], config: &SweepConfig) -> Sweep {
    assert_eq!(rops.len(), commanded_rad.len(), "one command per profile");
    let mut turns: Vec<Option<TurnEstimate>> = (0..rops.len())
        .map(|k| commanded_rad[k].map(|cmd| match_turn(&rops[k - 1], &rops[k], cmd, &config.matching)))
        .collect();
    let closure = if config.close_loop {
        close_loop(rops, &mut turns, config)
    } else {
        None
    };
    let mut links: Vec<(usize, usize)> = Vec::new();
    if let Some(c) = closure.filter(|c| c.applied) {
        links.push((0, c.frame));
        links.extend(rematch_after_loop(rops, &mut turns, c.frame + 1, config));
    }
    for (k, t) in turns.iter().enumerate().skip(1) {
        if t.is_some_and(|t| !t.fallback) && !links.iter().any(|&(_, b)| b == k) {
            links.push((k - 1, k));
        }
    }
    links.sort_unstable();
    let mut heading = 0.0;
    let heading_rad: Vec<f64> = turns
        .iter()
        .map(|t| {
            heading += t.map_or(0.0, |t| t.turn_rad);
            heading
        })
        .collect();
    let rop = join(rops, &heading_rad);
    Sweep {
        turns,
        heading_rad,
        closure,
        rop,
        links,
    }
}

fn close_loop(rops: &[Rop], turns: &mut [Option<TurnEstimate>], config: &SweepConfig) -> Option<LoopClosure> {
    let first = rops.first()?;
    let view = first.len() as f64 * first.bin_width_rad;
    let max_closing = view - config.matching.min_overlap_rad;
    let var = |t: &TurnEstimate| {
        if t.fallback {
            config.commanded_sigma_rad.powi(2)
        } else {
            config.verified_sigma_rad.powi(2)
        }
    };
    // The frame nearest to coming round: estimated heading closest to 360°
    // with the closing turn inside the view.
    let mut cumulative = 0.0;
    let mut cumulative_var = 0.0;
    let mut candidate: Option<(usize, f64, f64)> = None;
    for (k, t) in turns.iter().enumerate().skip(1) {
        let t = (*t)?;
        cumulative += t.turn_rad;
        cumulative_var += var(&t);
        let closing = TAU - cumulative;
        if closing.abs() <= max_closing && candidate.is_none_or(|(_, c, _)| closing.abs() < c.abs()) {
            candidate = Some((k, closing, cumulative_var));
        }
    }
    let (k, closing_est, heading_var) = candidate?;
    // Search the closing turn as widely as the heading is uncertain.
    let closing_config = MatchConfig {
        window_rad: config.matching.window_rad + 3.0 * heading_var.sqrt(),
        ..config.matching.clone()
    };
    let closing = match_turn(&rops[k], first, closing_est, &closing_config);
    if closing.fallback {
        return Some(LoopClosure {
            frame: k,
            closing,
            residual_rad: f64::NAN,
            applied: false,
        });
    }
    let loop_turns = &mut turns[1..=k];
    let sum: f64 = loop_turns.iter().flatten().map(|t| t.turn_rad).sum::<f64>() + closing.turn_rad;
    let residual = sum - TAU;
    let total_var: f64 = loop_turns.iter().flatten().map(var).sum::<f64>() + var(&closing);
    let applied = residual.abs() <= config.max_residual_sigmas * total_var.sqrt();
    if applied {
        // Least squares under the loop constraint: each turn takes a share
        // of the residual in proportion to its variance, so fallback turns
        // take nearly all of it. They stay flagged: the sum of many
        // verified turns is not as sure as one match.
        for t in loop_turns.iter_mut().flatten() {
            t.turn_rad -= residual * var(t) / total_var;
        }
    }
    Some(LoopClosure {
        frame: k,
        closing,
        residual_rad: residual,
        applied,
    })
}

/// Frames after the loop (the turn towards the next spot may be wider than
/// the view) are matched against the frame of the sweep whose heading is
/// nearest to where they should look. Returns the links `(j, k)` of the re-matched frames.
fn rematch_after_loop(
    rops: &[Rop],
    turns: &mut [Option<TurnEstimate>],
    from: usize,
    config: &SweepConfig,
) -> Vec<(usize, usize)> {
    let mut links = Vec::new();
    let view = rops[0].len() as f64 * rops[0].bin_width_rad;
    let max_turn = view - config.matching.min_overlap_rad;
    for k in from..rops.len() {
        let Some(t) = turns[k] else { continue };
        // Only turns that had nothing to compare with their predecessor: an
        // ambiguous match stays a fallback.
        if !(t.fallback && t.evidence == Evidence::NoOverlap) {
            continue;
        }
        let heading: Vec<f64> = turns[..k]
            .iter()
            .scan(0.0, |h, t| {
                *h += t.map_or(0.0, |t| t.turn_rad);
                Some(*h)
            })
            .collect();
        let predicted = heading[k - 1] + t.turn_rad;
        // Frames joined to the previous one by verified turns only: their
        // relative heading is known to a match's accuracy.
        let chained = |j: usize| turns[j + 1..k].iter().all(|t| t.is_some_and(|t| !t.fallback));
        let nearest = (0..k)
            .filter(|&j| j + 1 != k && chained(j))
            .map(|j| (j, wrap(predicted - heading[j])))
            .filter(|(_, d)| d.abs() <= max_turn)
            .min_by(|a, b| a.1.abs().total_cmp(&b.1.abs()));
        let Some((j, relative)) = nearest else { continue };
        let m = match_turn(&rops[j], &rops[k], relative, &config.matching);
        if !m.fallback {
            // On the command's branch of the circle.
            let turn = t.turn_rad + wrap(heading[j] + m.turn_rad - heading[k - 1] - t.turn_rad);
            turns[k] = Some(TurnEstimate { turn_rad: turn, ..m });
            links.push((j, k));
        }
    }
    links
}

fn wrap(a: f64) -> f64 {
    let w = a.rem_euclid(TAU);
    if w > PI {
        w - TAU
    } else {
        w
    }
}

/// The 360° sweep: every profile's bins rotated by its frame's heading;
/// where several frames see a bin, the median range (and the colour of the
/// sample nearest it).
fn join(rops: &[Rop], heading_rad: &[f64]) -> Rop {
    let Some(first) = rops.first() else {
        return Rop::empty(-PI, TAU, 0, 1.0);
    };
    let w = first.bin_width_rad;
    let mut out = Rop::covering(-PI, PI - w, w, first.max_range_m).expect("valid bin width");
    let n = out.len();
    let mut samples: Vec<Vec<(f32, Option<ColourTag>)>> = vec![Vec::new(); n];
    for (rop, &h) in rops.iter().zip(heading_rad) {
        for i in 0..rop.len() {
            if !rop.seen(i) {
                continue;
            }
            let b = rop.bin_centre_rad(i) + h;
            // Wrap into [start, start + 2π).
            let wrapped = (b - out.bearing_start_rad).rem_euclid(TAU) + out.bearing_start_rad;
            if let Some(j) = out.bin_of(wrapped) {
                samples[j].push((rop.range_m[i], rop.colour[i]));
            }
        }
    }
    for (j, mut s) in samples.into_iter().enumerate() {
        if s.is_empty() {
            continue;
        }
        s.sort_by(|a, b| a.0.total_cmp(&b.0));
        let finite = s.iter().filter(|x| x.0.is_finite()).count();
        if finite == 0 {
            out.range_m[j] = f32::INFINITY;
            continue;
        }
        // Median of the finite ranges when most samples saw something,
        // otherwise "nothing in sight" wins the vote.
        if finite * 2 < s.len() {
            out.range_m[j] = f32::INFINITY;
            continue;
        }
        let (r, c) = s[finite / 2];
        out.range_m[j] = r;
        out.colour[j] = c;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(bearing: f64) -> f32 {
        let d = bearing.to_degrees().rem_euclid(360.0);
        // An obstacle every 45° (different widths and ranges), so every
        // 30° turn has an edge in its overlap.
        let k = (d / 45.0).floor();
        let local = d - k * 45.0;
        if local < 8.0 + k {
            0.3 + 0.05 * k as f32
        } else {
            f32::INFINITY
        }
    }

    fn view(heading: f64) -> Rop {
        let w = 0.25f64.to_radians();
        let mut rop = Rop::covering(-30f64.to_radians(), 30f64.to_radians(), w, 0.9).unwrap();
        for i in 0..rop.len() {
            rop.range_m[i] = (0..5)
                .map(|s| scene(heading + rop.bearing_start_rad + (i as f64 + (s as f64 + 0.5) / 5.0) * w))
                .fold(f32::INFINITY, f32::min);
        }
        rop
    }

    #[test]
    fn pirouette_closes_and_recovers_headings() {
        let true_turns_deg = [
            0.0, 31.5, 28.0, 33.0, 29.0, 27.5, 32.0, 30.5, 29.5, 31.0, 28.5, 30.0,
        ];
        let mut heading = 0.0;
        let (mut rops, mut cmds, mut truth) = (Vec::new(), Vec::new(), Vec::new());
        for (k, t) in true_turns_deg.iter().enumerate() {
            heading += f64::to_radians(*t);
            rops.push(view(heading));
            cmds.push((k > 0).then_some(30f64.to_radians()));
            truth.push(heading - true_turns_deg[0]);
        }
        let sweep = assemble(&rops, &cmds, &SweepConfig::default());
        let closure = sweep.closure.expect("the pirouette comes round");
        assert_eq!(closure.frame, 11);
        // Two turns see no edge in their overlap and fall back to the
        // command (true turns 33° and 32°): the loop residual finds them.
        let fallbacks: Vec<usize> = (1..12).filter(|&k| sweep.turns[k].unwrap().fallback).collect();
        assert_eq!(fallbacks, [3, 6]);
        assert!(
            closure.applied && (closure.residual_rad.to_degrees() + 5.0).abs() < 0.5,
            "{closure:?}"
        );
        for (k, h) in sweep.heading_rad.iter().enumerate() {
            assert!(
                (h - truth[k]).abs().to_degrees() < 1.0,
                "frame {k}: {} vs {}",
                h.to_degrees(),
                truth[k].to_degrees()
            );
        }
        // Verified turns keep their sub-degree accuracy.
        for k in (1..12).filter(|k| !fallbacks.contains(k)) {
            let err = sweep.turns[k].unwrap().turn_rad.to_degrees() - true_turns_deg[k];
            assert!(err.abs() < 0.3, "turn {k}: error {err}");
        }
        // The joined sweep sees the obstacle at 90°-99° (k = 2: 10° wide, 0.4 m).
        let i = sweep.rop.bin_of(94f64.to_radians()).unwrap();
        assert!((sweep.rop.range_m[i] - 0.4).abs() < 1e-6);
        let free = sweep.rop.bin_of(120f64.to_radians()).unwrap();
        assert!(sweep.rop.range_m[free].is_infinite());
        assert_eq!(sweep.rop.len(), 1440);
    }
}
