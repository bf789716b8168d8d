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
pub mod fft;
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

/// A profile as rotation matching reads it: its ranges, reaches and
/// colours, and where the sensor has one, the ranges of an intermittent
/// cue. A plain `&Rop` is a view without the cue.
#[derive(Debug, Clone, Copy)]
pub struct MatchView<'a> {
    /// The profile.
    pub rop: &'a Rop,
    /// One range per bin found by a cue that finds true obstacles but not
    /// in every view (a camera's texture cue near the soft limit): finite
    /// where it found an obstacle; empty where the sensor has no such cue.
    /// Matching compares these where both views have one in a bin, and
    /// elsewhere the profile's ranges: that such a cue found nothing is no
    /// evidence.
    pub cue_m: &'a [f32],
}

impl<'a> From<&'a Rop> for MatchView<'a> {
    fn from(rop: &'a Rop) -> Self {
        Self { rop, cue_m: &[] }
    }
}

impl MatchView<'_> {
    /// The range the cue found in bin `i`, if any.
    pub fn cue(&self, i: usize) -> Option<f32> {
        self.cue_m.get(i).copied().filter(|r| r.is_finite())
    }
}

/// Verifies a turn: the angle between `before` and `after` nearest to
/// `commanded_rad` within the window. Both profiles must have the same bin
/// width (any width, any field of view: laser scans too); either may be a
/// plain `&Rop` or a [`MatchView`] with a sensor's intermittent cue.
///
/// # Panics
/// When the bin widths differ by more than a part in a million.
pub fn match_turn<'a, 'b>(
    before: impl Into<MatchView<'a>>,
    after: impl Into<MatchView<'b>>,
    commanded_rad: f64,
    config: &MatchConfig,
) -> TurnEstimate {
    let (before, after): (MatchView, MatchView) = (before.into(), after.into());
    let w = before.rop.bin_width_rad;
    assert!(
        (after.rop.bin_width_rad - w).abs() <= 1e-6 * w,
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
    let offset = ((after.rop.bearing_start_rad - before.rop.bearing_start_rad) / w).round() as i64;
    let k_cmd = (commanded_rad / w).round() as i64;
    let k_win = (config.window_rad / w).ceil() as i64;
    let (a, b) = (cells(after), cells(before));
    let min_overlap = ((config.min_overlap_rad / w).ceil() as usize).max(3);
    // The cost of every turn in the window, at the profiles' own noise.
    let window = (offset, k_cmd - k_win, k_cmd + k_win);
    let Some((curve, sigma)) = cost_curves(&a, &b, window, min_overlap, config) else {
        return fallback(Evidence::NoOverlap, 0.0, 0, None);
    };
    let Some(best) = best_shift(&curve, min_overlap) else {
        return fallback(Evidence::NoOverlap, 0.0, 0, None);
    };
    let ranked = Ranked {
        curve: &curve,
        best,
        min_overlap,
    };
    let k_best = curve.k_lo + best as i64;
    let overlap_bins = curve.overlap[best];
    // Structure of the overlap at the best shift: is there anything to match?
    let structure = structure(&a, &b, offset + k_best, sigma as f64);
    if structure < config.min_structure {
        return fallback(Evidence::Aperture, 0.0, overlap_bins, Some(k_best as f64 * w));
    }
    // How far the best stands out from its rivals.
    let confidence = ranked.confidence(w, config);
    // Below one bin.
    let k = k_best as f64 + ranked.sub_bin();
    let at_edge = best == 0 || best + 1 == curve.cost.len();
    if at_edge || confidence < config.min_confidence {
        return fallback(Evidence::Ambiguous, confidence, overlap_bins, Some(k * w));
    }
    let evidence = if curve.colour_pairs[best] > 0 {
        Evidence::RangeAndColour
    } else {
        Evidence::Range
    };
    // With the robot's small shift during the turn.
    let refined = (config.turn_shift_m > 0.0)
        .then(|| refine_with_shift(before.rop, after.rop, k * w, sigma as f64, config))
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

/// The lowest cost among the shifts that overlap enough.
fn best_shift(curve: &CostCurve, min_overlap: usize) -> Option<usize> {
    (0..curve.cost.len())
        .filter(|&j| curve.comparable(j, min_overlap))
        .min_by(|&x, &y| curve.cost[x].total_cmp(&curve.cost[y]))
}

/// The cost curve of cells `a` (after) shifted against `b` (before) over
/// `window` = (offset of `a`'s first bin in `b`'s, first and last shift),
/// and the inverse-range noise it is scaled by.
///
/// A first pass with the nominal noise; then the noise measured in the
/// residuals of that best match sets the scale of the costs and of the
/// significance (the profiles' own noise, not an assumed one).
fn cost_curves(
    a: &[Cell],
    b: &[Cell],
    window: (i64, i64, i64),
    min_overlap: usize,
    config: &MatchConfig,
) -> Option<(CostCurve, f32)> {
    let (offset, k_lo, k_hi) = window;
    // The profile after the turn, padded to whole blocks of the inner
    // loop; the one before, over every bin some shift compares with it.
    let a_len = a.len().div_ceil(LANES) as i64 * LANES as i64;
    let sa = Signals::new(a, 0..a_len);
    let sb = Signals::new(b, offset + k_lo..offset + k_hi + a_len);
    // Each informative pair's inverse-range gap, kept from the first pass
    // so that the second need not compare the profiles again; in the
    // thread's buffer, which every pass writes before it reads.
    KEPT_GAPS.with_borrow_mut(|gaps| {
        let nominal = cost_curve(&sa, &sb, k_lo, k_hi, config.inverse_range_sigma, config, gaps);
        let first = best_shift(&nominal, min_overlap)?;
        let sigma = residual_sigma(a, b, offset + k_lo + first as i64)
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
    })
}

/// A cost curve with its best shift, weighed against its rivals.
struct Ranked<'c> {
    curve: &'c CostCurve,
    best: usize,
    min_overlap: usize,
}

impl Ranked<'_> {
    /// Whether shift `j` can rival the best: it overlaps enough, and rests
    /// on at least half as many informative pairs (a mean cost over far
    /// fewer pairs is judged on too little).
    fn valid(&self, j: usize) -> bool {
        let c = self.curve;
        c.comparable(j, self.min_overlap) && 2 * c.informative[j] >= c.informative[self.best]
    }

    /// The cost of shift `j`, infinite where it cannot rival.
    fn cost(&self, j: usize) -> f64 {
        if self.valid(j) {
            self.curve.cost[j]
        } else {
            f64::INFINITY
        }
    }

    /// Distinctness as significance, mapped to `[0, 1]`: a rival's excess
    /// cost summed over the informative bins, in standard deviations of a
    /// sum of that many bins' noise costs (neighbouring fine bins share
    /// their errors: one sample per `correlation_rad`). The rivals are the
    /// lowest other local minimum (window ends included: a competitor may
    /// lie beyond them) and the lower arm of the best one's basin (a broad
    /// bowl is no verification).
    fn confidence(&self, w: f64, config: &MatchConfig) -> f64 {
        let (curve, best) = (self.curve, self.best);
        let basin = ((config.basin_rad / w).ceil() as usize).max(2);
        let last = curve.cost.len() - 1;
        let is_local_min = |j: usize| {
            self.valid(j)
                && (j == 0 || self.cost(j) <= self.cost(j - 1))
                && (j == last || self.cost(j) <= self.cost(j + 1))
        };
        let other_min = (0..curve.cost.len())
            .filter(|&j| j.abs_diff(best) > basin && is_local_min(j))
            .map(|j| self.cost(j))
            .fold(f64::INFINITY, f64::min);
        let arm = [best.checked_sub(basin), Some(best + basin).filter(|&j| j <= last)]
            .into_iter()
            .flatten()
            .map(|j| self.cost(j))
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
        // A basin neither of whose arms can be weighed was never tested:
        // its minimum verifies nothing, however alone it stands.
        let z_best = if arm.is_finite() {
            z(other_min).min(z(arm))
        } else {
            0.0
        };
        if z_best.is_finite() {
            z_best / (z_best + CONFIDENCE_HALF_Z)
        } else {
            1.0
        }
    }

    /// The best shift's offset below one bin: the vertex of a parabola
    /// through it and its neighbours (0 where they cannot rival it).
    fn sub_bin(&self) -> f64 {
        let (curve, best) = (self.curve, self.best);
        if best > 0 && best + 1 < curve.cost.len() && self.valid(best - 1) && self.valid(best + 1) {
            let (cm, c0, cp) = (curve.cost[best - 1], curve.cost[best], curve.cost[best + 1]);
            let denom = cm - 2.0 * c0 + cp;
            if denom > 1e-12 {
                return (0.5 * (cm - cp) / denom).clamp(-0.5, 0.5);
            }
        }
        0.0
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
mod tests;
