//! `pirouette profile` and `pirouette eval profile`.

use super::choices::{Filter, Model};
use anyhow::{bail, Result};
use pirouette::camera::ModelKind;
use pirouette::eval::{ProfileTally, SceneView};
use pirouette::pipeline;
use pirouette::profile::filter::OutlierFilter;
use pirouette::vision::VisionConfig;
use serde_json::json;
use std::path::PathBuf;

/// Settings shared by the commands that build profiles.
#[derive(clap::Args, Debug, Clone, PartialEq)]
pub struct ProfileOptions {
    /// Camera model: paper (the four tape measurements) or pinhole. Default:
    /// the most accurate one the dataset's camera allows.
    #[arg(long, value_enum)]
    model: Option<Model>,
    /// Outlier filter over the bins.
    #[arg(long, value_enum, default_value_t = Filter::Median3)]
    filter: Filter,
    /// The lowest obstacle to detect, metres (flatter things are floor).
    #[arg(long, default_value_t = VisionConfig::default().min_obstacle_height_m)]
    min_obstacle_height: f64,
    /// Relative brightness step (same chromaticity) that leaves the floor.
    #[arg(long, default_value_t = VisionConfig::default().min_brightness_step)]
    min_brightness_step: f32,
    /// Relative chromaticity change that leaves the floor.
    #[arg(long, default_value_t = VisionConfig::default().min_chroma_step)]
    min_chroma_step: f32,
    /// Steps must also exceed this many standard deviations of the image noise.
    #[arg(long, default_value_t = VisionConfig::default().noise_sigmas)]
    noise_sigmas: f32,
    /// At a step within one image row, this fraction of the chromaticity
    /// change is enough (1 turns the edge cue off).
    #[arg(long, default_value_t = VisionConfig::default().edge_fraction)]
    edge_fraction: f32,
    /// At a step of brightness alone within one image row, the most texture
    /// above it, as a share of the floor's below, that makes it an
    /// obstacle's base (0 turns the texture cue off). Profiles and maps
    /// use it; turns are verified on profiles without it.
    #[arg(long, default_value_t = VisionConfig::default().texture_ratio)]
    texture_ratio: f32,
    /// A faint step of brightness alone: more than this fraction of the
    /// brightness tolerance within one image row (by default a third), but
    /// less than the edge fraction.
    #[arg(long, default_value_t = VisionConfig::default().faint_step_fraction)]
    faint_step_fraction: f32,
    /// The most texture above a faint step, as a share of the floor's
    /// below, that makes it an obstacle's base (by default a third; 0 turns
    /// faint steps off).
    #[arg(long, default_value_t = VisionConfig::default().faint_texture_ratio)]
    faint_texture_ratio: f32,
    /// Columns each side over which the line cue pools the floor's grain
    /// along a candidate base, finding smooth walls of the floor's own
    /// brightness where the grain ends (0 turns it off; so does a texture
    /// ratio of 0).
    #[arg(long, default_value_t = VisionConfig::default().line_columns)]
    line_columns: u32,
    /// The deepest mark on the floor, metres: a base above which the floor
    /// shows again within this depth (tape, a stain, a flat cable, or an
    /// obstacle too low to tell from them) is left undecided, the floor
    /// known only up to it (0, the default, decides every base as an
    /// obstacle; 0.25 takes most marks).
    #[arg(long, default_value_t = VisionConfig::default().mark_depth_m)]
    mark_depth: f32,
}

impl ProfileOptions {
    pub fn model(&self) -> Option<ModelKind> {
        self.model.map(ModelKind::from)
    }

    pub fn config(&self, bin_deg: f64) -> Result<VisionConfig> {
        if !(bin_deg.is_finite() && (0.05..=10.0).contains(&bin_deg)) {
            bail!("--bin-deg {bin_deg} is outside 0.05..10");
        }
        let config = VisionConfig {
            bin_width_rad: bin_deg.to_radians(),
            min_obstacle_height_m: self.min_obstacle_height,
            min_brightness_step: self.min_brightness_step,
            min_chroma_step: self.min_chroma_step,
            noise_sigmas: self.noise_sigmas,
            edge_fraction: self.edge_fraction,
            texture_ratio: self.texture_ratio,
            faint_step_fraction: self.faint_step_fraction,
            faint_texture_ratio: self.faint_texture_ratio,
            line_columns: self.line_columns,
            mark_depth_m: self.mark_depth,
            filter: OutlierFilter::from(self.filter),
            ..VisionConfig::default()
        };
        // Checked before any dataset is read, so that the error names the
        // settings, not a dataset.
        config.validate()?;
        Ok(config)
    }
}

