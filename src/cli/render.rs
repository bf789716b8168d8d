//! `pirouette render` and `pirouette example`.

use anyhow::{Context, Result};
use pirouette::eval::{tally_sweeps, ProfileTally};
use pirouette::io::{Dataset, Motion};
use pirouette::pipeline;
use pirouette::sim::{render_dataset, Scene, BUILTIN_SCENES};
use pirouette::vision::VisionConfig;
use std::path::{Path, PathBuf};

/// Arguments of `pirouette render`.
#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// A built-in scene (field-pirouette, field-multi, room-multi; field-multi-b
    /// and room-multi-b: their scenes on other routes and in other light) or a
    /// JSON scene file.
    scene: String,
    /// Folder to write the dataset into.
    #[arg(long)]
    out: PathBuf,
    /// Seed of motion errors, floor pattern, specks and noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// Arguments of `pirouette example`.
#[derive(clap::Args, Debug)]
pub struct ExampleArgs {
    /// Folder for the rendered example and the results.
    #[arg(long, default_value = "out/example")]
    out: PathBuf,
}

fn load_scene(name: &str) -> Result<Scene> {
    if let Some(s) = Scene::builtin(name) {
        return Ok(s);
    }
    let path = Path::new(name);
    if !path.exists() {
        anyhow::bail!(
            "{name}: no such scene file, and not a built-in scene ({})",
            BUILTIN_SCENES.join(", ")
        );
    }
    Ok(Scene::from_file(path)?)
}

fn render_with_progress(scene: &Scene, seed: u64, out: &Path) -> Result<Dataset> {
    // Drawn once the renderer has said how many frames there are (not
    // as "0/0" before).
    let bar = super::progress(0, "render");
    bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    render_dataset(scene, seed, out, |done, total| {
        if bar.length() != Some(total as u64) {
            bar.set_length(total as u64);
            bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
        }
        bar.set_position(done as u64);
    })
    .with_context(|| format!("rendering into {}", out.display()))?;
    bar.finish_and_clear();
    super::open_dataset(out)
}

/// Prints what a dataset holds.
pub fn summary(ds: &Dataset) -> Result<()> {
    let m = &ds.manifest;
    let sweeps = m
        .frames
        .iter()
        .map(|f| f.sweep)
        .collect::<std::collections::BTreeSet<_>>()
        .len();
    let (mut turns, mut forward_m) = (0, 0.0);
    for f in &m.frames {
        match f.motion {
            Some(Motion::Turn { .. }) => turns += 1,
            Some(Motion::Forward { forward }) => forward_m += forward,
            Some(Motion::Move { relative }) => {
                turns += usize::from(relative.turn_deg != 0.0);
                forward_m += relative.forward.hypot(relative.left);
            }
            None => {}
        }
    }
    outln!("dataset   {} ({})", m.name, ds.root.display())?;
    outln!(
        "frames    {} in {} sweeps; {} turns, {:.2} m of forward moves",
        m.frames.len(),
        sweeps,
        turns,
        forward_m
    )?;
    outln!(
        "camera    {}x{}, {} model by default, max range {:.2} m",
        m.camera.width,
        m.camera.height,
        if m.camera.pinhole.is_some() {
            "pinhole"
        } else {
            "paper"
        },
        m.max_range
    )?;
    if let Ok(Some(w)) = ds.world() {
        outln!(
            "truth     scene with {} obstacles, true poses and profiles",
            w.obstacles.len()
        )?;
    }
    Ok(())
}

/// `pirouette render`.
pub fn render(a: RenderArgs) -> Result<()> {
    let scene = load_scene(&a.scene)?;
    super::check_output_dir(&a.out)?;
    let ds = render_with_progress(&scene, a.seed, &a.out)?;
    summary(&ds)
}

/// The built-in example: the multi-sweep soccer field.
pub const EXAMPLE_SCENE: &str = "field-multi";
/// Its seed.
pub const EXAMPLE_SEED: u64 = 2004;

/// `pirouette example`: render, profile every frame, verify the turns,
/// build the map, score everything against truth, draw pictures.
pub fn example(a: ExampleArgs) -> Result<()> {
    let scene = Scene::builtin(EXAMPLE_SCENE).expect("the example scene is built in");
    super::check_output_dir(&a.out)?;
    let dataset_dir = a.out.join("dataset");
    let ds = render_with_progress(&scene, EXAMPLE_SEED, &dataset_dir)?;
    summary(&ds)?;

    let extractor = pipeline::extractor(&ds, None, VisionConfig::default())?;
    let bar = super::progress(ds.manifest.frames.len(), "profile");
    let rops = pipeline::profiles(&ds, &extractor, || bar.inc(1))?;
    bar.finish_and_clear();
    let mut tally = ProfileTally::default();
    for (i, rop) in rops.iter().enumerate() {
        if let Some(t) = ds.truth_rop(i)? {
            tally.add(rop, &t);
        }
    }
    let s = tally.scores();
    outln!(
        "profiles  median range error {:.2} %, {:.1} % of obstacle bins within 10 %, {:.1} % missed, {:.2} % false",
        s.median_abs_rel_error * 100.0,
        s.within_10pct * 100.0,
        s.missed * 100.0,
        s.false_range * 100.0
    )?;
    let plots = a.out.join("profiles");
    let camera = ds.camera(None)?;
    super::plots::profile_plots(&ds, &extractor, &camera, &rops, &plots)?;

    // Verified turns, sweeps and the map, on fine profiles.
    let options = super::map::MapOptions::default();
    let (ds, mapped) = super::map::map_dataset(ds, &options)?;
    if let Some(tally) = tally_sweeps(&ds, &mapped.swept.sweeps) {
        let t = tally.scores();
        outln!(
            "turns     {:.0} % verified, median error {:.2}° (commanded {:.2}°); verified turns off by over 3°: {}",
            t.verified * 100.0,
            t.median_verified_error_deg,
            t.median_commanded_error_deg,
            t.wrong_verified
        )?;
        outln!(
            "sweeps    heading error accumulated over a sweep {:.2}° median (commanded {:.2}°)",
            t.median_sweep_heading_error_deg,
            t.median_sweep_commanded_heading_error_deg
        )?;
    }
    let map_dir = a.out.join("map");
    super::map::write_map(&ds, &mapped, &map_dir)?;
    let report = super::map::evaluate(&ds, &mapped.swept, &mapped.config, &map_dir, 2.0)?;
    outln!(
        "map       trajectory error {:.2} cm (ATE, aligned; commanded motion {:.2} cm); occupied-cell F1 {:.3} (true poses {:.3})",
        report.trajectory.ate_aligned_m * 100.0,
        report.commanded.ate_aligned_m * 100.0,
        report.scene.as_ref().map_or(f64::NAN, |s| s.map.f1),
        report.scene.as_ref().map_or(f64::NAN, |s| s.true_pose_map.f1)
    )?;
    let sweeps = &mapped.swept.sweeps;
    let sweep_dir = a.out.join("sweeps");
    super::plots::sweep_plots(sweeps, &sweep_dir)?;
    outln!(
        "\nlook at  {}  (per frame: -boundary.png, -rop.png, -floor.png)",
        plots.display()
    )?;
    outln!(
        "         {}  (one 360° sweep diagram per spot)",
        sweep_dir.display()
    )?;
    outln!(
        "         {}  (the map with the trajectory; map.pgm/.yaml for ROS, poses.json, poses.tum)",
        map_dir.join(pirouette::io::map_names::PNG).display()
    )?;
    Ok(())
}
