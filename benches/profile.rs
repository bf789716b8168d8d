//! Image → ROP: one 320 × 240 frame, single thread, tables built once.
//!
//! Fixtures are frames of the built-in scenes rendered with a fixed seed:
//! a dark soccer field with white walls and a light textured room.

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
    group.finish();
}

criterion_group!(benches, image_to_rop);
criterion_main!(benches);
