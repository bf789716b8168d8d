//! Sweep registration and whole-dataset mapping, on a render of the
//! built-in multi-sweep field (77 frames, 6 sweeps; rendered once per run).
//!
//! - `register_sweep`: the second sweep's 360° profile against the map of
//!   the first (from the true poses), starting from the pose its commanded
//!   forward move predicts: the correlative search and refinement, the
//!   lattice searched exhaustively beside branch and bound, and beside them
//!   the cost of scoring one pose on the lattice and exactly (k-d
//!   tree), which is why the search runs on the lattice.
//! - `map_dataset`: images to map end to end (profiles, sweeps,
//!   registration and refinement, the grid), and `build_map` alone.
//! - `register_scan`: a laser scan of the intel log registered as the
//!   laser mapper registers it (Laplace's covariance, the rival search),
//!   on the map of the 30 scans before it at their recorded poses: from
//!   the prior of a step with odometry, and from the stand of a step
//!   without (±3σ of 0.8 m and 25°). Skipped with a message without
//!   `PIROUETTE_SHARED`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use pirouette::geom::{Point2, Pose2};
use pirouette::grid::{GridConfig, OccupancyGrid};
use pirouette::io::{open_laser_log, BagOptions, Dataset, LaserScan, Motion};
use pirouette::laser::{scan_profile, step_prior, LaserConfig};
use pirouette::mapping::build_map;
use pirouette::pipeline::{self, PipelineConfig};
use pirouette::register::{
    endpoints, register, thin_points, LikelihoodField, MotionNoise, PosePrior, RegisterConfig, Search,
};
use pirouette::vision::VisionConfig;
use std::hint::black_box;
use std::path::Path;

struct Fixture {
    _dir: tempfile::TempDir,
    ds: Dataset,
}

fn fixture() -> Fixture {
    let dir = tempfile::tempdir().expect("temporary folder");
    let scene = pirouette::sim::Scene::builtin("field-multi").expect("built in");
    let root = dir.path().join("field-multi");
    pirouette::sim::render_dataset(&scene, 1, &root, |_, _| {}).expect("render");
    let ds = Dataset::open(&root).expect("dataset");
    Fixture { _dir: dir, ds }
}

fn vision() -> VisionConfig {
    VisionConfig {
        bin_width_rad: 0.25f64.to_radians(),
        ..VisionConfig::default()
    }
}

