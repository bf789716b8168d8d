//! The cost of every shift in the window: the vectorised pass over the
//! overlap, and the same curve rescaled to another noise.

use super::signals::Signals;
use super::{MatchConfig, Measure};
use rustdct::DctPlanner;

/// Costs of every integer shift `k` in `k_lo..=k_hi`: after bin `i` against
/// before bin `i + offset + k`.
#[derive(Clone)]
pub(super) struct CostCurve {
    pub(super) k_lo: i64,
    /// Mean cost over the informative pairs.
    pub(super) cost: Vec<f64>,
    /// Pairs of seen bins.
    pub(super) overlap: Vec<usize>,
    /// Pairs that can disagree (see [`informative`](super::signals::informative)): pairs that both see
    /// nothing agree trivially and would favour larger overlaps.
    pub(super) informative: Vec<usize>,
    /// Whether any shift has an informative pair.
    pub(super) any_informative: bool,
    pub(super) colour_pairs: Vec<usize>,
    /// The colour term's sum per shift (it does not depend on the range
    /// noise).
    pub(super) colour_cost: Vec<f32>,
    /// Per shift, the bins of the profile after the turn that whole blocks
    /// of the inner loop compared (where both profiles could be seen);
    /// every other pair adds nothing.
    pub(super) compared: Vec<std::ops::Range<usize>>,
}

impl CostCurve {
    /// Whether shift `j` can be weighed at all: its overlap is at least
    /// `min_overlap` bins, and some pair in it could disagree (unless no
    /// shift has such a pair: open floor, which the structure test
    /// catches). A shift that compares nothing contradicts nothing, which
    /// is no evidence for it: where one profile saw open floor only near,
    /// a shift can put every obstacle of the other beyond that floor.
    pub(super) fn comparable(&self, j: usize, min_overlap: usize) -> bool {
        self.overlap[j] >= min_overlap && (self.informative[j] > 0 || !self.any_informative)
    }

    /// The same curve at another range noise, from the informative pairs'
    /// gaps that [`cost_curve`] kept; the sums run in the
    /// same lanes and order, so the result is the one a new pass would give.
    /// Not for the DCT measure, whose range term is not a sum over pairs.
    pub(super) fn rescaled(
        mut self,
        gaps: &[f32],
        inverse_range_sigma: f32,
        config: &MatchConfig,
    ) -> CostCurve {
        debug_assert!(
            config.measure != Measure::Dct,
            "the DCT term is no sum over pairs"
        );
        let inv_s = 1.0 / inverse_range_sigma;
        let compared = &self.compared;
        let range_costs = match config.measure {
            Measure::Absolute => range_sums(gaps, compared, inv_s, |e: f32| e.abs()),
            Measure::Squared | Measure::Dct => range_sums(gaps, compared, inv_s, |e: f32| e * e),
            Measure::Robust => range_sums(gaps, compared, inv_s, |e: f32| (e * e).min(9.0)),
        };
        for (j, cost) in self.cost.iter_mut().enumerate() {
            *cost = if self.overlap[j] == 0 {
                f64::INFINITY
            } else if self.informative[j] == 0 {
                0.0
            } else {
                (range_costs[j] as f64 + config.colour_weight as f64 * self.colour_cost[j] as f64)
                    / self.informative[j] as f64
            };
        }
        self
    }
}

impl CostCurve {
    /// Shifts `k_lo..k_lo + n`, none compared yet.
    fn unmatched(k_lo: i64, n: usize) -> Self {
        Self {
            k_lo,
            cost: vec![f64::INFINITY; n],
            overlap: vec![0; n],
            informative: vec![0; n],
            any_informative: false,
            colour_pairs: vec![0; n],
            colour_cost: vec![0.0; n],
            compared: vec![0..0; n],
        }
    }
}

