//! Any bytes as a dataset manifest: an error or a checked dataset, never a
//! panic, an abort or a huge allocation.
#![no_main]

mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let dir = common::scratch();
    std::fs::write(dir.join("dataset.json"), data).expect("scratch manifest");
    if let Ok(ds) = pirouette::io::Dataset::open(dir) {
        // A manifest that passes must describe a camera the engine can use.
        let _ = ds.camera(None);
        let _ = pirouette::mapping::check_extent(
            &pirouette::frame::camera_motions(&ds),
            ds.manifest.max_range,
            &pirouette::grid::GridConfig::default(),
        );
    }
});