fn benches(c: &mut Criterion) {
    let f = fixture();
    let ds = &f.ds;
    let pipeline_config = PipelineConfig {
        vision: vision(),
        ..PipelineConfig::default()
    };
    let swept = pipeline::sweep_dataset(ds, &pipeline_config, &|_| {}).expect("sweeps");
    let (blind_m, sweeps) = (swept.blind_m, &swept.sweeps);
    let rops: Vec<_> = swept.frames.iter().map(|f| f.rop.clone()).collect();
    let truth = ds.truth_poses().expect("truth");
    let origin = truth[0].inverse();
    let truth: Vec<Pose2> = truth.iter().map(|t| origin * *t).collect();
    let config = swept.map_config(&pipeline_config);

    // The map of the first sweep, from its true poses.
    let mut grid = OccupancyGrid::new(GridConfig::default()).expect("grid");
    let mut mapped = Vec::new();
    for &i in &sweeps[0].frames {
        grid.insert_profile(&truth[i], &rops[i], blind_m);
        mapped.extend(
            endpoints(&rops[i])
                .into_iter()
                .map(|p| truth[i].transform_point(p)),
        );
    }
    let r = &config.register;
    mapped.retain(|p| grid.probability_at(p.x, p.y) > r.occupied_threshold);
    let field = LikelihoodField::from_map(
        &mapped,
        &grid,
        r.free_threshold,
        r.sigma_m,
        r.epsilon,
        r.epsilon_free,
    );
    // The second sweep, from the command after the first sweep's last frame.
    let last = *sweeps[0].frames.last().expect("frames");
    let first = sweeps[1].frames[0];
    let forward = match ds.manifest.frames[first].motion {
        Some(Motion::Forward { forward }) => forward,
        _ => 0.0,
    };
    let prior = PosePrior::after_forward(
        &truth[last],
        forward,
        0.5f64.to_radians(),
        &MotionNoise::default(),
    );
    let points = endpoints(&sweeps[1].sweep.rop);
    let thinned = thin_points(&points, r.spacing_m);

    let mut group = c.benchmark_group("register_sweep");
    group.throughput(Throughput::Elements(1));
    // The same search two ways: every lattice pose scored, and branch and
    // bound (which finds the same poses, and builds its max-pooled levels
    // of the field inside the timing). Once
    // from the forward move's prior, once from a wide one (±1 m, ±12°, as
    // after a turn whose command erred: about 9 million lattice poses).
    let wide = PosePrior {
        sigma_forward_m: 0.35,
        sigma_left_m: 0.35,
        sigma_theta_rad: 4f64.to_radians(),
        ..prior
    };
    for (case, prior) in [("forward", &prior), ("wide", &wide)] {
        for (name, search) in [
            ("exhaustive", Search::Exhaustive),
            ("branch_and_bound", Search::BranchAndBound),
        ] {
            let config = RegisterConfig { search, ..r.clone() };
            group.bench_function(format!("{case}/{name}"), |b| {
                b.iter(|| register(black_box(&field), black_box(&points), prior, &config).expect("registers"))
            });
        }
    }
    let s = field.resolution_m();
    group.bench_function("one_pose_lattice", |b| {
        b.iter(|| {
            thinned
                .iter()
                .map(|p| {
                    let q = prior.mean.transform_point(*p);
                    field.cell((q.x / s).floor() as i64, (q.y / s).floor() as i64)
                })
                .sum::<f32>()
        })
    });
    group.bench_function("one_pose_exact", |b| {
        b.iter(|| {
            thinned
                .iter()
                .map(|p| field.exact(prior.mean.transform_point(*p)))
                .sum::<f64>()
        })
    });
    group.finish();

    let mut group = c.benchmark_group("map_dataset");
    group.sample_size(10);
    group.throughput(Throughput::Elements(ds.manifest.frames.len() as u64));
    group.bench_function("images_to_map", |b| {
        b.iter(|| pipeline::map_dataset(ds, &pipeline_config, &|_| {}).expect("map"))
    });
    group.bench_function("build_map_only", |b| {
        b.iter(|| build_map(&swept.frames, sweeps, blind_m, &config, || {}).expect("map"))
    });
    group.finish();
}

/// The scan of the intel log registered, and the scans whose map it is
/// registered on (the laser mapper's local map).
const SCAN: usize = 400;
const MAP_SCANS: usize = 30;

fn scan_benches(c: &mut Criterion) {
    let Some(shared) = std::env::var_os("PIROUETTE_SHARED") else {
        eprintln!("register_scan skipped: set PIROUETTE_SHARED to the shared folder");
        return;
    };
    let log = Path::new(&shared).join("laser/intel-corrected.log");
    let scans: Vec<LaserScan> = open_laser_log(&log, &BagOptions::default())
        .expect("the intel log")
        .take(SCAN + 1)
        .collect::<Result<_, _>>()
        .expect("its scans");
    let config = LaserConfig::default();
    let points_of = |s: &LaserScan| endpoints(&scan_profile(s, config.max_range_m));
    let map: Vec<Point2> = scans[SCAN - MAP_SCANS..SCAN]
        .iter()
        .flat_map(|s| points_of(s).into_iter().map(|p| s.recorded.transform_point(p)))
        .collect();
    let r = &config.register;
    let field = LikelihoodField::from_points(&map, config.field_resolution_m, r.sigma_m, r.epsilon);
    let (previous, scan) = (scans[SCAN - 1].recorded, &scans[SCAN]);
    let points = points_of(scan);
    let step = previous.inverse() * scan.recorded;
    let mut group = c.benchmark_group("register_scan");
    group.throughput(Throughput::Elements(1));
    for (name, prior) in [
        ("intel/odometry", step_prior(&previous, Some(&step), &config)),
        ("intel/no_odometry", step_prior(&previous, None, &config)),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| register(black_box(&field), black_box(&points), &prior, r).expect("registers"))
        });
    }
    group.finish();
}

criterion_group!(register_benches, benches, scan_benches);
criterion_main!(register_benches);
