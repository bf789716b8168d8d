//! Radial sweeps: the profiles of one pirouette joined into 360°.

use crate::matching::{match_turn, Evidence, MatchConfig, MatchView, TurnEstimate};
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
    /// residual's share), or more for a barely distinct match (see
    /// [`SweepConfig::turn_sigma_rad`]).
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

impl SweepConfig {
    /// Standard deviation of a turn, radians: a command's for a fallback;
    /// for a verified match distinct by `z` standard deviations at a
    /// basin's distance ([`MatchConfig::basin_rad`]), the larger of
    /// `verified_sigma_rad` and `basin / z`: a match just distinct enough
    /// (`z` = 3) pins the turn to a third of its basin. A turn the loop
    /// closure fixed ([`Evidence::Loop`]) is taken as verified.
    pub fn turn_sigma_rad(&self, turn: &TurnEstimate) -> f64 {
        if turn.fallback {
            self.commanded_sigma_rad
        } else if turn.evidence == Evidence::Loop {
            self.verified_sigma_rad
        } else {
            self.verified_sigma_rad
                .max(self.matching.basin_rad / turn.significance())
        }
    }

    /// Standard deviation of an ambiguous match's own best angle
    /// ([`TurnEstimate::candidate_rad`]) as a measurement of its turn,
    /// radians: as for a verified match, the larger of
    /// `verified_sigma_rad` and `basin / z`; `None` for other fallbacks
    /// and where that is no tighter than the command.
    pub fn candidate_sigma_rad(&self, turn: &TurnEstimate) -> Option<f64> {
        if !(turn.fallback && turn.evidence == Evidence::Ambiguous && turn.candidate_rad.is_some()) {
            return None;
        }
        let sigma = self
            .verified_sigma_rad
            .max(self.matching.basin_rad / turn.significance());
        (sigma < self.commanded_sigma_rad).then_some(sigma)
    }
}

/// The loop closure of a pirouette.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopClosure {
    /// The frame whose view was matched against the first.
    pub frame: usize,
    /// The closing match (from that frame back round to the first).
    pub closing: TurnEstimate,
    /// Sum of the turns round the loop and the closing match minus 360°,
    /// radians, before spreading (ambiguous turns at their best matches
    /// where the loop picked those matches' basins: see [`assemble`]).
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
    /// match measured: consecutive frames joined by a matched turn, the
    /// loop closure, and frames after the loop matched against an earlier
    /// one (a turn the loop alone fixed has no link of its own). Sorted.
    pub links: Vec<(usize, usize)>,
}

/// Joins the profiles of one pirouette. `commanded_rad[k]` is the commanded
/// turn before frame `k` (`None` for the first frame). All profiles share
/// one bin width.
///
/// Where the pirouette comes round (a frame's view overlaps the first's
/// and the match between them is verified), the loop residual, the sum
/// of the turns and that closing match minus 360°, is spread over the
/// turns by least squares under the loop constraint: each takes a share in
/// proportion to its variance ([`SweepConfig::turn_sigma_rad`]), unless
/// the residual exceeds [`SweepConfig::max_residual_sigmas`] of the loop's
/// standard deviation (a wrong match; the turns are left as measured). A
/// fallback enters at its command and takes nearly all of the residual; it
/// stays flagged, since the sum of many verified turns is not as sure as
/// one match, unless it is the loop's only unverified turn, which the loop
/// then fixes ([`Evidence::Loop`]).
///
/// Where every unverified turn of the loop was merely ambiguous, the loop
/// puts their sum where the closing match and the other turns leave it.
/// Where the sum of their best matches lies within half a basin
/// ([`MatchConfig::basin_rad`]) of that, the loop has picked those
/// matches' basins (any one of them at a rival minimum, a basin or more
/// away, would put the sum further off): the turns enter at their best
/// matches, with the variance of [`SweepConfig::candidate_sigma_rad`],
/// instead of at their commands, and count as fixed by the loop.
pub fn assemble(rops: &[Rop], commanded_rad: &[Option<f64>], config: &SweepConfig) -> Sweep {
    let views: Vec<MatchView> = rops.iter().map(MatchView::from).collect();
    assemble_views(&views, commanded_rad, config)
}

