//! Real camera frames (`../shared/real/`) read through the project's rig.

use crate::util::shared;
use pirouette::io::Dataset;
use std::path::Path;

/// The project's rig of the TUM pioneer_360 frames, written beside a
/// TUM stamps file made from the shared frame times, in `dir`.
fn tum_rig(dir: &Path) -> std::path::PathBuf {
    let set = shared().join("real/tum-fr2-pioneer-360");
    let project = Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/real/tum-fr2-pioneer-360");
    let times = std::fs::read_to_string(set.join("frames_linear_times.txt")).unwrap();
    let stamps: String = times
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let mut f = l.split_whitespace();
            let (index, t) = (f.next().unwrap(), f.next().unwrap());
            format!("{t} frames/{index}.jpg\n")
        })
        .collect();
    std::fs::write(dir.join("rgb.txt"), stamps).unwrap();
    std::fs::copy(project.join("camera_info.yaml"), dir.join("camera_info.yaml")).unwrap();
    let mut rig: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(project.join("rig.json")).unwrap()).unwrap();
    rig["images"] = set.display().to_string().into();
    rig["truth"] = set.join("groundtruth.txt").display().to_string().into();
    std::fs::write(dir.join("rig.json"), rig.to_string()).unwrap();
    dir.join("rig.json")
}

/// The rig opens the 1225 frames, chooses every fifth, reads the lens, and
/// turns the camera's motion capture into robot headings whose sum over
/// the run is the 466° the set's description gives.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the shared data: set PIROUETTE_SHARED")]
fn the_tum_frames_open_as_a_dataset_with_their_lens_and_turn() {
    let dir = tempfile::tempdir().unwrap();
    let ds = Dataset::open(&tum_rig(dir.path())).unwrap();
    assert_eq!(ds.manifest.frames.len(), 245);
    // No odometry: no motion is taken for a command.
    assert!(ds.manifest.frames.iter().all(|f| f.motion.is_none()));
    let lens = ds
        .manifest
        .camera
        .pinhole
        .as_ref()
        .unwrap()
        .distortion
        .clone()
        .unwrap();
    assert_eq!(lens.model, "plumb_bob");
    assert_eq!(ds.load_image(100).unwrap().dimensions(), (320, 240));
    let truth: Vec<f64> = ds
        .manifest
        .frames
        .iter()
        .filter_map(|f| f.truth.map(|t| t.theta_deg))
        .collect();
    assert!(truth.len() >= 240, "{} frames with truth", truth.len());
    let turned: f64 = truth
        .windows(2)
        .map(|w| (w[1] - w[0] + 540.0).rem_euclid(360.0) - 180.0)
        .sum();
    assert!((440.0..490.0).contains(&turned.abs()), "turned {turned}°");
}
