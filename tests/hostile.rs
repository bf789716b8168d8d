//! Hostile input: manifests that are valid JSON but describe no real robot,
//! and output paths that cannot be written. Each is refused with a one-line
//! error naming the file and the problem, before any work.

use crate::util::{pirouette, rendered};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// A copy of a rendered dataset's manifest, changed by `edit`, beside the
/// original's frames (linked, not copied).
fn dataset_with(dir: &Path, name: &str, edit: impl FnOnce(&mut Value)) -> PathBuf {
    let source = rendered("field-multi", 3);
    let root = dir.join(name);
    std::fs::create_dir_all(&root).unwrap();
    std::os::unix::fs::symlink(source.join("frames"), root.join("frames")).unwrap();
    let mut manifest: Value =
        serde_json::from_str(&std::fs::read_to_string(source.join("dataset.json")).unwrap()).unwrap();
    edit(&mut manifest);
    std::fs::write(root.join("dataset.json"), manifest.to_string()).unwrap();
    root
}

/// The first frame reached by a straight move, and one reached by a turn.
fn frames_by_motion(m: &Value) -> (usize, usize) {
    let frames = m["frames"].as_array().unwrap();
    let forward = frames
        .iter()
        .position(|f| f["motion"].get("forward").is_some())
        .unwrap();
    let turn = frames
        .iter()
        .position(|f| f["motion"].get("turn_deg").is_some())
        .unwrap();
    (forward, turn)
}

/// Runs `args`, which must fail with exit 1 and a one-line error naming
/// `names` and saying `says`.
pub(crate) fn refused(args: &[&str], names: &str, says: &str) {
    let out = pirouette(args);
    assert!(!out.status.success(), "{args:?} was accepted");
    assert_eq!(
        out.status.code(),
        Some(1),
        "{args:?}: exit {:?}, a panic or an abort",
        out.status
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
    assert!(
        err.contains(names) && err.contains(says),
        "{args:?}: `{err}` should name {names} and say {says}"
    );
}

#[test]
fn absurd_manifests_are_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    type Edit = Box<dyn FnOnce(&mut Value)>;
    let cases: Vec<(&str, Edit, &str)> = vec![
        (
            "forward-1e10",
            Box::new(|m| {
                let (f, _) = frames_by_motion(m);
                m["frames"][f]["motion"] = json!({"forward": 1e10});
            }),
            "beyond the 5 m limit",
        ),
        (
            "forward-mm",
            Box::new(|m| {
                let (f, _) = frames_by_motion(m);
                m["frames"][f]["motion"] = json!({"forward": 300.0});
            }),
            "millimetres",
        ),
        (
            "turn-1e308",
            Box::new(|m| {
                let (_, t) = frames_by_motion(m);
                m["frames"][t]["motion"] = json!({"turn_deg": 1e308});
            }),
            "more than a full turn",
        ),
        (
            "huge-camera",
            Box::new(|m| {
                m["camera"]["width"] = json!(100_000);
                m["camera"]["height"] = json!(100_000);
            }),
            "8192 pixels",
        ),
        (
            "ipm-flat",
            Box::new(|m| {
                m["camera"]["ipm"]["d"] = json!(0.0001);
            }),
            "field of view",
        ),
        (
            "ipm-mm",
            Box::new(|m| {
                m["camera"]["ipm"]["h"] = json!(100.0);
            }),
            "millimetres",
        ),
        (
            "fx-1e308",
            Box::new(|m| {
                m["camera"]["pinhole"]["fx"] = json!(1e308);
            }),
            "1e308",
        ),
        (
            "centre-outside",
            Box::new(|m| {
                m["camera"]["pinhole"]["cx"] = json!(-5.0);
            }),
            "principal point",
        ),
        (
            "mount-far",
            Box::new(|m| {
                m["camera"]["mount"] = json!({"forward": 3.0, "left": 0.0});
            }),
            "turning centre",
        ),
        (
            "range-far",
            Box::new(|m| {
                m["max_range"] = json!(1e6);
            }),
            "max_range",
        ),
        (
            "sweep-jump",
            Box::new(|m| {
                let (_, t) = frames_by_motion(m);
                m["frames"][t]["sweep"] = json!(7);
            }),
            "keeps the robot in sweep",
        ),
        (
            "sweep-stuck",
            Box::new(|m| {
                let (f, _) = frames_by_motion(m);
                let before = m["frames"][f - 1]["sweep"].clone();
                m["frames"][f]["sweep"] = before;
            }),
            "starts a new sweep",
        ),
    ];
    let mut checked = 0;
    for (name, edit, says) in cases {
        let root = dataset_with(dir.path(), name, edit);
        let manifest = root.join("dataset.json");
        for command in ["profile", "sweep", "map"] {
            let out = dir.path().join(format!("out-{name}"));
            let mut args = vec![command, root.to_str().unwrap()];
            if command == "map" {
                args.extend(["--out", out.to_str().unwrap()]);
            }
            refused(&args, manifest.to_str().unwrap(), says);
            checked += 1;
        }
    }
    assert_eq!(checked, 36);
}

