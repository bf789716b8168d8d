//! Maps of whole datasets: the files `pirouette map` writes and their
//! accuracy against truth (`pirouette eval map`).

use crate::util::{pirouette, rendered, shared};
use pirouette::eval::map::{occupied_centres, truth_in_map_frame};
use pirouette::grid::RosMap;
use pirouette::io::{map_names, read_poses, read_ros_map, Dataset};
use pirouette::mapping::map_with_poses;
use pirouette::pipeline::{self, PipelineConfig};
use pirouette::profile::Rop;
use std::path::Path;

/// Maps `dataset` into `out` and evaluates it, returning the report.
fn map_and_eval(dataset: &Path, out: &Path) -> serde_json::Value {
    let o = pirouette(&["map", dataset.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = pirouette(&[
        "eval",
        "map",
        dataset.to_str().unwrap(),
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert_eq!(stdout.lines().count(), 1, "{stdout}");
    serde_json::from_str(stdout.trim()).unwrap()
}

fn num(v: &serde_json::Value, path: &[&str]) -> f64 {
    path.iter()
        .fold(v, |v, k| &v[*k])
        .as_f64()
        .unwrap_or_else(|| panic!("{path:?} in {v}"))
}

#[test]
fn map_folder_holds_every_file_in_the_contract() {
    let root = rendered("field-multi", 17);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("map");
    let report = map_and_eval(&root, &out);
    // ROS map: trinary P5 and its YAML.
    let ros = read_ros_map(&out.join(map_names::YAML)).unwrap();
    let yaml = std::fs::read_to_string(out.join(map_names::YAML)).unwrap();
    assert!(yaml.lines().any(|l| l == "mode: trinary"), "{yaml}");
    assert!(ros.pixels.iter().all(|p| [0u8, 205, 254].contains(p)));
    assert!(ros.pixels.contains(&0) && ros.pixels.contains(&254));
    let pgm = std::fs::read(out.join(map_names::PGM)).unwrap();
    assert!(pgm.starts_with(b"P5\n"));
    let png = image::open(out.join(map_names::PNG)).unwrap();
    assert!(png.width() >= 600 || png.height() >= 600);
    // One pose per frame, in the map frame: the first at the origin.
    let ds = Dataset::open(&root).unwrap();
    let poses = read_poses(&out.join(map_names::POSES_JSON)).unwrap();
    assert_eq!(poses.len(), ds.manifest.frames.len());
    for (p, f) in poses.iter().zip(&ds.manifest.frames) {
        assert_eq!(p.image.as_deref(), Some(f.image.as_str()));
    }
    assert_eq!((poses[0].x, poses[0].y, poses[0].theta_deg), (0.0, 0.0, 0.0));
    let tum = std::fs::read_to_string(out.join(map_names::POSES_TUM)).unwrap();
    assert_eq!(tum.lines().filter(|l| !l.starts_with('#')).count(), poses.len());
    // Mapping again replaces the files and leaves no temporary ones.
    let o = pirouette(&["map", root.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success());
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 5);
    assert!(num(&report, &["trajectory", "poses"]) as usize == poses.len());
}

#[test]
fn registered_sweeps_map_a_rendered_field_to_a_centimetre() {
    let root = rendered("field-multi", 17);
    let dir = tempfile::tempdir().unwrap();
    let r = map_and_eval(&root, &dir.path().join("map"));
    eprintln!("{r}");
    let ate = num(&r, &["trajectory", "ate_aligned_m"]);
    let commanded = num(&r, &["commanded", "ate_aligned_m"]);
    assert!(ate <= 0.02, "ATE {ate} m");
    assert!(ate * 10.0 < commanded, "{ate} vs commanded {commanded}");
    assert!(num(&r, &["trajectory", "ate_anchored_m"]) <= 0.025);
    // The best-fit alignment, which minimises the position errors, moves
    // a map whose first frame is right by little (this seed: 0.20°, 2.0 mm).
    assert!(ate <= num(&r, &["trajectory", "ate_anchored_m"]));
    let (turned, moved) = (
        num(&r, &["alignment", "heading_deg"]),
        num(&r, &["alignment", "shift_m"]),
    );
    assert!(turned.abs() <= 0.5 && moved <= 0.01, "{}", r["alignment"]);
    // Its scale: the ranges are metric, so the map is its true size to
    // within a per cent (this seed: 1.0047, the map 0.47 % too small).
    let scale = num(&r, &["alignment", "scale"]);
    assert!((scale - 1.0).abs() <= 0.01, "{}", r["alignment"]);
    // The issue's targets: F1 at least 0.9 and 95 % of the true-pose
    // map's (this seed measures 1.000 and 100 %).
    assert!(num(&r, &["map", "f1"]) >= 0.9, "{}", r["map"]);
    assert!(num(&r, &["f1_ratio"]) >= 0.95, "{r}");
    // The true-pose map checks the evaluation itself: the profiles are
    // right, so a map from the true poses matches the scene.
    assert!(
        num(&r, &["true_pose_map", "precision"]) >= 0.97,
        "{}",
        r["true_pose_map"]
    );
    assert!(
        num(&r, &["true_pose_map", "recall"]) >= 0.95,
        "{}",
        r["true_pose_map"]
    );
}

#[test]
fn revisits_the_place_index_recognises_are_true_and_close_loops() {
    let root = rendered("field-multi", 17);
    let ds = Dataset::open(&root).unwrap();
    let mapped = pipeline::map_dataset(&ds, &PipelineConfig::default(), &|_| {}).unwrap();
    let truth = truth_in_map_frame(&ds).unwrap();
    let revisits = &mapped.map.revisits;
    assert!(
        !revisits.is_empty(),
        "the route comes back, and no revisit was recognised"
    );
    let sweeps = &mapped.swept.sweeps;
    for r in revisits {
        assert!(
            r.earlier + 1 < r.later,
            "{r:?}: a revisit is of a sweep before the last"
        );
        // A true revisit: the two sweeps' first frames stand within 15 cm
        // (the place index's own bound), and the pose it found is right.
        let (a, b) = (
            truth[sweeps[r.earlier].frames[0]],
            truth[sweeps[r.later].frames[0]],
        );
        let true_rel = a.between(&b);
        assert!(true_rel.translation().norm() < 0.15, "{r:?}: {true_rel:?}");
        assert!(r.registered && r.kept, "{r:?}");
    }
    // Without the index the pairwise matching finds the same loops here
    // (the route does not drift out of its reach): the map is the same.
    let without = PipelineConfig {
        map: pirouette::mapping::MapConfig {
            revisits: None,
            ..PipelineConfig::default().map
        },
        ..PipelineConfig::default()
    };
    let plain = pipeline::map_dataset(&ds, &without, &|_| {}).unwrap();
    assert!(plain.map.revisits.is_empty());
    assert!(revisits.iter().all(|r| !r.beyond_reach));
    assert_eq!(plain.map.frame_poses, mapped.map.frame_poses);
}

#[test]
fn a_rendered_room_maps_within_the_office_targets() {
    // Its soft limit (1 m) leaves most walls of the 4 × 3 m room beyond
    // sight for the map: the sweeps are registered on what lies farther.
    let root = rendered("room-multi", 17);
    let dir = tempfile::tempdir().unwrap();
    let r = map_and_eval(&root, &dir.path().join("map"));
    eprintln!("{r}");
    let ate = num(&r, &["trajectory", "ate_aligned_m"]);
    assert!(ate <= 0.04, "ATE {ate} m");
    assert!(ate * 10.0 < num(&r, &["commanded", "ate_aligned_m"]), "{r}");
    // The issue's targets: F1 at least 0.9 and 95 % of the true-pose
    // map's (this seed measures 0.98 and 100 %).
    assert!(num(&r, &["map", "f1"]) >= 0.9, "{}", r["map"]);
    assert!(num(&r, &["f1_ratio"]) >= 0.95, "{r}");
    // The renderer turns the robot about a point 5 mm off its centre: the
    // turns measure it to within 2 mm of the true poses' fit (this seed
    // 1.6 mm; without the pivot the error would be the full 5 mm).
    let (est, truth) = (&r["pivot"]["estimated_mm"], &r["pivot"]["true_mm"]);
    let at = |v: &serde_json::Value, i: usize| v[i].as_f64().unwrap_or_else(|| panic!("{v}"));
    let err = (at(est, 0) - at(truth, 0)).hypot(at(est, 1) - at(truth, 1));
    assert!(err < 2.0, "pivot {est} against {truth}");
}

/// Registration compares the profiles without the texture cue's faint
/// steps and the grid fuses those with them: the poses of a map whose grid
/// is made of the compared profiles too. Made from the true poses (the
/// grid's part alone), the grid with faint steps has more occupied cells
/// on the scene's walls (within 2 cm) and no more than a few more
/// elsewhere.
#[test]
fn faint_steps_add_walls_to_the_grid_and_leave_registration_alone() {
    let ds = Dataset::open(&rendered("room-multi", 17)).unwrap();
    let mut swept = pipeline::sweep_dataset(&ds, &PipelineConfig::default(), &|_| {}).unwrap();
    let config = swept.map_config(&PipelineConfig::default());
    let with = pipeline::map_swept(&ds, &swept, &config, &|_| {}).unwrap();
    // The same run with the compared profiles in the grid too.
    let rops: Vec<Rop> = swept.frames.iter().map(|f| f.rop.clone()).collect();
    let compared: Vec<Rop> = swept.frames.iter().map(|f| f.compared.clone()).collect();
    for f in &mut swept.frames {
        f.rop = f.compared.clone();
    }
    let without = pipeline::map_swept(&ds, &swept, &config, &|_| {}).unwrap();
    assert_eq!(with.frame_poses, without.frame_poses);
    let blind_m = swept.blind_m;
    let world = ds.world().unwrap().expect("a rendered scene");
    let truth = truth_in_map_frame(&ds).unwrap();
    let first = ds.truth_poses().expect("true poses")[0];
    // Occupied cells within 2 cm of a wall, and the others.
    let on_walls = |rops: &[Rop]| {
        let grid = map_with_poses(rops, &truth, blind_m, &config.grid).unwrap();
        let cells = occupied_centres(&RosMap::from_grid(&grid));
        let on = cells
            .iter()
            .filter(|p| {
                let q = first.transform_point(**p);
                world.outline_distance([q.x, q.y]) <= 0.02
            })
            .count();
        (on, cells.len() - on)
    };
    let ((on_with, off_with), (on_without, off_without)) = (on_walls(&rops), on_walls(&compared));
    eprintln!("on walls {on_with} and {on_without}, elsewhere {off_with} and {off_without}");
    assert!(
        on_with > on_without,
        "{on_with} cells on walls with faint steps, {on_without} without"
    );
    assert!(
        off_with <= off_without + 5,
        "{off_with} cells off walls with faint steps, {off_without} without"
    );
}

/// The one entry takes a camera dataset and a laser log alike: it reports
/// as many steps of each stage as its input said it would, and returns
/// the map of the input's sensor; bad settings are refused before any
/// image is read.
#[test]
fn the_one_entry_maps_either_sensor_and_reports_the_work_it_announced() {
    use pirouette::pipeline::Stage;
    use pirouette::slam::{map, Config, Input, MapOutput, Sensor};
    use std::sync::atomic::{AtomicUsize, Ordering};
    let count = |input: Input, config: &Config| {
        let heard = [AtomicUsize::new(0), AtomicUsize::new(0), AtomicUsize::new(0)];
        let work = input.work(config).unwrap();
        let out = map(input, config, &|stage| {
            let k = match stage {
                Stage::Profiled => 0,
                Stage::Placed => 1,
                Stage::Scan => 2,
            };
            heard[k].fetch_add(1, Ordering::Relaxed);
        })
        .unwrap();
        let heard = heard.map(|h| h.into_inner());
        (work, heard, out)
    };
    // A single pirouette: one sweep, its refinement passes, the joint step.
    let camera = Input::open(&rendered("field-pirouette", 17)).unwrap();
    assert_eq!(camera.sensor(), Sensor::Camera);
    let (work, heard, out) = count(camera, &Config::default());
    assert_eq!(heard, [work.profiled, work.placed, 0]);
    assert_eq!(work.placed, pirouette::mapping::progress_steps(1));
    let MapOutput::Camera { dataset, mapped } = out else {
        panic!("a camera dataset mapped as a laser log");
    };
    assert_eq!(mapped.map.frame_poses.len(), dataset.manifest.frames.len());
    assert_eq!(work.profiled, dataset.manifest.frames.len());

    // A simulated CARMEN log, its scans counted before the run.
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("ring.log");
    let path = crate::util::ring_path(3, 0.25, 3, 30.0);
    let sim = pirouette::sim::LogSim::sick();
    let mut text = Vec::new();
    sim.write(
        &mut text,
        &pirouette::sim::Walls::ring(),
        path.iter().copied(),
        |_| false,
        2,
    )
    .unwrap();
    std::fs::write(&log, text).unwrap();
    let laser = Input::open(&log).unwrap();
    assert_eq!(laser.sensor(), Sensor::Laser);
    let (work, heard, out) = count(laser, &Config::default());
    assert_eq!(work.scans, Some(path.len()));
    assert_eq!(heard, [0, 0, path.len()]);
    let MapOutput::Laser(out) = out else {
        panic!("a laser log mapped as a camera dataset");
    };
    assert!(out.grid.is_ok() && out.coarsened.is_none());
    assert_eq!(out.registered.every_scan().len(), path.len());

    // A far reach short of the soft limit: refused before any image.
    let mut config = Config::default();
    config.camera.map.far_reach = 0.5;
    let camera = Input::open(&rendered("field-pirouette", 17)).unwrap();
    let err = map(camera, &config, &|stage| {
        panic!("{stage:?} heard: the settings were not checked first")
    })
    .err()
    .expect("refused");
    assert!(err.to_string().contains("far reach 0.5"), "{err}");
}

#[test]
fn a_single_pirouette_anchors_its_frames_on_each_other() {
    // No other sweep to register against: the frames' headings come from
    // the turns and from each frame against the map of the others.
    let root = rendered("field-pirouette", 17);
    let dir = tempfile::tempdir().unwrap();
    let r = map_and_eval(&root, &dir.path().join("map"));
    eprintln!("{r}");
    assert!(
        num(&r, &["trajectory", "heading_rmse_deg"]) <= 2.0,
        "{}",
        r["trajectory"]
    );
    assert!(num(&r, &["map", "f1"]) >= 0.85, "{}", r["map"]);
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the shared data: set PIROUETTE_SHARED")]
fn shared_datasets_map_far_better_than_the_commands() {
    let shared = shared();
    let dir = tempfile::tempdir().unwrap();
    // The issue's targets: ATE within 2 cm on the field and 4 cm in the
    // office, F1 at least 0.9 and 95 % of the true-pose map's. The office's
    // map in its first frame's coordinates is not held to the 95 %: it
    // measures 91.5-97.2 % of the true-pose map's under rounding-level
    // changes to its inputs, as the first frame's heading comes out a few
    // tenths of a degree either way and turns the whole map with it
    // (BENCHMARKS.md, "How much a map moves when nothing changes"). Its
    // shape, the map after the best-fit alignment, measures 98.0-99.0 %.
    // office-multi-b, the office on another trajectory, is held to the
    // office's figures too.
    let sets = [
        ("field-multi", 0.02, 0.95),
        ("office-multi", 0.04, 0.9),
        ("office-multi-b", 0.04, 0.9),
    ];
    for (name, max_ate_m, min_ratio) in sets {
        let root = shared.join("datasets").join(name);
        let r = map_and_eval(&root, &dir.path().join(name));
        eprintln!("{name}: {r}");
        let ate = num(&r, &["trajectory", "ate_aligned_m"]);
        assert!(ate <= max_ate_m, "{name}: ATE {ate} m");
        assert!(ate * 10.0 < num(&r, &["commanded", "ate_aligned_m"]), "{name}");
        assert!(num(&r, &["map", "f1"]) >= 0.9, "{name}: {}", r["map"]);
        assert!(num(&r, &["f1_ratio"]) >= min_ratio, "{name}: {r}");
        assert!(num(&r, &["f1_ratio_aligned"]) >= 0.95, "{name}: {r}");
        // Every frame's heading: the turns toward the next spot that the
        // commands got wrong by 8-17° are found.
        assert!(num(&r, &["trajectory", "heading_rmse_deg"]) < 1.0, "{name}: {r}");
    }
}

#[test]
fn map_and_eval_refuse_bad_input_with_the_file_named() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("robot.log");
    std::fs::write(&log, "ROBOTLASER1 0 0\n").unwrap();
    let o = pirouette(&[
        "map",
        log.to_str().unwrap(),
        "--out",
        dir.path().join("m").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("robot.log:1") && err.contains("ROBOTLASER1"),
        "{err}"
    );

    // A map folder without poses.
    let root = rendered("field-multi", 17);
    let empty = dir.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let o = pirouette(&["eval", "map", root.to_str().unwrap(), empty.to_str().unwrap()]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("poses.json"), "{err}");

    // A reach short of the soft limit itself.
    let o = pirouette(&[
        "map",
        root.to_str().unwrap(),
        "--out",
        dir.path().join("r").to_str().unwrap(),
        "--far-reach",
        "0.5",
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("far reach 0.5"), "{err}");
}

/// A dataset whose motions are general moves, as odometry gives them
/// (here the true relative poses, the shifts 8 % long and the turns 5 %
/// short, as a worn wheel makes them): frames that turned in place keep
/// their sweep and have their turns verified, moves are the priors of
/// registration, and the map is as good as from commands.
#[test]
fn odometry_moves_map_a_rendered_field_as_well_as_commands() {
    let src = rendered("field-multi", 1);
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("moves");
    let mut ds = pirouette::io::Dataset::open(&src).unwrap();
    let truth = ds.truth_poses().unwrap();
    let mut sweep = 0;
    for (i, f) in ds.manifest.frames.iter_mut().enumerate().skip(1) {
        let rel = truth[i - 1].inverse() * truth[i];
        let odometry = pirouette::geom::Pose2::new(1.08 * rel.x, 1.08 * rel.y, 0.95 * rel.theta);
        let m = pirouette::io::Motion::from_relative(&odometry);
        if !m.is_in_place_turn() {
            sweep += 1;
        }
        f.motion = Some(m);
        f.sweep = sweep;
    }
    assert!(sweep >= 5, "{sweep} moves");
    pirouette::io::Dataset::write_manifest(&root, &ds.manifest).unwrap();
    for f in &ds.manifest.frames {
        let to = root.join(&f.image);
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(src.join(&f.image), to).unwrap();
    }
    std::fs::create_dir_all(root.join("truth")).unwrap();
    std::fs::copy(src.join("truth/world.json"), root.join("truth/world.json")).unwrap();
    let r = map_and_eval(&root, &dir.path().join("map"));
    let ate = num(&r, &["trajectory", "ate_aligned_m"]);
    let odometry = num(&r, &["commanded", "ate_aligned_m"]);
    assert!(ate <= 0.01, "ATE {ate} m ({r})");
    assert!(ate * 5.0 < odometry, "{ate} against the odometry's {odometry}");
    assert!(num(&r, &["map", "f1"]) >= 0.98, "{r}");
}

/// A dataset with true poses but no scene (a real camera's recording with
/// motion capture) is scored on its trajectory alone; with the scene, the
/// map's figures stand beside the same trajectory figures.
#[test]
fn a_dataset_without_a_scene_is_scored_on_its_trajectory() {
    let src = rendered("field-pirouette", 1);
    let dir = tempfile::tempdir().unwrap();
    let with_scene = map_and_eval(&src, &dir.path().join("a"));
    let root = dir.path().join("no-scene");
    let ds = pirouette::io::Dataset::open(&src).unwrap();
    pirouette::io::Dataset::write_manifest(&root, &ds.manifest).unwrap();
    for f in &ds.manifest.frames {
        let to = root.join(&f.image);
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(src.join(&f.image), to).unwrap();
    }
    let without = map_and_eval(&root, &dir.path().join("b"));
    assert!(
        with_scene.get("map").is_some() && without.get("map").is_none(),
        "{without}"
    );
    assert_eq!(with_scene["trajectory"], without["trajectory"]);
    assert!(
        num(&without, &["trajectory", "ate_aligned_m"]) <= 0.02,
        "{without}"
    );
}
