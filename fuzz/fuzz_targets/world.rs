//! Any bytes as a dataset's `truth/world.json`.
#![no_main]

mod common;

const MANIFEST: &str = r#"{"format": "rop-dataset/1", "name": "fuzz",
  "camera": {"width": 320, "height": 240, "ipm": {"b": 0.1, "h": 0.1, "d": 0.125, "w": 0.136}},
  "max_range": 0.9, "frames": [{"image": "a.png", "sweep": 0, "motion": null}]}"#;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let dir = common::scratch();
    std::fs::write(dir.join("dataset.json"), MANIFEST).expect("scratch manifest");
    std::fs::write(dir.join("truth/world.json"), data).expect("scratch world");
    if let Ok(ds) = pirouette::io::Dataset::open(dir) {
        if let Ok(Some(world)) = ds.world() {
            let _ = world.outline_distance([0.5, 0.5]);
        }
    }
});
