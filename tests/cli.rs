//! The command line: contract, help and errors.

use crate::util::{pirouette, shared};

#[test]
fn every_command_has_help() {
    for args in [
        vec!["--help"],
        vec!["render", "--help"],
        vec!["camera", "--help"],
        vec!["example", "--help"],
        vec!["profile", "--help"],
        vec!["eval", "--help"],
        vec!["map", "--help"],
        vec!["eval", "map", "--help"],
        vec!["graph", "optimise", "--help"],
        vec!["places", "build", "--help"],
        vec!["places", "info", "--help"],
        vec!["localise", "--help"],
        vec!["eval", "places", "--help"],
        vec!["bench", "--help"],
    ] {
        let out = pirouette(&args);
        assert!(out.status.success(), "{args:?}");
        assert!(String::from_utf8_lossy(&out.stdout).contains("Usage"), "{args:?}");
    }
}

#[test]
fn bad_input_is_a_one_line_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-such-dataset");
    let out = pirouette(&["camera", missing.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("no-such-dataset"), "{err}");

    // Each cause once: no part of the line repeats.
    let parts: Vec<&str> = err.trim().split(": ").collect();
    let distinct: std::collections::HashSet<&&str> = parts.iter().collect();
    assert_eq!(distinct.len(), parts.len(), "{err}");

    // A folder without a manifest: the reader's message already quotes the
    // operating system's, which does not follow it again.
    let empty = dir.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let out = pirouette(&["camera", empty.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("dataset.json"), "{err}");
    assert_eq!(err.matches("os error").count(), 1, "{err}");

    // A file that is not a manifest (a glob over a folder of datasets
    // catches its README too) says so.
    let readme = dir.path().join("README.md");
    std::fs::write(&readme, "# datasets").unwrap();
    let out = pirouette(&["camera", readme.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("README.md") && err.contains("not a dataset"),
        "{err}"
    );

    // Bad settings are named before any dataset is read.
    let out = pirouette(&["profile", missing.to_str().unwrap(), "--texture-ratio", "1.5"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("texture ratio") && !err.contains("no-such-dataset"),
        "{err}"
    );

    let bad = dir.path().join("bad");
    std::fs::create_dir_all(&bad).unwrap();
    std::fs::write(bad.join("dataset.json"), "{\"format\": \"rop-dataset/1\", ").unwrap();
    let out = pirouette(&["camera", bad.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("dataset.json") && err.contains("bad JSON"), "{err}");

    let scene = dir.path().join("scene.json");
    std::fs::write(&scene, "[]").unwrap();
    let out = pirouette(&[
        "render",
        scene.to_str().unwrap(),
        "--out",
        dir.path().join("o").to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("scene.json"));
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the shared data: set PIROUETTE_SHARED")]
fn camera_report_shows_models_agree_near_and_diverge_far() {
    let shared = shared();
    let ds = shared.join("datasets").join("field-pirouette");
    let out = pirouette(&["camera", ds.to_str().unwrap(), "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let bands: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(bands.len(), 12);
    let gap = |b: &serde_json::Value| b["median_gap_m"].as_f64().unwrap();
    // Near the centre scanline (where d and w were taped) the models agree
    // within a centimetre; at the top, the angle-linear rows drift further.
    assert!(gap(&bands[6]) < 0.01, "{}", bands[6]);
    assert!(
        gap(&bands[0]) > 3.0 * gap(&bands[6]),
        "{} vs {}",
        bands[0],
        bands[6]
    );
    assert!(
        bands[0]["median_range_bias"].as_f64().unwrap() < 0.0,
        "paper ranges run low far away"
    );
}

/// `camera --overlay` writes each image with its floor grid, titled, and
/// refuses an output that is a file before any work.
#[test]
fn camera_overlay_writes_one_picture_per_frame() {
    let ds_dir = crate::util::rendered("field-pirouette", 5);
    let ds = pirouette::io::Dataset::open(&ds_dir).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("overlay");
    let run = pirouette(&[
        "camera",
        ds_dir.to_str().unwrap(),
        "--overlay",
        out.to_str().unwrap(),
    ]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let written: Vec<_> = std::fs::read_dir(&out).unwrap().filter_map(|e| e.ok()).collect();
    assert_eq!(written.len(), ds.manifest.frames.len());
    // Each is the frame with a title above and a legend below.
    let first = image::open(out.join("s00-000-overlay.png")).unwrap();
    let frame = ds.load_image(0).unwrap();
    assert_eq!(first.width(), frame.width());
    assert!(first.height() > frame.height() + 20);
    let file = dir.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    let run = pirouette(&[
        "camera",
        ds_dir.to_str().unwrap(),
        "--overlay",
        file.to_str().unwrap(),
    ]);
    assert!(!run.status.success());
    assert!(String::from_utf8_lossy(&run.stderr).contains("not a folder"));
}

/// `eval suite --check` fails on a gated target the build misses, after
/// writing the scoreboard, and passes where the gate holds.
#[test]
fn suite_check_fails_on_a_gated_target() {
    let dir = tempfile::tempdir().unwrap();
    let corpus = dir.path().join("corpus.toml");
    let run = |gate: &str| {
        std::fs::write(
            &corpus,
            format!(
                "format = 1\n[targets.camera]\nate_aligned_m = {{ max = 0.000001{gate} }}\n\
                 f1 = {{ min = 0.5, gate = true }}\n\
                 [[camera]]\nscene = \"field-pirouette\"\nseeds = [1]\n"
            ),
        )
        .unwrap();
        let out = dir.path().join("board");
        let o = pirouette(&[
            "eval",
            "suite",
            "--corpus",
            corpus.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--check",
        ]);
        let md = std::fs::read_to_string(out.join("scoreboard.md")).unwrap();
        (o, md)
    };
    // Short of an ungated target: a row of the board, and check passes.
    let (o, md) = run("");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(md.contains("**ate_aligned_m**") && md.contains("none."), "{md}");
    // The same target gated: exit 1, the case and figure named.
    let (o, md) = run(", gate = true");
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("field-pirouette seed 1: ate_aligned_m"), "{err}");
    assert!(md.contains("- field-pirouette seed 1: ate_aligned_m"), "{md}");
}
