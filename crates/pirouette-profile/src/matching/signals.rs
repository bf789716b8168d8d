//! The matching signal: each bin's inverse range, the reach it saw, its
//! colour and the intermittent cue's range, and how two bins compare.

use super::MatchView;

/// Per-bin matching signal.
#[derive(Debug, Clone, Copy)]
pub(super) struct Cell {
    /// Inverse range (0: nothing in sight); NaN: not seen.
    pub(super) inv: f32,
    /// The largest inverse range the bin allows: `inv`, but where nothing
    /// was in sight as far as the floor was seen, the inverse of that
    /// reach.
    pub(super) inv_hi: f32,
    /// Chromaticity shares (r, g) where the bin has a colour.
    pub(super) chroma: Option<[f32; 2]>,
    /// Inverse of the intermittent cue's range ([`MatchView::cue_m`]);
    /// NaN where it found nothing or the bin was not seen.
    pub(super) inv_c: f32,
}

/// The matching signal as contiguous arrays, for the inner loop: an absent
/// value is NaN, which every comparison of the loop treats as false, so
/// that the presence of a bin, an obstacle or a colour is a mask computed
/// from the values themselves and the loop vectorises. The five arrays
/// share one allocation.
pub(super) struct Signals {
    /// Bins per array.
    n: usize,
    /// Inverse range (0: nothing in sight; NaN where the bin was not seen),
    /// then the largest inverse range each bin allows (see [`Cell`]; NaN
    /// where the bin was not seen), then the two chromaticity shares (NaN
    /// where the bin has no colour), then the intermittent cue's inverse
    /// range (NaN where it found nothing), `n` each.
    data: Vec<f32>,
}

impl Signals {
    /// The signal of bins `range` of `cells`; bins outside the profile are
    /// absent.
    pub(super) fn new(cells: &[Cell], range: std::ops::Range<i64>) -> Self {
        let n = (range.end - range.start).max(0) as usize;
        let mut data = vec![f32::NAN; 5 * n];
        let (inv, rest) = data.split_at_mut(n);
        let (inv_hi, rest) = rest.split_at_mut(n);
        let (chroma_r, rest) = rest.split_at_mut(n);
        let (chroma_g, inv_c) = rest.split_at_mut(n);
        for (t, i) in range.enumerate() {
            let Some(c) = usize::try_from(i).ok().and_then(|i| cells.get(i)) else {
                continue;
            };
            if c.inv.is_nan() {
                continue;
            }
            inv[t] = c.inv;
            inv_hi[t] = c.inv_hi;
            inv_c[t] = c.inv_c;
            if let Some([r, g]) = c.chroma {
                chroma_r[t] = r;
                chroma_g[t] = g;
            }
        }
        Signals { n, data }
    }

    pub(super) fn inv(&self) -> &[f32] {
        &self.data[..self.n]
    }

    pub(super) fn inv_hi(&self) -> &[f32] {
        &self.data[self.n..2 * self.n]
    }

    pub(super) fn chroma_r(&self) -> &[f32] {
        &self.data[2 * self.n..3 * self.n]
    }

    pub(super) fn chroma_g(&self) -> &[f32] {
        &self.data[3 * self.n..4 * self.n]
    }

    pub(super) fn inv_c(&self) -> &[f32] {
        &self.data[4 * self.n..]
    }
}

pub(super) fn cells(view: MatchView) -> Vec<Cell> {
    let rop = view.rop;
    (0..rop.len())
        .map(|i| {
            let r = rop.range_m[i];
            let inv = if r.is_nan() {
                f32::NAN
            } else if r.is_infinite() {
                0.0
            } else {
                1.0 / r.max(1e-3)
            };
            let inv_hi = if r == f32::INFINITY {
                1.0 / rop.free_reach(i).max(1e-3)
            } else {
                inv
            };
            let inv_c = match view.cue(i) {
                Some(c) if !inv.is_nan() => 1.0 / c.max(1e-3),
                _ => f32::NAN,
            };
            Cell {
                inv,
                inv_hi,
                chroma: rop.colour[i].filter(|_| r.is_finite()).map(|c| c.chromaticity()),
                inv_c,
            }
        })
        .collect()
}

/// The gap between the inverse-range intervals of two seen bins (see
/// [`Cell`]): for two ranges, the absolute difference of their inverses;
/// where both bins have an intermittent cue's range, the difference of
/// those.
pub(super) fn gap(a: &Cell, b: &Cell) -> f32 {
    if !(a.inv_c.is_nan() || b.inv_c.is_nan()) {
        return (a.inv_c - b.inv_c).abs();
    }
    (a.inv - b.inv_hi).max(b.inv - a.inv_hi).max(0.0)
}

/// Whether a pair of seen bins can disagree: one of them sees an obstacle
/// within the other's reach. Two bins with nothing in sight agree
/// trivially, and an obstacle beyond the floor the other bin saw is no
/// evidence either way. Two bins that both have an intermittent cue's
/// range can disagree too.
pub(super) fn informative(a: &Cell, b: &Cell) -> bool {
    !(a.inv_c.is_nan() || b.inv_c.is_nan())
        || (a.inv > 0.0 && a.inv >= b.inv_hi)
        || (b.inv > 0.0 && b.inv >= a.inv_hi)
}
