//! Every dataset loads: the shared ones and the project's renders.

use crate::util::{rendered, shared, shared_datasets};
use pirouette::io::Dataset;
use std::path::Path;

fn load_all(root: &Path) -> usize {
    let ds = Dataset::open(root).unwrap_or_else(|e| panic!("{e}"));
    let m = &ds.manifest;
    for i in 0..m.frames.len() {
        let img = ds.load_image(i).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(img.dimensions(), (m.camera.width, m.camera.height));
        let truth = ds.truth_rop(i).unwrap_or_else(|e| panic!("{e}"));
        if let Some(t) = truth {
            assert!(!t.range.is_empty());
        }
    }
    ds.world().unwrap_or_else(|e| panic!("{e}"));
    ds.camera(None).unwrap_or_else(|e| panic!("{e}"));
    ds.camera(Some(pirouette::camera::ModelKind::Paper))
        .unwrap_or_else(|e| panic!("{e}"));
    m.frames.len()
}

#[test]
#[cfg_attr(not(shared_data), ignore = "needs the shared data: set PIROUETTE_SHARED")]
fn shared_datasets_load() {
    let shared = shared();
    let sets = shared_datasets(&shared);
    assert!(
        sets.len() >= 6,
        "expected the six shared datasets, found {}",
        sets.len()
    );
    for root in sets {
        let frames = load_all(&root);
        let ds = Dataset::open(&root).unwrap();
        // Every shared dataset carries truth for every frame.
        assert!(ds.truth_poses().is_some(), "{}", root.display());
        assert!(ds.truth_rop(frames - 1).unwrap().is_some(), "{}", root.display());
    }
}

#[test]
fn rendered_builtin_scenes_load() {
    for scene in pirouette::sim::BUILTIN_SCENES {
        let root = rendered(scene, 17);
        let frames = load_all(&root);
        let s = pirouette::sim::Scene::builtin(scene).unwrap();
        let sweeps = s.route.waypoints.len();
        assert_eq!(
            frames,
            sweeps * s.route.frames_per_sweep as usize + sweeps - 1,
            "{scene}"
        );
    }
}
