//! Any bytes as a scene file for `pirouette render` (checked, not rendered).
#![no_main]

mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = common::scratch().join("scene.json");
    std::fs::write(&path, data).expect("scratch scene");
    if let Ok(scene) = pirouette::sim::Scene::from_file(&path) {
        let _ = pirouette::sim::plan_route(&scene, 1);
    }
});
