//! Any bytes as a CARMEN laser log: scans read one at a time until an
//! error naming the line, never a panic; every scan read is well formed
//! and makes a profile.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = std::path::Path::new("fuzzed.log");
    let reader = pirouette::io::CarmenReader::new(path, data);
    for scan in reader.take(1000) {
        let Ok(scan) = scan else { break };
        assert!(scan.ranges_m.len() >= 2 && scan.ranges_m.len() <= pirouette::io::MAX_BEAMS);
        assert!(scan.first_bearing_rad.is_finite() && scan.beam_step_rad > 0.0);
        assert!(scan.recorded.is_finite());
        assert!(scan.odometry.is_none_or(|o| o.is_finite()));
        let rop = pirouette::laser::scan_profile(&scan, 20.0);
        assert_eq!(rop.len(), scan.ranges_m.len());
        let _ = pirouette::register::endpoints(&rop);
    }
});
