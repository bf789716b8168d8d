//! Real camera frames (`../shared/real/`) read through the project's rig.

use crate::util::shared;
use pirouette::eval::sync::{find_clock, put_truth_on_frames};
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

/// The rig opens the 1225 frames, chooses every fifth, reads the lens,
/// finds the motion capture's clock from the images, and turns the
/// camera's motion capture into robot headings whose sum over the run is
/// the 466° the set's description gives.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the shared data: set PIROUETTE_SHARED")]
fn the_tum_frames_open_as_a_dataset_with_their_lens_and_turn() {
    let dir = tempfile::tempdir().unwrap();
    let mut ds = Dataset::open(&tum_rig(dir.path())).unwrap();
    assert_eq!(ds.manifest.frames.len(), 245);
    // The stamps are made up: no frame has truth until the clock is found.
    assert!(ds.manifest.frames.iter().all(|f| f.truth.is_none()));
    let clock = put_truth_on_frames(&mut ds).unwrap().expect("a clock to find");
    eprintln!("{clock:?}");
    // The set's README: the even spacing is off by about half a second.
    assert!(
        clock.offset_s.abs() < 1.0 && (clock.rate - 1.0).abs() < 0.02,
        "{clock:?}"
    );
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

/// The clock found from the images follows the truth: with the motion
/// capture's times moved by 0.6 s, the offset found moves by 0.6 s.
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the shared data: set PIROUETTE_SHARED")]
fn the_truth_clock_found_from_the_images_follows_a_shifted_truth() {
    let dir = tempfile::tempdir().unwrap();
    let rig = tum_rig(dir.path());
    let clock = |ds: &Dataset| {
        let camera = ds.manifest.camera.pinhole_model().unwrap();
        find_clock(ds.truth_track.as_ref().unwrap(), &camera).unwrap()
    };
    let before = clock(&Dataset::open(&rig).unwrap());
    // The same truth, every stamp 0.6 s later.
    let truth = shared().join("real/tum-fr2-pioneer-360/groundtruth.txt");
    let shifted: String = std::fs::read_to_string(&truth)
        .unwrap()
        .lines()
        .map(|l| match l.split_once(' ') {
            Some((t, rest)) if !l.starts_with('#') => {
                format!("{:.4} {rest}\n", t.parse::<f64>().unwrap() + 0.6)
            }
            _ => format!("{l}\n"),
        })
        .collect();
    std::fs::write(dir.path().join("shifted.txt"), shifted).unwrap();
    let mut r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&rig).unwrap()).unwrap();
    r["truth"] = dir.path().join("shifted.txt").display().to_string().into();
    std::fs::write(&rig, r.to_string()).unwrap();
    let after = clock(&Dataset::open(&rig).unwrap());
    eprintln!("{before:?}\n{after:?}");
    assert!(
        ((after.offset_s - before.offset_s) - 0.6).abs() < 0.03,
        "{before:?} {after:?}"
    );
    assert!((after.rate - before.rate).abs() < 0.001, "{before:?} {after:?}");
    // Most pairs agree with the truth to within a degree or so.
    assert!(before.residual_median_deg < 1.0, "{before:?}");
}

/// The visual compass on real frames: the turn between every fifth
/// frame (about 3.6°, and 7 cm of travel) against the motion capture's, on
/// the clock found from the images. Measured: median 0.74°, 90 % within
/// 4.1° (moves past poles a metre or two away shift them by degrees).
#[test]
#[cfg_attr(not(shared_data), ignore = "needs the shared data: set PIROUETTE_SHARED")]
fn the_visual_compass_turns_with_the_motion_capture() {
    use pirouette::vision::compass::{bearing_profile, profile_turn, MIN_CORRELATION};
    let dir = tempfile::tempdir().unwrap();
    let mut ds = Dataset::open(&tum_rig(dir.path())).unwrap();
    put_truth_on_frames(&mut ds).unwrap();
    let camera = ds.manifest.camera.pinhole_model().unwrap();
    let profiles: Vec<_> = (0..ds.manifest.frames.len())
        .map(|i| bearing_profile(&ds.load_image(i).unwrap(), &camera))
        .collect();
    let mut errors = Vec::new();
    for k in 1..profiles.len() {
        let (Some(a), Some(b)) = (&profiles[k - 1], &profiles[k]) else {
            continue;
        };
        let [t0, t1] = [k - 1, k].map(|i| ds.manifest.frames[i].truth.unwrap().theta_deg);
        let truth = (t1 - t0 + 540.0).rem_euclid(360.0) - 180.0;
        if let Some((turn, score)) = profile_turn(a, b, 30.0) {
            if score >= MIN_CORRELATION {
                errors.push((turn - truth).abs());
            }
        }
    }
    errors.sort_by(f64::total_cmp);
    let n = errors.len();
    let (median, p90) = (errors[n / 2], errors[n * 9 / 10]);
    eprintln!(
        "{n} of {} turns: median {median:.2}°, 90 % within {p90:.2}°",
        profiles.len() - 1
    );
    assert!(n >= 200, "{n} turns");
    assert!(median < 0.8 && p90 < 4.5, "median {median}°, p90 {p90}°");
}