/// [`assemble`] of profiles with a sensor's intermittent cue (see
/// [`MatchView`]); the 360° profile is joined from the views' profiles.
pub fn assemble_views(rops: &[MatchView], commanded_rad: &[Option<f64>], config: &SweepConfig) -> Sweep {
    assert_eq!(rops.len(), commanded_rad.len(), "one command per profile");
    let mut turns: Vec<Option<TurnEstimate>> = (0..rops.len())
        .map(|k| commanded_rad[k].map(|cmd| match_turn(rops[k - 1], rops[k], cmd, &config.matching)))
        .collect();
    let closure = if config.close_loop {
        close_loop(rops, &mut turns, config)
    } else {
        None
    };
    let mut links: Vec<(usize, usize)> = Vec::new();
    if let Some(c) = closure {
        if c.applied {
            links.push((0, c.frame));
        }
        // The frames after the one nearest to coming round, whether or not
        // the closing match verified: their headings rest on the verified
        // turns before them either way.
        links.extend(rematch_after_loop(rops, &mut turns, c.frame + 1, config));
    }
    for (k, t) in turns.iter().enumerate().skip(1) {
        // A turn the loop fixed is no match of its own: the closure's link
        // already holds what is known of it.
        let matched = t.is_some_and(|t| !t.fallback && t.evidence != Evidence::Loop);
        if matched && !links.iter().any(|&(_, b)| b == k) {
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
    let rop = join(rops.iter().map(|v| v.rop), &heading_rad);
    Sweep {
        turns,
        heading_rad,
        closure,
        rop,
        links,
    }
}

fn close_loop(
    rops: &[MatchView],
    turns: &mut [Option<TurnEstimate>],
    config: &SweepConfig,
) -> Option<LoopClosure> {
    let first = *rops.first()?;
    let view = first.rop.len() as f64 * first.rop.bin_width_rad;
    let max_closing = view - config.matching.min_overlap_rad;
    let var = |t: &TurnEstimate| config.turn_sigma_rad(t).powi(2);
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
    let closing = match_turn(rops[k], first, closing_est, &closing_config);
    if closing.fallback {
        return Some(LoopClosure {
            frame: k,
            closing,
            residual_rad: f64::NAN,
            applied: false,
        });
    }
    let (residual, applied) = spread_residual(&mut turns[1..=k], &closing, config);
    Some(LoopClosure {
        frame: k,
        closing,
        residual_rad: residual,
        applied,
    })
}

/// Spreads a loop's residual over its turns `loop_turns` (see
/// [`assemble`]), `closing` the match from the loop's last frame back to
/// the first. Returns the residual and whether it was spread.
fn spread_residual(
    loop_turns: &mut [Option<TurnEstimate>],
    closing: &TurnEstimate,
    config: &SweepConfig,
) -> (f64, bool) {
    let var = |t: &TurnEstimate| config.turn_sigma_rad(t).powi(2);
    let mut measured: Vec<Option<(f64, f64)>> = loop_turns
        .iter()
        .map(|t| t.map(|t| (t.turn_rad, var(&t))))
        .collect();
    let residual_of = |measured: &[Option<(f64, f64)>]| {
        measured.iter().flatten().map(|m| m.0).sum::<f64>() + closing.turn_rad - TAU
    };
    let unverified: Vec<usize> = (0..loop_turns.len())
        .filter(|&i| loop_turns[i].is_some_and(|t| t.fallback))
        .collect();
    // Every unverified turn at its ambiguous match, where each has one.
    let with_candidates: Option<Vec<Option<(f64, f64)>>> = (!unverified.is_empty())
        .then(|| {
            let mut with = measured.clone();
            for &i in &unverified {
                let t = loop_turns[i]?;
                let sigma = config.candidate_sigma_rad(&t)?;
                with[i] = Some((t.candidate_rad?, sigma * sigma));
            }
            Some(with)
        })
        .flatten();
    // With the candidates in, the residual is the distance of their sum
    // from where the loop puts it.
    let picked = match with_candidates {
        Some(with) if wrap(residual_of(&with)).abs() <= config.matching.basin_rad / 2.0 => {
            measured = with;
            true
        }
        _ => false,
    };
    let residual = residual_of(&measured);
    let total_var = measured.iter().flatten().map(|m| m.1).sum::<f64>() + var(closing);
    let applied = residual.abs() <= config.max_residual_sigmas * total_var.sqrt();
    if applied {
        for (t, (value, v)) in loop_turns
            .iter_mut()
            .zip(&measured)
            .filter_map(|(t, m)| Some((t.as_mut()?, (*m)?)))
        {
            t.turn_rad = value - residual * v / total_var;
        }
        // The turns the loop fixed: those whose basins it picked, or its
        // only unverified one.
        if picked || unverified.len() == 1 {
            for &i in &unverified {
                #[allow(clippy::expect_used, reason = "`unverified` lists turns that are present")]
                let t = loop_turns[i].as_mut().expect("an unverified turn");
                (t.fallback, t.evidence) = (false, Evidence::Loop);
            }
        }
    }
    (residual, applied)
}

/// Frames after the loop (the turn towards the next spot may be wider than
/// the view) are matched against the frame of the sweep whose heading is
/// nearest to where they should look: those whose turn had nothing to
/// compare with their predecessor, and those whose verified turn is wider
/// than their heading's distance from that frame (it overlaps them more
/// than the predecessor did, and a match on a narrow overlap may be
/// wrong). A re-match that verifies replaces the turn, unless it confirms
/// a verified one (within half a basin, [`MatchConfig::basin_rad`]).
/// Returns the links `(j, k)` of the re-matched frames.
fn rematch_after_loop(
    rops: &[MatchView],
    turns: &mut [Option<TurnEstimate>],
    from: usize,
    config: &SweepConfig,
) -> Vec<(usize, usize)> {
    let mut links = Vec::new();
    let view = rops[0].rop.len() as f64 * rops[0].rop.bin_width_rad;
    let max_turn = view - config.matching.min_overlap_rad;
    for k in from..rops.len() {
        let Some(t) = turns[k] else { continue };
        // Turns that had nothing to compare with their predecessor, or
        // were verified on it (an ambiguous match stays a fallback).
        let no_overlap = t.fallback && t.evidence == Evidence::NoOverlap;
        if t.fallback && !no_overlap {
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
        if !no_overlap && relative.abs() >= t.turn_rad.abs() {
            continue;
        }
        let m = match_turn(rops[j], rops[k], relative, &config.matching);
        // On the command's branch of the circle.
        let turn = t.turn_rad + wrap(heading[j] + m.turn_rad - heading[k - 1] - t.turn_rad);
        // A verified turn that the wider overlap confirms (within half a
        // basin) stays as matched, its link and shift with it; one it
        // contradicts was a wrong minimum.
        let confirmed = !no_overlap && (turn - t.turn_rad).abs() <= config.matching.basin_rad / 2.0;
        if !m.fallback && !confirmed {
            // (The shift was measured from frame `j`, not the one before.)
            turns[k] = Some(TurnEstimate {
                turn_rad: turn,
                shift: None,
                ..m
            });
            links.push((j, k));
        }
    }
    links
}

/// The point a robot turns about, in its own frame (x forward, y left),
/// metres, from the shifts its verified turns measured (see
/// [`TurnEstimate::shift`]). A turn by θ about the point `p` moves the
/// robot centre by `M·p`, `M = I − R(θ)`, in the frame before the turn.
/// Each turn's profiles alone say `H·d ≈ H·M·p` (`H` their information on
/// the shift `d`, [`crate::matching::TurnShift::weighted_evidence`]), so the least-squares
/// `p` solves `Σ MᵀHM · p = Σ MᵀH·d`, independent of the priors the turns
/// were refined under. `None` where the turns do not fix both coordinates.
pub fn pivot_from_turns<'a>(
    turns: impl IntoIterator<Item = &'a TurnEstimate>,
    floor_sd_m: f64,
) -> Option<[f64; 2]> {
    use nalgebra::{Matrix2, SymmetricEigen, Vector2};
    let mut a = Matrix2::<f64>::zeros();
    let mut b = Vector2::<f64>::zeros();
    for t in turns {
        let Some(shift) = t.shift.filter(|_| !t.fallback) else {
            continue;
        };
        // The turn's information with the floor added to its covariance,
        // `(H⁺ + σ²I)⁻¹ = V·diag(λ / (1 + σ²λ))·Vᵀ`, and the evidence
        // `Hd` scaled alike: `V·diag(1 / (1 + σ²λ))·Vᵀ·Hd`.
        let [[h00, h01], [h10, h11]] = shift.information;
        let eigen = SymmetricEigen::new(Matrix2::new(h00, 0.5 * (h01 + h10), 0.5 * (h01 + h10), h11));
        let lambda = eigen.eigenvalues.map(|l| l.max(0.0));
        let damp = lambda.map(|l| 1.0 / (1.0 + floor_sd_m * floor_sd_m * l));
        let v = eigen.eigenvectors;
        let h = v * Matrix2::from_diagonal(&lambda.component_mul(&damp)) * v.transpose();
        let hd = v * Matrix2::from_diagonal(&damp) * v.transpose() * Vector2::from(shift.weighted_evidence());
        let (s, c) = t.turn_rad.sin_cos();
        let m = Matrix2::new(1.0 - c, s, -s, 1.0 - c);
        a += m.transpose() * h * m;
        b += m.transpose() * hd;
    }
    // Both coordinates fixed: the smaller eigenvalue not lost in rounding.
    let eigen = SymmetricEigen::new(a);
    let (lo, hi) = (eigen.eigenvalues.min(), eigen.eigenvalues.max());
    (hi > 0.0 && lo > 1e-9 * hi)
        .then(|| a.try_inverse())
        .flatten()
        .map(|inv| {
            let p = inv * b;
            [p.x, p.y]
        })
}

fn wrap(a: f64) -> f64 {
    let w = a.rem_euclid(TAU);
    if w > PI {
        w - TAU
    } else {
        w
    }
}

/// The 360° sweep: every profile's bins rotated by its frame's heading
/// about the first frame's centre (the other frames' centres lie within a
/// centimetre of it, on the circle a robot turning about a point off its
/// centre runs round: a diagram, not a map);
/// where several frames see a bin, the median range (and the colour of the
/// sample nearest it). [`assemble`] joins the profiles it matched; a
/// caller that verified the turns on other profiles of the same frames
/// (see `pirouette_vision::VisionConfig::for_matching`) joins its own with
/// the sweep's headings.
pub fn join<'a>(rops: impl IntoIterator<Item = &'a Rop>, heading_rad: &[f64]) -> Rop {
    let mut rops = rops.into_iter().peekable();
    let Some(&first) = rops.peek() else {
        return Rop::empty(-PI, TAU, 0, 1.0);
    };
    let w = first.bin_width_rad;
    #[allow(clippy::expect_used, reason = "the bin width is an existing profile's")]
    let mut out = Rop::covering(-PI, PI - w, w, first.max_range_m).expect("valid bin width");
    let n = out.len();
    let mut samples: Vec<Vec<(f32, Option<ColourTag>)>> = vec![Vec::new(); n];
    for (rop, &h) in rops.zip(heading_rad) {
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
mod tests;