/// For each of `n` shifts, the bins of `sa` compared: after's bin `i`
/// meets before's `sb[i + j]` at shift `j`, both seen only within
/// `lo..hi`, widened to whole blocks of [`LANES`] so that each bin keeps
/// its lane.
fn compared_blocks(sa: &Signals, sb: &Signals, n: usize) -> Vec<std::ops::Range<usize>> {
    // The bins each profile saw, first to last.
    let seen = |inv: &[f32]| {
        let first = inv.iter().position(|x| !x.is_nan()).unwrap_or(inv.len());
        let last = inv.iter().rposition(|x| !x.is_nan()).map_or(first, |l| l + 1);
        first..last
    };
    let (seen_a, seen_b) = (seen(sa.inv()), seen(sb.inv()));
    (0..n)
        .map(|j| {
            let lo = seen_a.start.max(seen_b.start.saturating_sub(j));
            let hi = seen_a.end.min(seen_b.end.saturating_sub(j));
            if lo < hi {
                lo / LANES * LANES..hi.div_ceil(LANES) * LANES
            } else {
                0..0
            }
        })
        .collect()
}

thread_local! {
    /// The buffer of [`cost_curve`]'s kept gaps, one per thread and reused
    /// from match to match: it only grows, and is never cleared, since each
    /// pass writes every gap it reads (a fresh zeroed buffer was a tenth of
    /// a 1° match).
    ///
    /// # Memory
    /// Four bytes per shift and compared bin of the largest match the
    /// thread has made: 16 KB for 1° bins and a ±30° window over a 60°
    /// view, 370 KB for 0.2° bins; held until the thread ends.
    pub(super) static KEPT_GAPS: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// The costs of shifts `k_lo..=k_hi`: `sa` is the profile after the turn,
/// `sb` the one before from the bin that shift `k_lo` puts under `sa`'s
/// first bin (see [`match_turn`](super::match_turn)).
#[multiversion::multiversion(targets("x86_64+avx2", "x86_64+sse4.1", "aarch64+neon"))]
pub(super) fn cost_curve(
    sa: &Signals,
    sb: &Signals,
    k_lo: i64,
    k_hi: i64,
    inverse_range_sigma: f32,
    config: &MatchConfig,
    gaps: &mut Vec<f32>,
) -> CostCurve {
    let n = (k_hi - k_lo + 1).max(0) as usize;
    let mut curve = CostCurve::unmatched(k_lo, n);
    curve.compared = compared_blocks(sa, sb, n);
    let (inv_s, chroma_s) = (1.0 / inverse_range_sigma, 1.0 / config.chroma_sigma);
    let mut planner = (config.measure == Measure::Dct).then(DctPlanner::new);
    // The gaps of each shift's compared blocks, shift after shift, at the
    // start of `gaps` (every one is written below; a longer buffer's tail
    // is left as it is).
    let total = curve.compared.iter().map(|c| c.len()).sum();
    if gaps.len() < total {
        gaps.resize(total, 0.0);
    }
    let mut stored = 0;
    let mut xa = Vec::new();
    let mut xb = Vec::new();
    for j in 0..n {
        let blocks = curve.compared[j].clone();
        if blocks.is_empty() {
            continue;
        }
        let out = &mut gaps[stored..stored + blocks.len()];
        stored += blocks.len();
        let b = j + blocks.start..j + blocks.end;
        let pair = Pair {
            ia: &sa.inv()[blocks.clone()],
            ib: &sb.inv()[b.clone()],
            ha: &sa.inv_hi()[blocks.clone()],
            hb: &sb.inv_hi()[b.clone()],
            ra: &sa.chroma_r()[blocks.clone()],
            rb: &sb.chroma_r()[b.clone()],
            ga: &sa.chroma_g()[blocks.clone()],
            gb: &sb.chroma_g()[b.clone()],
            ca: &sa.inv_c()[blocks.clone()],
            cb: &sb.inv_c()[b],
            inv_s,
            chroma_s,
        };
        let sums = match config.measure {
            Measure::Absolute => pair.sums(|e: f32| e.abs(), out),
            Measure::Squared | Measure::Dct => pair.sums(|e: f32| e * e, out),
            Measure::Robust => pair.sums(|e: f32| (e * e).min(9.0), out),
        };
        let Sums {
            range_cost,
            colour_cost,
            n_range,
            n_info,
            n_colour,
        } = sums;
        if n_range == 0 {
            continue;
        }
        let mut range_cost = range_cost as f64;
        if let Some(planner) = planner.as_mut() {
            range_cost = pair.dct_cost(planner, (&mut xa, &mut xb));
        }
        curve.overlap[j] = n_range as usize;
        curve.informative[j] = n_info as usize;
        curve.colour_pairs[j] = n_colour as usize;
        curve.colour_cost[j] = colour_cost;
        // The sum now, the mean below.
        curve.cost[j] = range_cost + config.colour_weight as f64 * colour_cost as f64;
    }
    // The means, in a loop of their own: divisions issued back to back
    // overlap, where one at the end of each shift's pass held it up.
    for (cost, &n) in curve.cost.iter_mut().zip(&curve.informative) {
        if cost.is_finite() {
            *cost = if n == 0 { 0.0 } else { *cost / n as f64 };
        }
    }
    curve.any_informative = curve.informative.iter().any(|&n| n > 0);
    curve
}

/// Per shift, the range term over the stored gaps of the blocks it
/// `compared` (stored shift after shift; 0 for pairs that are not
/// informative, which cost nothing under every measure), summed in the
/// lanes of [`Pair::sums`].
#[inline(always)]
fn range_sums(
    gaps: &[f32],
    compared: &[std::ops::Range<usize>],
    inv_s: f32,
    rho: impl Fn(f32) -> f32,
) -> Vec<f32> {
    let mut rest = gaps;
    compared
        .iter()
        .map(|blocks| {
            let (shift, tail) = rest.split_at(blocks.len());
            rest = tail;
            let mut acc = [0f32; LANES];
            for block in shift.chunks_exact(LANES) {
                for l in 0..LANES {
                    acc[l] += rho(block[l] * inv_s);
                }
            }
            acc.iter().sum()
        })
        .collect()
}

/// Two aligned stretches of signal (see [`Signals`]).
struct Pair<'a> {
    ia: &'a [f32],
    ib: &'a [f32],
    ha: &'a [f32],
    hb: &'a [f32],
    ra: &'a [f32],
    rb: &'a [f32],
    ga: &'a [f32],
    gb: &'a [f32],
    ca: &'a [f32],
    cb: &'a [f32],
    inv_s: f32,
    chroma_s: f32,
}