/// Arguments of `pirouette profile`.
#[derive(clap::Args, Debug)]
pub struct ProfileArgs {
    /// The dataset folder.
    dataset: PathBuf,
    #[command(flatten)]
    options: ProfileOptions,
    /// Bin width of the profile, degrees (down to 0.2°: one image column).
    #[arg(long = "bin-deg", default_value_t = 1.0)]
    bin_deg: f64,
    /// JSON Lines on stdout: one object per frame.
    #[arg(long)]
    json: bool,
    /// Write per-frame pictures (ROP diagram, top-down floor view) into this folder.
    #[arg(long)]
    plot: Option<PathBuf>,
}

/// Arguments of `pirouette eval profile`.
#[derive(clap::Args, Debug)]
pub struct EvalProfileArgs {
    /// Dataset folders with truth/rop.
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    #[command(flatten)]
    options: ProfileOptions,
    /// Bin width of the profile, degrees.
    #[arg(long = "bin-deg", default_value_t = 1.0)]
    bin_deg: f64,
    /// JSON Lines on stdout: one object per dataset and model, then the overall scores.
    #[arg(long)]
    json: bool,
}

fn json_value(x: f64) -> serde_json::Value {
    // Four decimals (0.1 mm): what the profile can resolve, and short lines.
    json!((x * 1e4).round() / 1e4)
}

/// `pirouette profile`.
pub fn profile(a: ProfileArgs) -> Result<()> {
    let config = a.options.config(a.bin_deg)?;
    let ds = super::open_dataset(&a.dataset)?;
    if let Some(dir) = &a.plot {
        super::check_output_dir(dir)?;
    }
    let extractor = pipeline::extractor(&ds, a.options.model(), config)?;
    let bar = super::progress(ds.manifest.frames.len(), "profile");
    let rops = pipeline::profiles(&ds, &extractor, || bar.inc(1))?;
    bar.finish_and_clear();
    for (f, rop) in ds.manifest.frames.iter().zip(&rops) {
        let range: Vec<serde_json::Value> = (0..rop.len())
            .map(|i| rop.reliable(i).map_or(json!(null), |r| json_value(r as f64)))
            .collect();
        if a.json {
            let rgb: Vec<serde_json::Value> = (0..rop.len())
                .map(|i| rop.reliable_colour(i).map_or(json!(null), |c| json!(c.0)))
                .collect();
            let line = json!({
                "image": f.image,
                "bearing_start_deg": json_value(rop.bearing_start_deg()),
                "bin_deg": json_value(rop.bin_width_deg()),
                "range": range,
                "rgb": rgb,
            });
            outln!("{line}")?;
        } else {
            let hits: Vec<f32> = (0..rop.len()).filter_map(|i| rop.reliable(i)).collect();
            let nearest = hits.iter().copied().fold(f32::INFINITY, f32::min);
            if hits.is_empty() {
                outln!("{:<24} {:>3} of {} bins with an obstacle", f.image, 0, rop.len())?;
            } else {
                outln!(
                    "{:<24} {:>3} of {} bins with an obstacle, nearest {:.3} m",
                    f.image,
                    hits.len(),
                    rop.len(),
                    nearest
                )?;
            }
        }
    }
    if let Some(dir) = &a.plot {
        let camera = ds.camera(a.options.model())?;
        super::plots::profile_plots(&ds, &extractor, &camera, &rops, dir)?;
        if !a.json {
            outln!("pictures written to {}", dir.display())?;
        }
    }
    Ok(())
}

