//! Image → ROP: one 320 × 240 frame, single thread, tables built once.
//!
//! Fixtures are frames of the built-in scenes rendered with a fixed seed:
//! a dark soccer field with white walls and a light textured room; and,
//! where `PIROUETTE_SHARED` is set, a real frame (TUM pioneer_360, JPEG,
//! through its calibrated lens) read with the project's rig.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use pirouette::geom::Pose2;
use pirouette::sim::{Renderer, Scene};
use pirouette::vision::{RopExtractor, VisionConfig};
use std::hint::black_box;

fn frame(scene: &str, pose: Pose2) -> (Scene, image::RgbImage) {
    let s = Scene::builtin(scene).expect("built-in scene");
    let img = Renderer::new(&s, 1).render(&pose, 0);
    (s, img)
}

fn image_to_rop(c: &mut Criterion) {
    let fixtures = [
        (
            "field",
            frame("field-pirouette", Pose2::from_deg(0.6, 0.55, 30.0)),
        ),
        ("room", frame("room-multi", Pose2::from_deg(1.6, 1.2, 100.0))),
    ];
    let mut group = c.benchmark_group("image_to_rop");
    group.throughput(Throughput::Elements(1));
    for (name, (scene, img)) in &fixtures {
        let camera = scene.camera.pinhole();
        for (label, bin_deg) in [("1deg", 1.0f64), ("0.2deg", 0.2)] {
            let config = VisionConfig {
                bin_width_rad: bin_deg.to_radians(),
                ..VisionConfig::default()
            };
            let ex = RopExtractor::new(&camera, scene.max_range, config);
            group.bench_function(format!("{name}/{label}"), |b| {
                b.iter(|| ex.rop(black_box(img)).expect("sizes match"))
            });
        }
        // The profile turns are verified on (the texture cue off), which
        // sweeps and maps compute beside the default one.
        let matching = VisionConfig::default()
            .for_matching()
            .expect("the cue is on by default");
        let ex = RopExtractor::new(&camera, scene.max_range, matching);
        group.bench_function(format!("{name}/1deg-no-texture-cue"), |b| {
            b.iter(|| ex.rop(black_box(img)).expect("sizes match"))
        });
        // The profile sweeps are registered on (no faint steps), which
        // sweeps and maps compute beside the default one too.
        let comparing = VisionConfig::default()
            .for_comparing()
            .expect("faint steps are on by default");
        let ex = RopExtractor::new(&camera, scene.max_range, comparing);
        group.bench_function(format!("{name}/1deg-no-faint-steps"), |b| {
            b.iter(|| ex.rop(black_box(img)).expect("sizes match"))
        });
        // The boundary scan alone, beside the whole path.
        let ex = RopExtractor::new(&camera, scene.max_range, VisionConfig::default());
        group.bench_function(format!("{name}/boundaries-only"), |b| {
            b.iter(|| ex.boundaries(black_box(img)).expect("sizes match"))
        });
    }
    real_frame(&mut group);
    group.finish();
}

/// A real 320 × 240 frame through the project's rig of the TUM set (lens
/// included), at the sweeps' bin width; skipped with a message where the
/// shared data is not there.
fn real_frame(group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>) {
    let Some(shared) = std::env::var_os("PIROUETTE_SHARED").filter(|v| !v.is_empty()) else {
        eprintln!("PIROUETTE_SHARED unset: the real frame (image_to_rop/real-tum) is not measured");
        return;
    };
    let set = std::path::Path::new(&shared).join("real/tum-fr2-pioneer-360");
    let rig =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/real/tum-fr2-pioneer-360/rig.json");
    let rig: pirouette::io::Rig =
        serde_json::from_str(&std::fs::read_to_string(&rig).expect("the project's rig")).expect("a rig");
    let calibration = pirouette::camera::Calibration::read(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("datasets/real/tum-fr2-pioneer-360/camera_info.yaml"),
    )
    .expect("the project's calibration");
    let mount = rig.mount.unwrap_or_default();
    let camera = calibration.pinhole(rig.height, rig.tilt_deg.to_radians(), mount.forward, mount.left);
    let img = image::open(set.join("frames/00600.jpg"))
        .expect("a shared frame")
        .into_rgb8();
    let config = VisionConfig {
        bin_width_rad: pirouette::pipeline::SWEEP_BIN_DEG.to_radians(),
        ..VisionConfig::default()
    };
    let ex = RopExtractor::new(&camera, rig.max_range, config);
    group.bench_function("real-tum/0.25deg", |b| {
        b.iter(|| ex.rop(black_box(&img)).expect("sizes match"))
    });
}

criterion_group!(benches, image_to_rop);
criterion_main!(benches);
