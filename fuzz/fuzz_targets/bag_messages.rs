//! Any bytes as each message a laser map reads from a bag, in both
//! serialisations: decoded or refused, never a panic.
#![no_main]

use pirouette::io::bag::wire::{self, Wire};

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    for w in [Wire::Ros1, Wire::Cdr] {
        if let Ok(s) = wire::laser_scan(data, w) {
            assert!(s.ranges.len() <= data.len());
        }
        if let Ok(o) = wire::odometry(data, w) {
            assert!(o.pose.is_finite());
        }
        if let Ok(ts) = wire::transforms(data, w) {
            assert!(ts.iter().all(|t| t.pose.is_finite()));
        }
    }
});