/// `pirouette eval profile`.
pub fn eval_profile(a: EvalProfileArgs) -> Result<()> {
    let config = a.options.config(a.bin_deg)?;
    let mut overall: Vec<(ModelKind, ProfileTally)> = Vec::new();
    // Every dataset opened before the table starts.
    let datasets = a
        .datasets
        .iter()
        .map(|path| super::open_dataset(path))
        .collect::<Result<Vec<_>>>()?;
    if !a.json {
        outln!(
            "{:<18} {:<8} {:>10} {:>9} {:>10} {:>8} {:>9} {:>9} {:>7} {:>7}",
            "dataset",
            "model",
            "|rel err|",
            "bias",
            "within10%",
            "missed",
            "false rng",
            "(scene)",
            "truth",
            "free"
        )?;
    }
    for ds in &datasets {
        let models = match a.options.model() {
            Some(m) => vec![m],
            None if ds.manifest.camera.pinhole.is_some() => vec![ModelKind::Pinhole, ModelKind::Paper],
            None => vec![ModelKind::Paper],
        };
        let truths = (0..ds.manifest.frames.len())
            .map(|i| ds.truth_rop(i))
            .collect::<Result<Vec<_>, _>>()?;
        if truths.iter().all(Option::is_none) {
            bail!("{}: no truth/rop files to evaluate against", ds.root.display());
        }
        // The scene, where the dataset has one, checks the false ranges
        // again (the true camera: the most accurate model).
        let world = ds.world()?;
        let poses = ds.truth_poses();
        let true_camera = ds.camera(None)?;
        let scenes: Vec<Option<SceneView<'_>>> = (0..truths.len())
            .map(|i| {
                let (world, poses) = (world.as_ref()?, poses.as_ref()?);
                Some(SceneView {
                    world,
                    camera: &true_camera,
                    world_from_robot: poses[i],
                    max_range_m: ds.manifest.max_range,
                })
            })
            .collect();
        for model in models {
            let extractor = pipeline::extractor(ds, Some(model), config.clone())?;
            let bar = super::progress(ds.manifest.frames.len(), "profile");
            let rops = pipeline::profiles(ds, &extractor, || bar.inc(1))?;
            bar.finish_and_clear();
            let mut tally = ProfileTally::default();
            for ((rop, truth), scene) in rops.iter().zip(&truths).zip(&scenes) {
                if let Some(t) = truth {
                    tally.add_with_scene(rop, t, scene.as_ref());
                }
            }
            print_scores(&ds.label(), model, &tally, a.json)?;
            match overall.iter_mut().find(|(m, _)| *m == model) {
                Some((_, t)) => t.merge(&tally),
                None => overall.push((model, tally)),
            }
        }
    }
    if a.datasets.len() > 1 {
        for (model, tally) in &overall {
            print_scores("overall", *model, tally, a.json)?;
        }
    }
    if !a.json {
        outln!(
            "\n|rel err|: median |measured − true| / true over the truth bins measured; bias: the same, signed\n\
             within10%: truth bins measured within 10 %; missed: truth bins given no range\n\
             false rng: obstacle-free bins given a range; (scene): the same, counting only bins where the scene\n\
             cast densely has no obstacle either; truth, free: bins with and without a true obstacle"
        )?;
    }
    Ok(())
}

pub fn model_name(m: ModelKind) -> &'static str {
    match m {
        ModelKind::Paper => "paper",
        ModelKind::Pinhole => "pinhole",
    }
}

fn print_scores(name: &str, model: ModelKind, tally: &ProfileTally, json: bool) -> Result<()> {
    let s = tally.scores();
    if json {
        let mut v = serde_json::to_value(&s).expect("scores serialise");
        v["dataset"] = json!(name);
        v["model"] = json!(model_name(model));
        outln!("{v}")?;
    } else {
        outln!(
            "{:<18} {:<8} {:>9.2}% {:>8.2}% {:>9.1}% {:>7.1}% {:>8.2}% {:>9} {:>7} {:>7}",
            name,
            model_name(model),
            s.median_abs_rel_error * 100.0,
            s.median_rel_bias * 100.0,
            s.within_10pct * 100.0,
            s.missed * 100.0,
            s.false_range * 100.0,
            s.false_range_scene
                .map_or_else(|| "-".to_string(), |f| format!("{:.2}%", f * 100.0)),
            s.truth_bins,
            s.free_bins
        )?;
    }
    Ok(())
}