#[test]
fn unusable_output_paths_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let ds = rendered("field-multi", 3);
    let file = dir.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    refused(
        &["map", ds.to_str().unwrap(), "--out", file.to_str().unwrap()],
        "a-file",
        "is a file, not a folder",
    );
    refused(
        &["map", ds.to_str().unwrap(), "--out", "/proc/no-such/map"],
        "/proc/no-such",
        "cannot create",
    );
    refused(
        &["profile", ds.to_str().unwrap(), "--plot", file.to_str().unwrap()],
        "a-file",
        "not a folder",
    );
    refused(
        &["render", "field-multi", "--out", file.to_str().unwrap()],
        "a-file",
        "not a folder",
    );
    refused(
        &["camera", ds.to_str().unwrap(), "--band-rows", "0"],
        "--band-rows",
        "at least 1",
    );
}

/// A process killed at any moment while it writes leaves the file it was
/// replacing intact, or the new one complete: never a torn file.
#[test]
fn killed_writers_leave_the_old_file_or_the_new_one() {
    use pirouette::graph::synthetic;
    use pirouette::io::{read_g2o, write_g2o, G2oGraph};
    let dir = tempfile::tempdir().unwrap();
    // A graph large enough that writing it takes a while; its odometry
    // chain alone (no loop closures to check), so that a run ends soon.
    let (mut graph, _) = synthetic::grid_world(60_000, 0.05, 0.01, 5);
    graph.edges.retain(|e| e.to == e.from + 1);
    let poses = graph.poses.len();
    let input = dir.path().join("in.g2o");
    write_g2o(
        &input,
        &G2oGraph {
            ids: (0..poses as u64).collect(),
            graph,
            has_vertices: true,
        },
    )
    .unwrap();
    let out = dir.path().join("out.g2o");
    let old = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n";
    let command = || {
        let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_pirouette"));
        c.args([
            "graph",
            "optimise",
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--max-iterations",
            "1",
        ])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null());
        c
    };
    // One run to its end: how long the kills have to land in.
    let start = std::time::Instant::now();
    assert!(command().status().unwrap().success());
    let whole = start.elapsed();
    assert_eq!(read_g2o(&out).unwrap().graph.poses.len(), poses);
    let (mut old_seen, mut new_seen) = (0, 0);
    // Kill after delays spread from the start to past the end of a run
    // (reading, solving, writing, done): 0 to 1.8 times its length.
    for k in 0..12u32 {
        std::fs::write(&out, old).unwrap();
        let mut child = command().spawn().unwrap();
        std::thread::sleep(whole * k / 6);
        let _ = child.kill();
        let _ = child.wait();
        let text = std::fs::read_to_string(&out).unwrap();
        if text == old {
            old_seen += 1;
        } else {
            let g = read_g2o(&out).expect("a complete new file");
            assert_eq!(g.graph.poses.len(), poses);
            new_seen += 1;
        }
    }
    assert!(old_seen > 0, "no kill landed before the rename");
    assert!(new_seen > 0, "no run got as far as its rename");
    eprintln!("killed 12 writers: the old file {old_seen} times, a complete new one {new_seen} times");
}
