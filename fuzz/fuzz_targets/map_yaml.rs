//! Any bytes as a map's YAML (its PGM a fixed small valid image).
#![no_main]

mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let dir = common::scratch();
    let pgm = dir.join("map.pgm");
    if !pgm.exists() {
        let mut bytes = b"P5\n4 3\n255\n".to_vec();
        bytes.extend([0u8, 205, 254, 205].repeat(3));
        std::fs::write(&pgm, bytes).expect("scratch pgm");
    }
    std::fs::write(dir.join("map.yaml"), data).expect("scratch yaml");
    let _ = pirouette::io::read_ros_map(&dir.join("map.yaml"));
});
