//! Helpers shared by the end-to-end tests.

use pirouette::geom::Pose2;
use std::path::{Path, PathBuf};
use std::process::Output;

/// The shared folder from `PIROUETTE_SHARED`. The tests that call this are
/// marked `ignore` in builds without the variable (see `build.rs`), so here
/// it is set: a missing folder or missing data fails the test.
pub fn shared() -> PathBuf {
    let p = PathBuf::from(std::env::var_os("PIROUETTE_SHARED").expect("PIROUETTE_SHARED is set"));
    assert!(
        p.join("datasets").is_dir(),
        "PIROUETTE_SHARED={} has no datasets/",
        p.display()
    );
    p
}

/// The camera datasets under `shared/datasets`, sorted.
pub fn shared_datasets(shared: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(shared.join("datasets"))
        .expect("shared/datasets is readable")
        .map(|e| e.expect("directory entry").path())
        .filter(|p| p.join("dataset.json").is_file())
        .collect();
    v.sort();
    v
}

/// Runs the `pirouette` binary.
pub fn pirouette(args: &[&str]) -> Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_pirouette"))
        .args(args)
        .output()
        .expect("the pirouette binary runs")
}

/// Renders a built-in scene once per test process into a temporary folder.
pub fn rendered(scene: &str, seed: u64) -> PathBuf {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    static CACHE: OnceLock<Mutex<HashMap<(String, u64), PathBuf>>> = OnceLock::new();
    static ROOT: OnceLock<tempfile::TempDir> = OnceLock::new();
    let root = ROOT.get_or_init(|| tempfile::tempdir().expect("temporary folder"));
    let mut cache = CACHE
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    cache
        .entry((scene.to_string(), seed))
        .or_insert_with(|| {
            let out = root.path().join(format!("{scene}-{seed}"));
            let s = pirouette::sim::Scene::builtin(scene).expect("built-in scene");
            pirouette::sim::render_dataset(&s, seed, &out, |_, _| {}).expect("render succeeds");
            out
        })
        .clone()
}

/// A path along `sides` sides of the ring corridor
/// (`pirouette::sim::Walls::ring`) from its first corner, in steps of
/// `step_m` along each, then `turns` in-place turns of `turn_deg` at its
/// end.
pub fn ring_path(sides: usize, step_m: f64, turns: usize, turn_deg: f64) -> Vec<Pose2> {
    let corners = [[2.0, 1.5], [10.0, 1.5], [10.0, 6.5], [2.0, 6.5]];
    let mut path = vec![Pose2::new(2.0, 1.5, 0.0)];
    for side in 0..sides {
        let [x1, y1] = corners[(side + 1) % 4];
        let start = *path.last().expect("a start");
        let steps = ((x1 - start.x).hypot(y1 - start.y) / step_m).round() as usize;
        for s in 1..=steps {
            let f = s as f64 / steps as f64;
            path.push(Pose2::new(
                start.x + f * (x1 - start.x),
                start.y + f * (y1 - start.y),
                start.theta,
            ));
        }
        for _ in 0..turns {
            let p = *path.last().expect("a pose");
            path.push(Pose2::new(p.x, p.y, p.theta + turn_deg.to_radians()));
        }
    }
    path
}
