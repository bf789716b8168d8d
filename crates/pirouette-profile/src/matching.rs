//! Rotation verification: sliding the profile after a turn over the one
//! before it.
//!
//! A robot that turns counter-clockwise by θ sees an obstacle that stood at
//! bearing β at β − θ afterwards: `after(β) = before(β + θ)`. The turn is
//! found by searching θ in a window around the commanded angle for the
//! least dissimilarity over the bins both profiles saw.
//!
//! Each bin is compared as inverse range (`1/r`; "nothing in sight" is 0):
//! its noise is about the same near and far, ranges beyond the soft limit
//! still tell bearing with a weight that falls with distance, and open
//! floor compares as equal. A bin with nothing in sight whose floor was
//! seen only so far ([`Rop::free_reach`], at the sides of a camera's view)
//! says only that any obstacle lies beyond that: it is the interval of
//! inverse ranges up to the reach's, and two bins differ by the gap
//! between their intervals. Where both bins carry a colour tag, their
//! chromaticities are compared too.

mod curve;
mod refine;
mod signals;

use crate::Rop;
use curve::{cost_curve, CostCurve, KEPT_GAPS, LANES};
use refine::refine_with_shift;
use signals::{cells, gap, informative, Cell, Signals};

/// How two overlapping stretches of profile are compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Measure {
    /// Mean absolute difference.
    Absolute,
    /// Mean squared difference.
    Squared,
    /// Mean truncated quadratic: differences beyond three standard
    /// deviations cost the same (outlier bins cannot dominate).
    #[default]
    Robust,
    /// The paper's proposal: low-pass DCT coefficients of both stretches
    /// compared (squared distance), then the colour term.
    Dct,
}

impl std::str::FromStr for Measure {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "absolute" => Ok(Self::Absolute),
            "squared" => Ok(Self::Squared),
            "robust" => Ok(Self::Robust),
            "dct" => Ok(Self::Dct),
            _ => Err(format!("unknown measure `{s}` (absolute, squared, robust, dct)")),
        }
    }
}

/// Settings of rotation matching.
#[derive(Debug, Clone, PartialEq)]
pub struct MatchConfig {
    /// Half-width of the search window around the commanded turn, radians.
    pub window_rad: f64,
    /// The least overlap of the two profiles' seen bins, radians.
    pub min_overlap_rad: f64,
    /// Standard deviation of a bin's inverse range assumed before it is
    /// measured, and the most it may be taken to be, 1/m. Each match
    /// measures its own from the residuals of its best shift.
    pub inverse_range_sigma: f32,
    /// The least standard deviation of inverse range a match may measure,
    /// 1/m: what the sensor resolves at best. For a camera, a tenth of the
    /// least change of inverse range between two adjacent image rows (a
    /// boundary found to a tenth of a row there; the `pirouette` pipeline
    /// sets it so from each dataset's camera).
    pub min_inverse_range_sigma: f32,
    /// Standard deviation of a bin's chromaticity share.
    pub chroma_sigma: f32,
    /// Weight of the colour term beside the range term.
    pub colour_weight: f32,
    /// The dissimilarity measure.
    pub measure: Measure,
    /// Local minima closer than this to the best belong to its basin, radians.
    pub basin_rad: f64,
    /// Angular extent over which a profile's errors are shared by
    /// neighbouring bins (smoothing, joined columns), radians.
    pub correlation_rad: f64,
    /// The least confidence for a verified turn.
    pub min_confidence: f64,
    /// The least structure in the overlap (edges of inverse range beyond
    /// the noise, colour changes) for a match to mean anything: below it
    /// the overlap is featureless.
    pub min_structure: f64,
    /// How far a turn may move the robot centre, metres (one standard
    /// deviation each way; 0: the turn is refined alone). A verified turn
    /// is refined together with that shift.
    pub turn_shift_m: f64,
    /// The point the robot turns about, in its own frame (x forward, y
    /// left), metres: a turn by θ about it moves the robot centre by
    /// `(I − R(θ))·pivot`, where the shift's prior is centred (see
    /// [`crate::sweep::pivot_from_turns`]).
    pub pivot_m: [f64; 2],
}

