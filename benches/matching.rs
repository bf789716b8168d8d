//! Rotation matching: one turn between two profiles of a 60° view, ±30°
//! search window, at 1° and 0.2° bins. The direct search (the engine's
//! matcher, robust measure, with its noise estimate and sub-bin refinement)
//! beside an FFT-based correlation that scores every shift's masked sum of
//! squared differences at once (the baseline: no robust cost, no colour,
//! no refinement).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use pirouette::profile::matching::{match_turn, MatchConfig};
use pirouette::profile::Rop;
use rustfft::{num_complex::Complex, FftPlanner};
use std::hint::black_box;

/// A 360° scene of walls and obstacles around the robot.
fn scene(bearing: f64) -> f32 {
    let d = bearing.to_degrees().rem_euclid(360.0);
    let k = (d / 37.0).floor();
    let local = d - k * 37.0;
    if local < 6.0 + (k % 4.0) * 2.0 {
        0.3 + 0.04 * (k % 5.0) as f32
    } else {
        (0.7 + 0.3 * (d.to_radians() * 2.0).sin()) as f32
    }
}

fn view(heading_deg: f64, bin_deg: f64) -> Rop {
    let w = bin_deg.to_radians();
    let mut rop = Rop::covering(-30f64.to_radians(), 30f64.to_radians(), w, 0.9).expect("valid");
    for i in 0..rop.len() {
        rop.range_m[i] = scene(heading_deg.to_radians() + rop.bin_centre_rad(i));
    }
    rop
}

/// Masked SSD of every shift by FFT: Σ m_a m_b (a − b)² expanded into four
/// cross-correlations, then the best shift within the window.
struct FftMatcher {
    planner: FftPlanner<f32>,
}

impl FftMatcher {
    fn best_shift(&mut self, before: &Rop, after: &Rop, k_lo: i64, k_hi: i64) -> i64 {
        let (na, nb) = (after.len(), before.len());
        let n = (na + nb).next_power_of_two();
        let fwd = self.planner.plan_fft_forward(n);
        let inv = self.planner.plan_fft_inverse(n);
        let signal = |r: f32| if r.is_finite() { 1.0 / r } else { 0.0 };
        let spectra = |values: &dyn Fn(usize) -> f32, len: usize| {
            let mut buf = vec![Complex::new(0.0f32, 0.0); n];
            for (i, x) in buf.iter_mut().enumerate().take(len) {
                *x = Complex::new(values(i), 0.0);
            }
            fwd.process(&mut buf);
            buf
        };
        let a = |i: usize| signal(after.range_m[i]);
        let b = |i: usize| signal(before.range_m[i]);
        let ma = |i: usize| (!after.range_m[i].is_nan()) as u8 as f32;
        let mb = |i: usize| (!before.range_m[i].is_nan()) as u8 as f32;
        let fa2 = spectra(&|i| ma(i) * a(i) * a(i), na);
        let fa1 = spectra(&|i| ma(i) * a(i), na);
        let fma = spectra(&ma, na);
        let fb2 = spectra(&|i| mb(i) * b(i) * b(i), nb);
        let fb1 = spectra(&|i| mb(i) * b(i), nb);
        let fmb = spectra(&mb, nb);
        // corr(x, y)(k) = Σ x_i y_{i+k}  ⇔  IFFT(conj(X) · Y).
        let mut ssd = vec![Complex::new(0.0f32, 0.0); n];
        let mut count = vec![Complex::new(0.0f32, 0.0); n];
        for i in 0..n {
            ssd[i] = fa2[i].conj() * fmb[i] + fma[i].conj() * fb2[i] - fa1[i].conj() * fb1[i] * 2.0;
            count[i] = fma[i].conj() * fmb[i];
        }
        inv.process(&mut ssd);
        inv.process(&mut count);
        let at = |k: i64| (k.rem_euclid(n as i64)) as usize;
        (k_lo..=k_hi)
            .filter(|&k| count[at(k)].re > 10.0 * n as f32)
            .min_by(|&x, &y| (ssd[at(x)].re / count[at(x)].re).total_cmp(&(ssd[at(y)].re / count[at(y)].re)))
            .unwrap_or(0)
    }
}

fn matching(c: &mut Criterion) {
    let mut group = c.benchmark_group("match_turn");
    group.throughput(Throughput::Elements(1));
    let config = MatchConfig {
        window_rad: 30f64.to_radians(),
        ..MatchConfig::default()
    };
    let mut fft = FftMatcher {
        planner: FftPlanner::new(),
    };
    for bin_deg in [1.0, 0.2] {
        let (before, after) = (view(40.0, bin_deg), view(68.6, bin_deg));
        let label = format!("{bin_deg}deg");
        // Both find the true shift before they are timed.
        let est = match_turn(&before, &after, 30f64.to_radians(), &config);
        assert!(!est.fallback && (est.turn_rad.to_degrees() - 28.6).abs() < bin_deg);
        let k_cmd = (30.0 / bin_deg) as i64;
        let k_win = (30.0 / bin_deg) as i64;
        let k = fft.best_shift(&before, &after, k_cmd - k_win, k_cmd + k_win);
        assert!(
            (k as f64 * bin_deg - 28.6).abs() <= bin_deg,
            "fft found {}",
            k as f64 * bin_deg
        );
        group.bench_with_input(
            BenchmarkId::new("direct", &label),
            &(&before, &after),
            |b, (p, q)| b.iter(|| match_turn(black_box(p), black_box(q), 30f64.to_radians(), &config)),
        );
        group.bench_with_input(
            BenchmarkId::new("fft-ssd", &label),
            &(&before, &after),
            |b, (p, q)| b.iter(|| fft.best_shift(black_box(p), black_box(q), k_cmd - k_win, k_cmd + k_win)),
        );
    }
    group.finish();
}

criterion_group!(benches, matching);
criterion_main!(benches);
