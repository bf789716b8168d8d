//! Scores of the engine's results against ground truth.

use pirouette_io::TruthRop;
use pirouette_profile::Rop;
use serde::Serialize;

/// Relative error within which a range counts as measured well.
pub const WITHIN_REL: f64 = 0.10;

/// Per-bin tallies of measured profiles against true ones.
#[derive(Debug, Clone, Default)]
pub struct ProfileTally {
    /// Relative range errors `(measured − true) / true` over truth bins
    /// that were measured.
    pub rel_errors: Vec<f64>,
    /// Truth bins (a true obstacle within the soft range limit).
    pub truth_bins: usize,
    /// Truth bins measured within [`WITHIN_REL`].
    pub within: usize,
    /// Truth bins with no measured range.
    pub missed: usize,
    /// Bins inside the view with no true obstacle within the limit.
    pub free_bins: usize,
    /// Free bins that were given a range.
    pub false_ranges: usize,
}

/// The scores of a [`ProfileTally`].
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ProfileScores {
    /// Median of |relative range error| over measured truth bins.
    pub median_abs_rel_error: f64,
    /// Median of the signed relative range error (negative: ranges short).
    pub median_rel_bias: f64,
    /// Share of truth bins measured within 10 %.
    pub within_10pct: f64,
    /// Share of truth bins missed.
    pub missed: f64,
    /// Share of obstacle-free bins given a false range.
    pub false_range: f64,
    /// Truth bins counted.
    pub truth_bins: usize,
    /// Obstacle-free bins counted.
    pub free_bins: usize,
}

fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        (s[n / 2 - 1] + s[n / 2]) / 2.0
    }
}

impl ProfileTally {
    /// Adds one frame: every truth bin against the nearest reliable range
    /// of the measured bins whose centres fall inside it (any bin width).
    pub fn add(&mut self, measured: &Rop, truth: &TruthRop) {
        let w_t = truth.bin_deg.to_radians();
        let t0 = truth.bearing_start_deg.to_radians();
        let mut nearest = vec![None::<f32>; truth.range.len()];
        for i in 0..measured.len() {
            let k = ((measured.bin_centre_rad(i) - t0) / w_t).floor();
            if k < 0.0 || k as usize >= nearest.len() {
                continue;
            }
            if let Some(r) = measured.reliable(i) {
                let slot = &mut nearest[k as usize];
                *slot = Some(slot.map_or(r, |s: f32| s.min(r)));
            }
        }
        for (t, m) in truth.range.iter().zip(&nearest) {
            match (t, m) {
                (Some(t), Some(m)) => {
                    self.truth_bins += 1;
                    let e = (*m as f64 - t) / t;
                    self.rel_errors.push(e);
                    if e.abs() <= WITHIN_REL {
                        self.within += 1;
                    }
                }
                (Some(_), None) => {
                    self.truth_bins += 1;
                    self.missed += 1;
                }
                (None, m) => {
                    self.free_bins += 1;
                    if m.is_some() {
                        self.false_ranges += 1;
                    }
                }
            }
        }
    }

    /// Adds another tally.
    pub fn merge(&mut self, other: &ProfileTally) {
        self.rel_errors.extend_from_slice(&other.rel_errors);
        self.truth_bins += other.truth_bins;
        self.within += other.within;
        self.missed += other.missed;
        self.free_bins += other.free_bins;
        self.false_ranges += other.false_ranges;
    }

    /// The scores.
    pub fn scores(&self) -> ProfileScores {
        let share = |a: usize, b: usize| if b == 0 { f64::NAN } else { a as f64 / b as f64 };
        let abs: Vec<f64> = self.rel_errors.iter().map(|e| e.abs()).collect();
        ProfileScores {
            median_abs_rel_error: median(&abs),
            median_rel_bias: median(&self.rel_errors),
            within_10pct: share(self.within, self.truth_bins),
            missed: share(self.missed, self.truth_bins),
            false_range: share(self.false_ranges, self.free_bins),
            truth_bins: self.truth_bins,
            free_bins: self.free_bins,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tally_counts_each_case() {
        let truth = TruthRop {
            bearing_start_deg: -2.0,
            bin_deg: 1.0,
            range: vec![Some(0.5), Some(0.5), None, None],
        };
        let mut m = Rop::empty(-2f64.to_radians(), 0.5f64.to_radians(), 8, 0.9);
        m.range_m = vec![0.52, 0.6, f32::NAN, f32::NAN, 0.3, f32::INFINITY, 1.5, f32::NAN];
        let mut t = ProfileTally::default();
        t.add(&m, &truth);
        // Bin 0: nearest of 0.52 and 0.6 → +4 %. Bin 1: missed. Bin 2: false
        // range 0.3. Bin 3: 1.5 is beyond the soft limit, not a range.
        assert_eq!(
            (t.truth_bins, t.within, t.missed, t.free_bins, t.false_ranges),
            (2, 1, 1, 2, 1)
        );
        let s = t.scores();
        assert!((s.median_abs_rel_error - 0.04).abs() < 1e-6);
        assert_eq!(s.missed, 0.5);
    }
}
