//! Inserting one radial sweep into the occupancy grid: a 360° profile at
//! 0.25° (1,440 bearings), 0.9 m soft limit, 1 cm cells. Throughput counts
//! cell visits (every cell every ray passes through); the baseline beside
//! it is the bare traversal of the same rays.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use pirouette::geom::Pose2;
use pirouette::grid::{traverse, GridConfig, OccupancyGrid};
use pirouette::profile::Rop;
use std::hint::black_box;

const BLIND_M: f64 = 0.09;

/// A sweep in a 1.5 × 1.3 m field seen from (0.5, 0.4): walls, some of them
/// beyond the limit.
fn sweep() -> Rop {
    let w = 0.25f64.to_radians();
    let mut rop = Rop::covering(-std::f64::consts::PI, std::f64::consts::PI - w, w, 0.9).expect("valid");
    let (x0, y0, x1, y1) = (-0.5, -0.4, 1.0, 0.9);
    for i in 0..rop.len() {
        let b = rop.bin_centre_rad(i);
        let (c, s) = (b.cos(), b.sin());
        let wall = |d: f64, lo: f64, hi: f64| {
            if d > 0.0 {
                hi / d
            } else if d < 0.0 {
                lo / d
            } else {
                f64::INFINITY
            }
        };
        let (tx, ty) = (wall(c, x0, x1), wall(s, y0, y1));
        rop.range_m[i] = tx.min(ty) as f32;
    }
    rop
}

fn visits(rop: &Rop, s: f64) -> u64 {
    let mut n = 0u64;
    for i in 0..rop.len() {
        let r = (rop.range_m[i] as f64).min(rop.max_range_m as f64);
        let (c, sn) = (rop.bin_centre_rad(i).cos(), rop.bin_centre_rad(i).sin());
        traverse([BLIND_M * c, BLIND_M * sn], [r * c, r * sn], s, |_, _| n += 1);
    }
    n
}

fn insert_sweep(c: &mut Criterion) {
    let rop = sweep();
    let config = GridConfig::default();
    let cells = visits(&rop, config.resolution_m);
    let mut group = c.benchmark_group("grid_insert_sweep");
    group.throughput(Throughput::Elements(cells));
    let mut grid = OccupancyGrid::new(config.clone()).expect("valid");
    grid.insert_profile(&Pose2::IDENTITY, &rop, BLIND_M);
    group.bench_function("insert_profile", |b| {
        b.iter(|| grid.insert_profile(black_box(&Pose2::IDENTITY), black_box(&rop), BLIND_M))
    });
    group.bench_function("traverse_only", |b| {
        b.iter(|| visits(black_box(&rop), config.resolution_m))
    });
    group.finish();
}

criterion_group!(benches, insert_sweep);
criterion_main!(benches);