impl Default for MatchConfig {
    /// - `window_rad`: ±15°, five times the turn errors of a cheap robot;
    /// - `min_overlap_rad`: 10°;
    /// - `inverse_range_sigma`: 0.05 /m (a range error of 0.5 cm at 0.3 m,
    ///   4 cm at 0.9 m), measured per match within 0.01-0.05 /m (0.01 is
    ///   about a quarter of an image row for a camera 10 cm up with a
    ///   277-pixel focal length, whose rows change inverse range by at
    ///   least 0.036 /m);
    /// - `chroma_sigma`: 0.03;
    /// - `colour_weight`: 1;
    /// - `measure`: robust;
    /// - `basin_rad`: 3°;
    /// - `correlation_rad`: 1°, about five image columns;
    /// - `min_confidence`: 0.5: the best shift must beat the best one
    ///   outside its basin by three standard deviations of the noise;
    /// - `min_structure`: 3, one clear edge seen in both profiles;
    /// - `turn_shift_m`: 3 mm: a robot that turns about a point 5 mm off
    ///   its centre moves that centre by 2.6 mm in a 30° turn;
    /// - `pivot_m`: the centre (no shift expected) until a dataset's turns
    ///   have measured it.
    fn default() -> Self {
        Self {
            window_rad: 15f64.to_radians(),
            min_overlap_rad: 10f64.to_radians(),
            inverse_range_sigma: 0.05,
            min_inverse_range_sigma: 0.01,
            chroma_sigma: 0.03,
            colour_weight: 1.0,
            measure: Measure::Robust,
            basin_rad: 3f64.to_radians(),
            correlation_rad: 1f64.to_radians(),
            min_confidence: 0.5,
            min_structure: 3.0,
            turn_shift_m: 0.003,
            pivot_m: [0.0, 0.0],
        }
    }
}

/// What a verified turn rests on, or why a turn was not verified.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Evidence {
    /// Ranges alone (within or beyond the soft limit).
    Range,
    /// Ranges and obstacle colours.
    RangeAndColour,
    /// An unverified turn of a closed pirouette that the loop fixed: its
    /// only one (the closing match and the loop's other turns, all
    /// verified, fix it), or one of its ambiguous turns whose best
    /// matches' basins the loop picked (see [`crate::sweep::assemble`]).
    Loop,
    /// Fallback: the profiles overlap too little in the window.
    NoOverlap,
    /// Fallback: the overlap is featureless (open floor): the aperture problem.
    Aperture,
    /// Fallback: another shift matches nearly as well (flat or periodic cost),
    /// the best lies at the window's edge, or no shift a basin away from it
    /// can be compared (its distinctness untested).
    Ambiguous,
}

impl Evidence {
    /// A short name for output.
    pub fn name(&self) -> &'static str {
        match self {
            Evidence::Range => "range",
            Evidence::RangeAndColour => "range+colour",
            Evidence::Loop => "loop",
            Evidence::NoOverlap => "no-overlap",
            Evidence::Aperture => "aperture",
            Evidence::Ambiguous => "ambiguous",
        }
    }
}

/// The verified (or fallen back) angle of one turn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TurnEstimate {
    /// The turn, radians counter-clockwise; the commanded angle on fallback.
    pub turn_rad: f64,
    /// How distinct the best match is, 0-1 (0 on fallback without a match).
    pub confidence: f64,
    /// True when no trustworthy match was found.
    pub fallback: bool,
    /// What verified the turn, or why it fell back.
    pub evidence: Evidence,
    /// Bins compared at the best shift.
    pub overlap_bins: usize,
    /// The best match's angle, even when it was not trusted (`None` when
    /// there was nothing to match), radians.
    pub candidate_rad: Option<f64>,
    /// How far the robot centre moved during a verified turn, refined
    /// with it (see [`MatchConfig::turn_shift_m`]); `None` where it was not.
    pub shift: Option<TurnShift>,
}

/// The robot centre's move during a turn, measured with the turn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TurnShift {
    /// The estimate, in the frame before the turn (x forward, y left),
    /// metres: the profiles' evidence and the prior together.
    pub shift_m: [f64; 2],
    /// The prior's mean (the shift a turn about [`MatchConfig::pivot_m`]
    /// makes), metres.
    pub prior_mean_m: [f64; 2],
    /// The prior's information (the inverse of its variance, the same each
    /// way), 1/m².
    pub prior_information: f64,
    /// What the profiles alone say of the shift: its information matrix
    /// with the turn marginalised out, 1/m². Along a plain wall the shift
    /// parallel to it is not seen at all.
    pub information: [[f64; 2]; 2],
}

impl TurnShift {
    /// The shift the profiles alone give, weighed by [`Self::information`]:
    /// `information · shift_alone`, which stays defined where the
    /// information is singular. The estimate satisfies
    /// `(information + λ·I)·shift = information·shift_alone + λ·prior_mean`.
    pub fn weighted_evidence(&self) -> [f64; 2] {
        let (h, l) = (&self.information, self.prior_information);
        let [x, y] = self.shift_m;
        let [mx, my] = self.prior_mean_m;
        [
            (h[0][0] + l) * x + h[0][1] * y - l * mx,
            h[1][0] * x + (h[1][1] + l) * y - l * my,
        ]
    }
}

/// The significance at which a match's confidence is one half: confidence
/// is `z / (z + CONFIDENCE_HALF_Z)` for a best match `z` standard
/// deviations of the noise below its rivals.
const CONFIDENCE_HALF_Z: f64 = 3.0;

