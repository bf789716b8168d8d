//! Pirouette's own renderer: scenes of boxes and cylinders on a floor,
//! rendered through a pinhole camera into complete `rop-dataset/1` datasets
//! with ground truth.
//!
//! - [`Scene`]: the scene file format (world, camera, look, route, motion
//!   errors); [`Scene::builtin`] has the built-in scenes.
//! - [`plan_route`]: the commanded motions of a route and the actual poses
//!   they produce under turn and distance errors and a drifting rotation
//!   centre.
//! - [`Renderer`]: the ray caster (shading, vignetting, floor variation,
//!   specks, sensor noise, 2 × 2 supersampling).
//! - [`true_profile`]: the true radial profile of a pose, by 2D ray casting.
//! - [`render_dataset`]: all of it, written to a folder.
//! - [`LogSim`]: simulated 2D laser logs (CARMEN text) of a path among
//!   [`Walls`], such as an [`OfficeFloor`] the robot wanders for ever.
//!
//! ```no_run
//! use pirouette_sim::{Scene, render_dataset};
//! let scene = Scene::builtin("field-pirouette").ok_or("no such scene")?;
//! render_dataset(&scene, 7, "out/field".as_ref(), |_done, _total| {})?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

mod laser;
mod motion;
mod render;
mod scene;
mod truth;

pub use laser::{LogLine, LogSim, LogWriter, OfficeFloor, Walls};
pub use motion::{plan_route, PlannedFrame};
pub use render::Renderer;
pub use scene::{CameraSetup, Look, MotionErrors, Route, Scene, SimError, BUILTIN_SCENES};
pub use truth::{nearest_in_view, true_profile, RAYS_PER_BIN};

use pirouette_camera::FloorTable;
use pirouette_io::{
    CameraSpec, Dataset, FrameSpec, Manifest, MountSpec, PinholeSpec, PoseSpec, TruthRop, FORMAT_VERSION,
};
use std::path::Path;

/// Bin width of the true profiles written to `truth/rop`, degrees.
pub const TRUTH_BIN_WIDTH_DEG: f64 = 1.0;

/// Renders `scene` with `seed` into a complete dataset in `out`: manifest,
/// frames, `truth/world.json` and `truth/rop`. `progress(done, total)` is
/// called after each frame. Files are written atomically.
pub fn render_dataset(
    scene: &Scene,
    seed: u64,
    out: &Path,
    mut progress: impl FnMut(usize, usize),
) -> Result<Manifest, SimError> {
    scene.validate()?;
    let camera = scene.camera.pinhole();
    let ipm = camera.ipm_measurements().ok_or(SimError::Invalid {
        problem: "camera: the centre scanline does not see the floor (tilt too small)".into(),
    })?;
    let view = FloorTable::new(&camera).bearing_span().ok_or(SimError::Invalid {
        problem: "camera: no pixel sees the floor".into(),
    })?;
    let frames = plan_route(scene, seed);
    let renderer = Renderer::new(scene, seed);
    let mut specs = Vec::with_capacity(frames.len());
    for (k, f) in frames.iter().enumerate() {
        let image_rel = format!("frames/s{:02}/{:03}.png", f.sweep, f.index_in_sweep);
        let img = renderer.render(&f.world_from_robot, k as u64);
        Dataset::write_image(out, &image_rel, &img)?;
        let rop = true_profile(
            &scene.world,
            &camera,
            &f.world_from_robot,
            scene.max_range,
            TRUTH_BIN_WIDTH_DEG.to_radians(),
            view,
        );
        Dataset::write_truth_rop(out, &image_rel, &TruthRop::from_rop(&rop))?;
        specs.push(FrameSpec {
            image: image_rel,
            sweep: f.sweep,
            motion: f.motion,
            truth: Some(PoseSpec::from(f.world_from_robot)),
        });
        progress(k + 1, frames.len());
    }
    Dataset::write_world(out, &scene.world)?;
    let manifest = Manifest {
        format: FORMAT_VERSION.into(),
        name: scene.name.clone(),
        camera: CameraSpec {
            width: camera.width,
            height: camera.height,
            ipm,
            pinhole: Some(PinholeSpec {
                fx: camera.fx,
                fy: camera.fy,
                cx: camera.cx,
                cy: camera.cy,
                height: camera.height_m,
                tilt_deg: camera.tilt_rad.to_degrees(),
                distortion: pirouette_io::LensSpec::of(&camera.distortion),
            }),
            mount: Some(MountSpec {
                forward: camera.mount_forward_m,
                left: camera.mount_left_m,
            }),
        },
        max_range: scene.max_range,
        frames: specs,
    };
    // The manifest goes last: a dataset folder with a manifest is complete.
    Dataset::write_manifest(out, &manifest)?;
    Ok(manifest)
}
