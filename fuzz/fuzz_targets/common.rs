//! A scratch folder per fuzzing process, for readers that take paths.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The process's scratch folder, made once, holding an image file at the
/// paths fuzzed manifests most often name.
pub fn scratch() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("pirouette-fuzz-{}", std::process::id()));
        for name in [
            "frames/s00/000.png",
            "frames/s00/001.png",
            "frames/s01/000.png",
            "a.png",
        ] {
            let path = dir.join(name);
            std::fs::create_dir_all(path.parent().expect("a parent")).expect("scratch folder");
            std::fs::write(&path, b"").expect("scratch image");
        }
        std::fs::create_dir_all(dir.join("truth")).expect("scratch folder");
        dir
    })
}

/// Reads the scans of a laser log until its end or an error: an error
/// names the file; every scan read is well formed and makes a profile.
#[allow(dead_code)]
pub fn read_scans(path: &Path) {
    let log = match pirouette::io::open_laser_log(path, &Default::default()) {
        Ok(log) => log,
        Err(e) => {
            assert!(e.to_string().contains("fuzzed"), "{e}");
            return;
        }
    };
    for scan in log.take(1000) {
        let scan = match scan {
            Ok(s) => s,
            Err(e) => {
                assert!(e.to_string().contains("fuzzed"), "{e}");
                break;
            }
        };
        assert!(scan.ranges_m.len() >= 2 && scan.ranges_m.len() <= pirouette::io::MAX_BEAMS);
        assert!(scan.first_bearing_rad.is_finite() && scan.beam_step_rad > 0.0);
        assert!(scan.odometry.is_none_or(|o| o.is_finite()));
        let rop = pirouette::laser::scan_profile(&scan, 20.0);
        assert_eq!(rop.len(), scan.ranges_m.len());
    }
}
