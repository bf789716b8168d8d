//! The baseline turn matcher: every shift's masked mean squared difference
//! of inverse ranges at once, by FFT cross-correlation. No robust cost, no
//! colour, no noise model; a parabola through the best shift and its
//! neighbours gives a fraction of a bin. It stands beside [`super::match_turn`]
//! in benchmarks.

use crate::Rop;
use rustfft::{num_complex::Complex, FftPlanner};

/// FFT cross-correlation of two profiles; keeps its FFT plans between calls.
pub struct FftCorrelation {
    planner: FftPlanner<f32>,
}

impl Default for FftCorrelation {
    fn default() -> Self {
        Self::new()
    }
}

impl std::fmt::Debug for FftCorrelation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("FftCorrelation")
    }
}

impl FftCorrelation {
    /// A matcher with no plans yet.
    pub fn new() -> Self {
        Self {
            planner: FftPlanner::new(),
        }
    }

    /// The turn from `before` to `after` within `window_rad` of
    /// `commanded_rad`, radians counter-clockwise: the shift whose seen bins
    /// (at least `min_overlap_rad` of them in common) differ least in mean
    /// squared inverse range. No return counts as inverse range 0; unseen
    /// bins are left out. `None` where the bin widths differ or no shift
    /// overlaps enough.
    pub fn match_turn(
        &mut self,
        before: &Rop,
        after: &Rop,
        commanded_rad: f64,
        window_rad: f64,
        min_overlap_rad: f64,
    ) -> Option<f64> {
        let w = before.bin_width_rad;
        if (after.bin_width_rad - w).abs() > 1e-9 * w || before.is_empty() || after.is_empty() {
            return None;
        }
        let (na, nb) = (after.len(), before.len());
        let n = (na + nb).next_power_of_two();
        let fwd = self.planner.plan_fft_forward(n);
        let inv = self.planner.plan_fft_inverse(n);
        let inverse = |r: f32| if r.is_finite() { 1.0 / r } else { 0.0 };
        let spectrum = |rop: &Rop, power: i32| {
            let mut buf = vec![Complex::new(0.0f32, 0.0); n];
            for (x, &r) in buf.iter_mut().zip(&rop.range_m) {
                if !r.is_nan() {
                    *x = Complex::new(inverse(r).powi(power), 0.0);
                }
            }
            fwd.process(&mut buf);
            buf
        };
        let (a2, a1, ma) = (spectrum(after, 2), spectrum(after, 1), spectrum(after, 0));
        let (b2, b1, mb) = (spectrum(before, 2), spectrum(before, 1), spectrum(before, 0));
        // Σ m_a m_b (a − b)² at every shift k (after's bin i against
        // before's bin i + k), as correlations: corr(x, y)(k) =
        // Σ x_i y_{i+k} = IFFT(conj(X)·Y)(k).
        let mut ssd: Vec<Complex<f32>> = (0..n)
            .map(|i| a2[i].conj() * mb[i] + ma[i].conj() * b2[i] - a1[i].conj() * b1[i] * 2.0)
            .collect();
        let mut count: Vec<Complex<f32>> = (0..n).map(|i| ma[i].conj() * mb[i]).collect();
        inv.process(&mut ssd);
        inv.process(&mut count);
        // Before's bin i + k lies at after's bin i turned by the offset
        // of their starts and k bins.
        let offset = before.bearing_start_rad - after.bearing_start_rad;
        let centre = ((commanded_rad - offset) / w).round() as i64;
        let half = (window_rad / w).ceil() as i64;
        let least = (min_overlap_rad / w).max(1.0) * n as f64;
        let at = |k: i64| k.rem_euclid(n as i64) as usize;
        let cost = |k: i64| {
            let c = f64::from(count[at(k)].re);
            (k.abs() < n as i64 / 2 && c >= least - 0.5 * n as f64).then(|| f64::from(ssd[at(k)].re) / c)
        };
        let best = (centre - half..=centre + half)
            .filter_map(|k| cost(k).map(|c| (k, c)))
            .min_by(|x, y| x.1.total_cmp(&y.1))?;
        let fraction = match (cost(best.0 - 1), cost(best.0 + 1)) {
            (Some(l), Some(r)) if l + r - 2.0 * best.1 > 0.0 => {
                (0.5 * (l - r) / (l + r - 2.0 * best.1)).clamp(-0.5, 0.5)
            }
            _ => 0.0,
        };
        Some(offset + (best.0 as f64 + fraction) * w)
    }
}