impl TurnEstimate {
    /// How distinct the best match is, in standard deviations of the noise
    /// (the `z` its confidence comes from): infinite where no rival could
    /// be weighed against it, 0 where there was no match.
    pub fn significance(&self) -> f64 {
        if self.confidence >= 1.0 {
            f64::INFINITY
        } else {
            CONFIDENCE_HALF_Z * self.confidence / (1.0 - self.confidence)
        }
    }
}

/// Verifies a turn: the angle between `before` and `after` nearest to
/// `commanded_rad` within the window. Both profiles must have the same bin
/// width (any width, any field of view: laser scans too).
///
/// # Panics
/// When the bin widths differ by more than a part in a million.
pub fn match_turn(before: &Rop, after: &Rop, commanded_rad: f64, config: &MatchConfig) -> TurnEstimate {
    let w = before.bin_width_rad;
    assert!(
        (after.bin_width_rad - w).abs() <= 1e-6 * w,
        "profiles of different bin widths"
    );
    let fallback = |evidence, confidence, overlap_bins, candidate_rad| TurnEstimate {
        turn_rad: commanded_rad,
        confidence,
        fallback: true,
        evidence,
        overlap_bins,
        candidate_rad,
        shift: None,
    };
    let offset = ((after.bearing_start_rad - before.bearing_start_rad) / w).round() as i64;
    let k_cmd = (commanded_rad / w).round() as i64;
    let k_win = (config.window_rad / w).ceil() as i64;
    let (a, b) = (cells(after), cells(before));
    let min_overlap = ((config.min_overlap_rad / w).ceil() as usize).max(3);
    let (k_lo, k_hi) = (k_cmd - k_win, k_cmd + k_win);
    let best_of = |curve: &CostCurve| {
        (0..curve.cost.len())
            .filter(|&j| curve.comparable(j, min_overlap))
            .min_by(|&x, &y| curve.cost[x].total_cmp(&curve.cost[y]))
    };
    // First pass with the nominal noise; then the noise measured in the
    // residuals of that best match sets the scale of the costs and of the
    // significance (the profiles' own noise, not an assumed one).
    // The profile after the turn, padded to whole blocks of the inner
    // loop; the one before, over every bin some shift compares with it.
    let a_len = a.len().div_ceil(LANES) as i64 * LANES as i64;
    let sa = Signals::new(&a, 0..a_len);
    let sb = Signals::new(&b, offset + k_lo..offset + k_hi + a_len);
    // Each informative pair's inverse-range gap, kept from the first pass
    // so that the second need not compare the profiles again; in the
    // thread's buffer, which every pass writes before it reads.
    let curves = KEPT_GAPS.with_borrow_mut(|gaps| {
        let nominal = cost_curve(&sa, &sb, k_lo, k_hi, config.inverse_range_sigma, config, gaps);
        let first = best_of(&nominal)?;
        let sigma = residual_sigma(&a, &b, offset + k_lo + first as i64)
            .map_or(config.inverse_range_sigma, |s| {
                s.clamp(config.min_inverse_range_sigma, config.inverse_range_sigma)
            });
        // A noise measured at (or clamped to) the nominal one gives the
        // same curve.
        let curve = if sigma == config.inverse_range_sigma {
            nominal
        } else if config.measure == Measure::Dct {
            cost_curve(&sa, &sb, k_lo, k_hi, sigma, config, gaps)
        } else {
            nominal.rescaled(gaps, sigma, config)
        };
        Some((curve, sigma))
    });
    let Some((curve, sigma)) = curves else {
        return fallback(Evidence::NoOverlap, 0.0, 0, None);
    };
    let Some(best) = best_of(&curve) else {
        return fallback(Evidence::NoOverlap, 0.0, 0, None);
    };
    // A rival must rest on at least half as many informative pairs as the
    // best: a mean cost over far fewer pairs is judged on too little.
    let valid =
        |j: usize| curve.comparable(j, min_overlap) && 2 * curve.informative[j] >= curve.informative[best];
    let k_best = curve.k_lo + best as i64;
    let overlap_bins = curve.overlap[best];

    // Structure of the overlap at the best shift: is there anything to match?
    let structure = structure(&a, &b, offset + k_best, sigma as f64);
    if structure < config.min_structure {
        return fallback(Evidence::Aperture, 0.0, overlap_bins, Some(k_best as f64 * w));
    }
    // Distinctness as significance: a rival's excess cost summed over the
    // informative bins, in standard deviations of a sum of that many bins'
    // noise costs (neighbouring fine bins share their errors: one sample
    // per `correlation_rad`). The rivals are the lowest other local minimum
    // (window ends included: a competitor may lie beyond them) and the
    // lower arm of the best one's basin (a broad bowl is no verification).
    let basin = ((config.basin_rad / w).ceil() as usize).max(2);
    let cost = |j: usize| if valid(j) { curve.cost[j] } else { f64::INFINITY };
    let last = curve.cost.len() - 1;
    let is_local_min =
        |j: usize| valid(j) && (j == 0 || cost(j) <= cost(j - 1)) && (j == last || cost(j) <= cost(j + 1));
    let other_min = (0..curve.cost.len())
        .filter(|&j| j.abs_diff(best) > basin && is_local_min(j))
        .map(cost)
        .fold(f64::INFINITY, f64::min);
    let arm = [best.checked_sub(basin), Some(best + basin).filter(|&j| j <= last)]
        .into_iter()
        .flatten()
        .map(cost)
        .fold(f64::INFINITY, f64::min);
    let c0 = curve.cost[best];
    let n_eff = curve.informative[best] as f64 * (w / config.correlation_rad).min(1.0);
    let z = |rival: f64| {
        if rival.is_finite() {
            (rival - c0).max(0.0) * n_eff / (noise_cost_sd(config.measure) * n_eff.max(1.0).sqrt())
        } else {
            f64::INFINITY
        }
    };
    // A basin neither of whose arms can be weighed was never tested: its
    // minimum verifies nothing, however alone it stands.
    let z_best = if arm.is_finite() {
        z(other_min).min(z(arm))
    } else {
        0.0
    };
    let confidence = if z_best.is_finite() {
        z_best / (z_best + CONFIDENCE_HALF_Z)
    } else {
        1.0
    };
    // Below one bin: a parabola through the best and its neighbours.
    let mut k = k_best as f64;
    if best > 0 && best + 1 < curve.cost.len() && valid(best - 1) && valid(best + 1) {
        let (cm, cp) = (curve.cost[best - 1], curve.cost[best + 1]);
        let denom = cm - 2.0 * c0 + cp;
        if denom > 1e-12 {
            k += (0.5 * (cm - cp) / denom).clamp(-0.5, 0.5);
        }
    }
    let at_edge = best == 0 || best + 1 == curve.cost.len();
    if at_edge || confidence < config.min_confidence {
        return fallback(Evidence::Ambiguous, confidence, overlap_bins, Some(k * w));
    }
    let evidence = if curve.colour_pairs[best] > 0 {
        Evidence::RangeAndColour
    } else {
        Evidence::Range
    };
    let refined = (config.turn_shift_m > 0.0)
        .then(|| refine_with_shift(before, after, k * w, sigma as f64, config))
        .flatten();
    let turn = refined.map_or(k * w, |(turn, _)| turn);
    TurnEstimate {
        turn_rad: turn,
        confidence,
        fallback: false,
        evidence,
        overlap_bins,
        candidate_rad: Some(turn),
        shift: refined.map(|(_, shift)| shift),
    }
}

