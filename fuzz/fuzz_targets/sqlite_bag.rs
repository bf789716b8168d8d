//! Any bytes after the SQLite header string as a ROS 2 bag's `.db3`
//! file: scans read until an error naming the file, never a panic.
#![no_main]

mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = common::scratch().join("fuzzed.db3");
    let mut bytes = b"SQLite format 3\0".to_vec();
    bytes.extend_from_slice(data);
    std::fs::write(&path, &bytes).expect("scratch file");
    common::read_scans(&path);
});
