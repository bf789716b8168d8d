//! Any bytes after the MCAP magic as a ROS 2 bag's storage file: scans
//! read until an error naming the file, never a panic.
#![no_main]

mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = common::scratch().join("fuzzed.mcap");
    let mut bytes = pirouette::io::bag::mcap::MAGIC.to_vec();
    bytes.extend_from_slice(data);
    std::fs::write(&path, &bytes).expect("scratch file");
    common::read_scans(&path);
});