/// Cost sums over an overlap.
struct Sums {
    range_cost: f32,
    colour_cost: f32,
    n_range: u32,
    n_info: u32,
    n_colour: u32,
}

/// Lanes of the partial sums in [`Pair::sums`]: eight `f32` fill one AVX
/// register.
pub(super) const LANES: usize = 8;

impl Pair<'_> {
    /// The range cost under [`Measure::Dct`]: the DCT distance of the
    /// inverse ranges of the bins both saw, in σ (`xa`, `xb`: buffers).
    fn dct_cost(&self, planner: &mut DctPlanner<f32>, (xa, xb): (&mut Vec<f32>, &mut Vec<f32>)) -> f64 {
        xa.clear();
        xb.clear();
        for (&a, &b) in self.ia.iter().zip(self.ib) {
            if !a.is_nan() && !b.is_nan() {
                xa.push(a * self.inv_s);
                xb.push(b * self.inv_s);
            }
        }
        dct_distance(planner, xa, xb)
    }

    /// The costs over the overlap, one monomorphised loop per measure:
    /// - a pair of bins counts when both were seen; its range cost, the gap
    ///   between the bins' intervals of inverse range, when one sees an
    ///   obstacle within the other's reach (two bins that both see nothing
    ///   agree trivially, and an obstacle beyond the floor the other saw
    ///   is no evidence); where both bins have an intermittent cue's range
    ///   ([`MatchView::cue_m`](super::MatchView::cue_m)), the difference of those instead, always
    ///   informative (one bin with such a range against one without is
    ///   compared by their ranges alone: the cue's silence is no evidence);
    /// - its colour cost when both have a colour: the larger difference of
    ///   the two chromaticity shares.
    ///
    /// Absent values are NaN, so each condition is a comparison that comes
    /// out false for them, and a term is added where its mask holds. The
    /// sums are kept in eight lanes (bin `i` adds to lane `i mod 8`) added
    /// up at the end, so the loop vectorises. Counts are sums of ones,
    /// exact in `f32`. Each pair's gap goes to `gaps` where the pair is
    /// informative, 0 elsewhere.
    #[inline(always)]
    fn sums(&self, rho: impl Fn(f32) -> f32, gaps: &mut [f32]) -> Sums {
        let n = self.ia.len();
        let pair = self;
        assert!(n % LANES == 0, "signals come in whole blocks");
        let mut acc = [[0f32; LANES]; 5];
        // Eight pairs of bins at a time, as fixed-size arrays the compiler
        // maps onto vector registers.
        #[inline(always)]
        #[allow(
            clippy::expect_used,
            reason = "callers pass a base with LANES values after it"
        )]
        fn block(c: &[f32], base: usize) -> &[f32; LANES] {
            c[base..base + LANES].try_into().expect("a whole block")
        }
        let when = |mask: bool, x: f32| if mask { x } else { 0.0 };
        for base in (0..n / LANES).map(|b| b * LANES) {
            let (ia, ib, ha, hb) = (
                block(pair.ia, base),
                block(pair.ib, base),
                block(pair.ha, base),
                block(pair.hb, base),
            );
            let (ra, rb, ga, gb) = (
                block(pair.ra, base),
                block(pair.rb, base),
                block(pair.ga, base),
                block(pair.gb, base),
            );
            let (ca, cb) = (block(pair.ca, base), block(pair.cb, base));
            let mut kept = [0f32; LANES];
            for l in 0..LANES {
                // Both seen: neither inverse range is NaN.
                // (`&` and `|`, not `&&` and `||`: no branches to keep.)
                let seen = !(ia[l].is_nan() | ib[l].is_nan());
                // Both have the intermittent cue's range (only seen bins
                // do).
                let cue = !(ca[l].is_nan() | cb[l].is_nan());
                // Informative: a bin sees an obstacle within the other's
                // reach (so the other would have seen it), or both have
                // the intermittent cue's range; false where either bin is
                // unseen.
                let info = cue | (ia[l] > 0.0) & (ia[l] >= hb[l]) | (ib[l] > 0.0) & (ib[l] >= ha[l]);
                // Both coloured (only bins seen to an obstacle are).
                let coloured = !(ra[l].is_nan() | rb[l].is_nan());
                let e = (ra[l] - rb[l]).abs().max((ga[l] - gb[l]).abs()) * pair.chroma_s;
                // The gap between the two intervals (for two ranges, their
                // difference), or between the intermittent cue's ranges.
                let interval_gap = (ia[l] - hb[l]).max(ib[l] - ha[l]).max(0.0);
                let gap = if cue { (ca[l] - cb[l]).abs() } else { interval_gap };
                kept[l] = when(info, gap);
                acc[0][l] += when(info, rho(gap * pair.inv_s));
                acc[1][l] += when(coloured, rho(e));
                acc[2][l] += when(seen, 1.0);
                acc[3][l] += when(info, 1.0);
                acc[4][l] += when(coloured, 1.0);
            }
            gaps[base..base + LANES].copy_from_slice(&kept);
        }
        let [range_cost, colour_cost, n_range, n_info, n_colour] = acc.map(|lanes| lanes.iter().sum::<f32>());
        Sums {
            range_cost,
            colour_cost,
            n_range: n_range as u32,
            n_info: n_info as u32,
            n_colour: n_colour as u32,
        }
    }
}

/// Squared distance of the lowest third of the DCT-II coefficients (the
/// paper keeps the low frequencies to suppress outliers), scaled so that
/// it is comparable with a sum of squared bin differences.
fn dct_distance(planner: &mut DctPlanner<f32>, xa: &mut [f32], xb: &mut [f32]) -> f64 {
    let n = xa.len();
    let dct = planner.plan_dct2(n);
    dct.process_dct2(xa);
    dct.process_dct2(xb);
    let keep = n.div_ceil(3);
    // DCT-II (unnormalised) scales energy by n/2 (n for the first term).
    let scale = 2.0 / n as f64;
    (0..keep).map(|i| ((xa[i] - xb[i]) as f64).powi(2) * scale).sum()
}