/// Standard deviation of one bin's cost when the two profiles agree but
/// for noise (their difference is normal with variance 2 in units of σ).
fn noise_cost_sd(measure: Measure) -> f64 {
    match measure {
        // |e|: sd of a half-normal of scale √2.
        Measure::Absolute => (2.0 * (1.0 - 2.0 / std::f64::consts::PI)).sqrt(),
        // e²: 2·χ²₁, sd 2√2; truncation at 9 trims it a little.
        Measure::Squared | Measure::Dct => 2.0 * std::f64::consts::SQRT_2,
        Measure::Robust => 2.3,
    }
}

/// Robust standard deviation (1.4826 · median absolute deviation) of the
/// inverse-range residuals over the informative pairs at `shift`, each
/// residual being the difference of two bins (so divided by √2).
fn residual_sigma(a: &[Cell], b: &[Cell], shift: i64) -> Option<f32> {
    // The gaps as their bit patterns: finite and not negative, they sort
    // as the values do, and integers compare faster.
    let mut r = Vec::with_capacity(a.len());
    r.extend(a.iter().enumerate().filter_map(|(i, ca)| {
        let j = i as i64 + shift;
        let cb = *b.get(usize::try_from(j).ok()?)?;
        (!ca.inv.is_nan() && !cb.inv.is_nan() && informative(ca, &cb)).then(|| gap(ca, &cb).to_bits())
    }));
    if r.len() < 5 {
        return None;
    }
    let mid = r.len() / 2;
    let (_, med, _) = r.select_nth_unstable(mid);
    Some(1.4826 * f32::from_bits(*med) / std::f32::consts::SQRT_2)
}

