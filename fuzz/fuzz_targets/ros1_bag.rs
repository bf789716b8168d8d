//! Any bytes after the ROS 1 bag magic as a bag: scans read until an
//! error naming the file, never a panic; every scan read is well formed.
#![no_main]

mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = common::scratch().join("fuzzed.bag");
    let mut bytes = pirouette::io::bag::ros1::MAGIC.to_vec();
    bytes.extend_from_slice(data);
    std::fs::write(&path, &bytes).expect("scratch file");
    common::read_scans(&path);
});
