//! Rotation matching: one turn between two profiles of a 60° view, ±30°
//! search window, at 1° and 0.2° bins. The direct search (the engine's
//! matcher, robust measure, with its noise estimate and sub-bin refinement)
//! beside an FFT-based correlation that scores every shift's masked sum of
//! squared differences at once (the baseline: no robust cost, no colour,
//! a parabola for the fraction of a bin).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use pirouette::profile::matching::fft::FftCorrelation;
use pirouette::profile::matching::{match_turn, MatchConfig};
use pirouette::profile::Rop;
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

fn matching(c: &mut Criterion) {
    let mut group = c.benchmark_group("match_turn");
    group.throughput(Throughput::Elements(1));
    let config = MatchConfig {
        window_rad: 30f64.to_radians(),
        ..MatchConfig::default()
    };
    let mut fft = FftCorrelation::new();
    let (cmd, win) = (30f64.to_radians(), 30f64.to_radians());
    for bin_deg in [1.0, 0.2] {
        let (before, after) = (view(40.0, bin_deg), view(68.6, bin_deg));
        let label = format!("{bin_deg}deg");
        // Both find the true shift before they are timed.
        let est = match_turn(&before, &after, 30f64.to_radians(), &config);
        assert!(!est.fallback && (est.turn_rad.to_degrees() - 28.6).abs() < bin_deg);
        let turn = fft
            .match_turn(&before, &after, cmd, win, config.min_overlap_rad)
            .expect("a turn");
        assert!(
            (turn.to_degrees() - 28.6).abs() <= bin_deg,
            "fft found {}",
            turn.to_degrees()
        );
        group.bench_with_input(
            BenchmarkId::new("direct", &label),
            &(&before, &after),
            |b, (p, q)| b.iter(|| match_turn(black_box(*p), black_box(*q), 30f64.to_radians(), &config)),
        );
        group.bench_with_input(
            BenchmarkId::new("fft-ssd", &label),
            &(&before, &after),
            |b, (p, q)| {
                b.iter(|| fft.match_turn(black_box(p), black_box(q), cmd, win, config.min_overlap_rad))
            },
        );
    }
    group.finish();
}

criterion_group!(benches, matching);
criterion_main!(benches);