/// How much there is to align in the overlap at `shift`: every step of
/// inverse range between neighbouring bins (as the pairs compare them:
/// the intermittent cue's where both bins have it) counts by how far it
/// exceeds twice the noise (in standard deviations, at most 3), every
/// colour appearing or vanishing counts 1; each profile counts half. One
/// clear edge seen by both profiles scores 3.
fn structure(a: &[Cell], b: &[Cell], shift: i64, sigma: f64) -> f64 {
    let step = |x: f32, y: f32| ((((x - y) as f64).abs() - 2.0 * sigma) / sigma).clamp(0.0, 3.0);
    let mut total = 0.0;
    let mut last: Option<(Cell, Cell)> = None;
    for (i, ca) in a.iter().enumerate() {
        let j = i as i64 + shift;
        if j < 0 || j as usize >= b.len() {
            continue;
        }
        let cb = b[j as usize];
        if ca.inv.is_nan() || cb.inv.is_nan() {
            last = None;
            continue;
        }
        if let Some((pa, pb)) = last {
            // Each pair's inverse ranges as compared: the intermittent
            // cue's where both bins have it.
            let compared = |x: &Cell, y: &Cell| {
                if x.inv_c.is_nan() || y.inv_c.is_nan() {
                    (x.inv, y.inv)
                } else {
                    (x.inv_c, y.inv_c)
                }
            };
            let ((xa, xb), (qa, qb)) = (compared(ca, &cb), compared(&pa, &pb));
            total += (step(xa, qa) + step(xb, qb)) / 2.0;
            total += ((ca.chroma.is_some() != pa.chroma.is_some()) as u8
                + (cb.chroma.is_some() != pb.chroma.is_some()) as u8) as f64
                / 2.0;
        }
        last = Some((*ca, cb));
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The cost curve's vectorised sums against the definitions summed one
    /// pair at a time: unseen bins, open floor (seen all the way or only
    /// up to a reach), colours present and absent, an intermittent cue's
    /// ranges in one bin of a pair, in both or in neither,
    /// a profile length that is not a whole number of blocks, and shifts
    /// that run off both ends. The curve rescaled to another noise from the
    /// kept gaps equals a new pass.
    #[test]
    fn cost_curve_matches_the_definitions_pair_by_pair() {
        let mut rng = ChaCha8Rng::seed_from_u64(12345);
        let mut next = move || rng.random::<f32>();
        let mut random_cells = |n: usize| -> Vec<Cell> {
            (0..n)
                .map(|_| {
                    let kind = next();
                    let inv = if kind < 0.15 {
                        f32::NAN
                    } else if kind < 0.4 {
                        0.0
                    } else {
                        1.0 + 3.0 * next()
                    };
                    let chroma =
                        (inv > 0.0 && next() < 0.6).then(|| [0.3 + 0.1 * next(), 0.3 + 0.1 * next()]);
                    // Open floor seen all the way, or only up to a reach.
                    let inv_hi = if inv == 0.0 && next() < 0.5 {
                        1.0 + 3.0 * next()
                    } else {
                        inv
                    };
                    // The intermittent cue's range in some seen bins: the
                    // bin's own obstacle or a nearer one.
                    let inv_c = if !inv.is_nan() && next() < 0.3 {
                        inv.max(1.0) + next()
                    } else {
                        f32::NAN
                    };
                    Cell {
                        inv,
                        inv_hi,
                        chroma,
                        inv_c,
                    }
                })
                .collect()
        };
        let (a, b) = (random_cells(45), random_cells(61));
        let config = MatchConfig::default();
        let (offset, k_lo, k_hi, sigma) = (3i64, -20i64, 25i64, 0.02f32);
        let a_len = a.len().div_ceil(LANES) as i64 * LANES as i64;
        let (sa, sb) = (
            Signals::new(&a, 0..a_len),
            Signals::new(&b, offset + k_lo..offset + k_hi + a_len),
        );
        let mut gaps = Vec::new();
        let curve = cost_curve(&sa, &sb, k_lo, k_hi, sigma, &config, &mut gaps);
        // The curve at another noise, from the kept gaps, is the one a new
        // pass over the profiles gives, to the last bit.
        let other = cost_curve(&sa, &sb, k_lo, k_hi, 0.05, &config, &mut Vec::new());
        let rescaled = curve.clone().rescaled(&gaps, 0.05, &config);
        assert_eq!(rescaled.cost, other.cost);
        assert_eq!(rescaled.informative, other.informative);
        let rho = |e: f64| (e * e).min(9.0);
        let mut checked = 0;
        for (j, k) in (k_lo..=k_hi).enumerate() {
            let (mut range, mut colour) = (0f64, 0f64);
            let (mut seen, mut info, mut coloured) = (0, 0, 0);
            for (i, ca) in a.iter().enumerate() {
                let Some(cb) = usize::try_from(i as i64 + offset + k).ok().and_then(|t| b.get(t)) else {
                    continue;
                };
                if ca.inv.is_nan() || cb.inv.is_nan() {
                    continue;
                }
                seen += 1;
                if !(ca.inv_c.is_nan() || cb.inv_c.is_nan()) {
                    // Both have the intermittent cue's range: compared.
                    info += 1;
                    range += rho((ca.inv_c - cb.inv_c).abs() as f64 / sigma as f64);
                } else if (ca.inv > 0.0 && ca.inv >= cb.inv_hi) || (cb.inv > 0.0 && cb.inv >= ca.inv_hi) {
                    info += 1;
                    // The distance between the bins' intervals of inverse
                    // range.
                    let d = (ca.inv.max(cb.inv) - ca.inv_hi.min(cb.inv_hi)).max(0.0);
                    range += rho(d as f64 / sigma as f64);
                }
                if let (Some(x), Some(y)) = (ca.chroma, cb.chroma) {
                    coloured += 1;
                    let e =
                        ((x[0] - y[0]).abs().max((x[1] - y[1]).abs())) as f64 / config.chroma_sigma as f64;
                    colour += rho(e);
                }
            }
            assert_eq!(curve.overlap[j], seen, "shift {k}");
            assert_eq!(curve.informative[j], info, "shift {k}");
            assert_eq!(curve.colour_pairs[j], coloured, "shift {k}");
            if seen == 0 {
                assert!(curve.cost[j].is_infinite(), "shift {k}: nothing seen in common");
                continue;
            }
            let expect = if info == 0 {
                0.0
            } else {
                (range + config.colour_weight as f64 * colour) / info as f64
            };
            assert!(
                (curve.cost[j] - expect).abs() <= 1e-5 * expect.max(1.0),
                "shift {k}: {} vs {expect}",
                curve.cost[j]
            );
            checked += 1;
        }
        assert!(checked > 30, "{checked} shifts compared");
    }

    /// A 360° scene of ranges around the robot, seen through a 60° view.
    fn scene_range(bearing: f64) -> f32 {
        let d = bearing.to_degrees().rem_euclid(360.0);
        match d {
            d if (20.0..35.0).contains(&d) => 0.35,
            d if (45.0..50.0).contains(&d) => 0.5,
            d if (170.0..175.0).contains(&d) => 0.4,
            d if (250.0..262.0).contains(&d) => 0.55,
            d if (115.0..118.0).contains(&d) => 0.45,
            d if (80.0..140.0).contains(&d) => 0.6 + 0.002 * (d - 80.0) as f32,
            d if (200.0..210.0).contains(&d) => 0.25,
            d if (300.0..330.0).contains(&d) => 1.4,
            _ => f32::INFINITY,
        }
    }

    fn view(heading_deg: f64, bin_deg: f64) -> Rop {
        let w = bin_deg.to_radians();
        let mut rop = Rop::covering(-30f64.to_radians(), 30f64.to_radians(), w, 0.9).unwrap();
        for i in 0..rop.len() {
            // Sample the scene at sub-bin resolution: nearest over the bin.
            let r = (0..5)
                .map(|s| {
                    scene_range(
                        heading_deg.to_radians()
                            + rop.bearing_start_rad
                            + (i as f64 + (s as f64 + 0.5) / 5.0) * w,
                    )
                })
                .fold(f32::INFINITY, f32::min);
            rop.range_m[i] = r;
        }
        rop
    }

    #[test]
    fn recovers_turns_against_brute_force_truth() {
        let mut checked = 0;
        for measure in [Measure::Absolute, Measure::Squared, Measure::Robust, Measure::Dct] {
            let config = MatchConfig {
                measure,
                ..MatchConfig::default()
            };
            for (h, turn) in [
                (10.0, 30.0),
                (60.0, 27.3),
                (100.0, 32.6),
                (190.0, 30.0),
                (160.0, 25.0),
            ] {
                let est = match_turn(&view(h, 1.0), &view(h + turn, 1.0), 30f64.to_radians(), &config);
                assert!(!est.fallback, "{measure:?} h={h} turn={turn}: {est:?}");
                let err = (est.turn_rad.to_degrees() - turn).abs();
                assert!(
                    err < 0.6,
                    "{measure:?} h={h} turn={turn}: got {}",
                    est.turn_rad.to_degrees()
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 20);
    }

    /// Walls round the robot beyond the reach of every cue but an
    /// intermittent one, which finds them in each view in its own
    /// stretches (seven bins in ten, at random): with nothing else in
    /// sight the turn is open floor; compared where both views have them
    /// and silent elsewhere, the walls verify it; the same stretches taken
    /// as steady ranges (a wall in one view against nothing in the other
    /// is a contradiction) verify it less surely.
    #[test]
    fn an_intermittent_cue_counts_where_both_views_have_it() {
        // Six-degree stretches of wall at ranges 0.55-0.8 m in an order
        // that does not repeat within a view.
        let wall = |bearing: f64| {
            let segment = (bearing.to_degrees().rem_euclid(360.0) / 6.0) as u32;
            0.55 + 0.05 * ((segment * 7 + segment / 6) % 6) as f32
        };
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let config = MatchConfig::default();
        let mut steady_confidence = 0.0;
        let mut intermittent_confidence = 0.0;
        for (h, turn) in [
            (10.0, 30.0),
            (60.0, 27.5),
            (100.0, 32.5),
            (190.0, 30.0),
            (160.0, 25.0),
        ] {
            let mut views = |heading: f64| {
                let mut blank =
                    Rop::covering(-30f64.to_radians(), 30f64.to_radians(), 0.25f64.to_radians(), 0.9)
                        .unwrap();
                blank.range_m.fill(f32::INFINITY);
                let mut seen = blank.clone();
                seen.intermittent_m = (0..blank.len())
                    .map(|i| {
                        let r = wall(heading.to_radians() + blank.bin_centre_rad(i));
                        if rng.random::<f32>() < 0.7 {
                            r
                        } else {
                            f32::INFINITY
                        }
                    })
                    .collect();
                let mut steady = blank.clone();
                steady.range_m = seen.intermittent_m.clone();
                [blank, seen, steady]
            };
            let (before, after) = (views(h), views(h + turn));
            let cmd = 30f64.to_radians();
            let blank = match_turn(&before[0], &after[0], cmd, &config);
            assert!(blank.fallback, "h={h}: open floor verified {blank:?}");
            let est = match_turn(&before[1], &after[1], cmd, &config);
            assert!(!est.fallback, "h={h} turn={turn}: {est:?}");
            let err = (est.turn_rad.to_degrees() - turn).abs();
            assert!(err < 0.25, "h={h} turn={turn}: got {}", est.turn_rad.to_degrees());
            intermittent_confidence += est.confidence;
            let steady = match_turn(&before[2], &after[2], cmd, &config);
            steady_confidence += if steady.fallback { 0.0 } else { steady.confidence };
        }
        assert!(
            steady_confidence < intermittent_confidence,
            "steady {steady_confidence} against intermittent {intermittent_confidence} (sums of five)"
        );
    }

    /// A camera sees only the near floor at the sides of its view: there a
    /// bin with nothing in sight says nothing of what lies farther.
    fn view_with_short_sides(heading_deg: f64, bin_deg: f64, side_deg: f64, reach_m: f32) -> Rop {
        let mut rop = view(heading_deg, bin_deg);
        let side = (side_deg / bin_deg).round() as usize;
        let n = rop.len();
        for i in (0..side).chain(n - side..n) {
            if rop.range_m[i] > reach_m {
                rop.range_m[i] = f32::INFINITY;
                rop.free_m[i] = reach_m;
            }
        }
        rop
    }

    #[test]
    fn open_floor_seen_only_near_does_not_contradict_far_walls() {
        // At the sides of each view, the floor is seen to 0.3 m only, and
        // the walls there (0.35-1.4 m) are out of sight in one view but in
        // the middle of the other.
        for (h, turn) in [(60.0, 27.3), (100.0, 32.6), (160.0, 25.0)] {
            let (before, after) = (
                view_with_short_sides(h, 0.25, 5.0, 0.3),
                view_with_short_sides(h + turn, 0.25, 5.0, 0.3),
            );
            let est = match_turn(&before, &after, 30f64.to_radians(), &MatchConfig::default());
            assert!(!est.fallback, "h={h} turn={turn}: {est:?}");
            let err = (est.turn_rad.to_degrees() - turn).abs();
            assert!(err < 0.3, "h={h} turn={turn}: got {}", est.turn_rad.to_degrees());
        }
    }

    #[test]
    fn fine_bins_refine_below_a_degree() {
        let est = match_turn(
            &view(60.0, 0.2),
            &view(88.3, 0.2),
            30f64.to_radians(),
            &MatchConfig::default(),
        );
        assert!(!est.fallback, "{est:?}");
        assert!(
            (est.turn_rad.to_degrees() - 28.3).abs() < 0.15,
            "{}",
            est.turn_rad.to_degrees()
        );
    }

    /// A profile of 0.25° bins over a 60° view from `(x, y)` facing
    /// `heading_deg`, ray-cast against wall segments (nearest over five
    /// rays a bin), soft limit 0.9 m.
    fn cast_view(walls: &[[f64; 4]], x: f64, y: f64, heading_deg: f64) -> Rop {
        let w = 0.25f64.to_radians();
        let mut rop = Rop::covering(-30f64.to_radians(), 30f64.to_radians(), w, 0.9).unwrap();
        for i in 0..rop.len() {
            rop.range_m[i] = (0..5)
                .filter_map(|k| {
                    let b = heading_deg.to_radians()
                        + rop.bearing_start_rad
                        + (i as f64 + (k as f64 + 0.5) / 5.0) * w;
                    let (dx, dy) = (b.cos(), b.sin());
                    walls
                        .iter()
                        .filter_map(|&[x0, y0, x1, y1]| {
                            // Ray (x, y) + t·d against the segment.
                            let (ex, ey) = (x1 - x0, y1 - y0);
                            let den = dx * ey - dy * ex;
                            if den.abs() < 1e-12 {
                                return None;
                            }
                            let t = ((x0 - x) * ey - (y0 - y) * ex) / den;
                            let u = ((x0 - x) * dy - (y0 - y) * dx) / den;
                            (t > 0.0 && (0.0..=1.0).contains(&u)).then_some(t)
                        })
                        .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.min(t))))
                })
                .fold(f32::INFINITY, |m, t| m.min(t as f32));
        }
        rop
    }

    #[test]
    fn a_turn_that_moves_the_robot_is_refined_with_the_shift() {
        // A wall slanting across the view at 0.45-0.8 m that ends at 29°,
        // and a post at 0.3 m.
        let walls = [
            [0.6, -0.5, 0.4, 0.22],
            [0.22, 0.05, 0.25, 0.05],
            [0.25, 0.05, 0.25, 0.08],
            [0.25, 0.08, 0.22, 0.08],
            [0.22, 0.08, 0.22, 0.05],
        ];
        // The robot turns 28° and its centre moves 3 mm (toward the wall
        // and sideways), as a turn about a point 6 mm off the centre does.
        let before = cast_view(&walls, 0.0, 0.0, 10.0);
        let after = cast_view(&walls, 0.0025, -0.0018, 38.0);
        // Ray-cast bins share no errors with their neighbours: each is an
        // independent sample.
        let config = MatchConfig {
            correlation_rad: before.bin_width_rad,
            ..MatchConfig::default()
        };
        let plain = MatchConfig {
            turn_shift_m: 0.0,
            ..config.clone()
        };
        let alone = match_turn(&before, &after, 30f64.to_radians(), &plain);
        let with_shift = match_turn(&before, &after, 30f64.to_radians(), &config);
        assert!(
            !alone.fallback && !with_shift.fallback,
            "{alone:?} {with_shift:?}"
        );
        let err = |e: &TurnEstimate| (e.turn_rad.to_degrees() - 28.0).abs();
        assert!(
            err(&with_shift) < 0.2,
            "refined: {}",
            with_shift.turn_rad.to_degrees()
        );
        assert!(
            err(&alone) > 4.0 * err(&with_shift),
            "alone {} refined {}",
            alone.turn_rad.to_degrees(),
            with_shift.turn_rad.to_degrees()
        );
    }

    #[test]
    fn open_floor_falls_back_to_the_command() {
        let mut a = Rop::covering(-0.5, 0.5, 1f64.to_radians(), 0.9).unwrap();
        a.range_m.iter_mut().for_each(|r| *r = f32::INFINITY);
        let est = match_turn(&a, &a.clone(), 0.5, &MatchConfig::default());
        assert!(est.fallback && est.evidence == Evidence::Aperture);
        assert_eq!(est.turn_rad, 0.5);
    }

    /// Two views that share a 12° sliver, with a clear profile in it: the
    /// true shift matches exactly, but no shift three bins or more away
    /// overlaps enough to be compared, so the basin's arms cannot be
    /// weighed and the match is not trusted. With three bins more of
    /// overlap each way it is.
    #[test]
    fn a_minimum_whose_basin_cannot_be_tested_is_not_trusted() {
        let w = 1f64.to_radians();
        let shared = |i: usize| 0.4 + 0.05 * (i as f32 * 1.7).sin() + 0.1 * (i % 4 == 0) as u8 as f32;
        let views = |seen: usize| {
            let mut before = Rop::covering(-0.5, 0.5, w, 0.9).unwrap();
            let mut after = before.clone();
            before.range_m.iter_mut().for_each(|r| *r = f32::NAN);
            after.range_m.iter_mut().for_each(|r| *r = f32::NAN);
            // After a turn by 20 bins, after's bin i sees before's i + 20.
            for i in 10..10 + seen {
                after.range_m[i] = shared(i);
                before.range_m[i + 20] = shared(i);
            }
            (before, after)
        };
        let turn = 20.0 * w;
        let (before, after) = views(12);
        let est = match_turn(&before, &after, turn, &MatchConfig::default());
        assert!(est.fallback, "{est:?}");
        assert_eq!(est.evidence, Evidence::Ambiguous);
        assert_eq!(est.confidence, 0.0);
        let (before, after) = views(18);
        let est = match_turn(&before, &after, turn, &MatchConfig::default());
        assert!(!est.fallback, "{est:?}");
        assert!((est.turn_rad - turn).abs() < 0.1 * w, "{est:?}");
    }

    #[test]
    fn periodic_profiles_are_ambiguous() {
        let mut a = Rop::covering(-0.5, 0.5, 1f64.to_radians(), 0.9).unwrap();
        for i in 0..a.len() {
            a.range_m[i] = if (i / 4) % 2 == 0 { 0.4 } else { 0.8 };
        }
        let est = match_turn(&a, &a.clone(), 0.0, &MatchConfig::default());
        assert!(est.fallback && est.evidence == Evidence::Ambiguous, "{est:?}");
    }
}
