//! `pirouette sweep` and `pirouette eval sweep`.

use super::choices::Dissimilarity;
use super::profile::ProfileOptions;
use anyhow::{bail, Result};
use pirouette::eval::{tally_sweeps, SweepTally};
use pirouette::frame::DatasetSweep;
use pirouette::pipeline::{self, PipelineConfig};
use pirouette::profile::matching::{MatchConfig, Measure};
use pirouette::profile::sweep::SweepConfig;
use serde_json::json;
use std::path::PathBuf;

/// Settings of rotation verification.
#[derive(clap::Args, Debug, Clone, PartialEq)]
pub struct SweepOptions {
    #[command(flatten)]
    profile: ProfileOptions,
    /// Bin width of the profiles matched, degrees: fine bins (one image
    /// column is about 0.2°) let matching resolve a fraction of a degree.
    #[arg(long = "bin-deg", default_value_t = 0.25)]
    bin_deg: f64,
    /// Dissimilarity of two profiles' stretches.
    #[arg(long, value_enum, default_value_t = Dissimilarity::Robust)]
    measure: Dissimilarity,
    /// Half-width of the search window around the commanded turn, degrees.
    #[arg(long, default_value_t = 15.0)]
    window_deg: f64,
    /// Leave the loop of a full pirouette open.
    #[arg(long)]
    no_loop_closure: bool,
}

impl SweepOptions {
    /// The sweep settings.
    pub fn config(&self) -> Result<SweepConfig> {
        if !(self.window_deg.is_finite() && self.window_deg > 0.0 && self.window_deg <= 90.0) {
            bail!("--window-deg {} is outside (0, 90]", self.window_deg);
        }
        Ok(SweepConfig {
            matching: MatchConfig {
                window_rad: self.window_deg.to_radians(),
                measure: Measure::from(self.measure),
                ..MatchConfig::default()
            },
            close_loop: !self.no_loop_closure,
            ..SweepConfig::default()
        })
    }

    /// Checks every setting, before any dataset is read.
    pub fn check(&self) -> Result<()> {
        self.profile.config(self.bin_deg)?;
        self.config()?;
        Ok(())
    }

    /// The run's settings: these sweep settings, mapping's defaults.
    pub fn pipeline(&self) -> Result<PipelineConfig> {
        Ok(PipelineConfig {
            model: self.profile.model(),
            vision: self.profile.config(self.bin_deg)?,
            sweep: self.config()?,
            ..PipelineConfig::default()
        })
    }

    fn run(&self, ds: &pirouette::io::Dataset) -> Result<Vec<DatasetSweep>> {
        let bar = super::progress(ds.manifest.frames.len(), "profile");
        let swept = pipeline::sweep_dataset(ds, &self.pipeline()?, &|_| bar.inc(1))?;
        bar.finish_and_clear();
        Ok(swept.sweeps)
    }
}

/// Arguments of `pirouette sweep`.
#[derive(clap::Args, Debug)]
pub struct SweepArgs {
    /// The dataset folder.
    dataset: PathBuf,
    #[command(flatten)]
    options: SweepOptions,
    /// JSON Lines on stdout: one object per frame.
    #[arg(long)]
    json: bool,
    /// Write one top-down sweep diagram per sweep into this folder.
    #[arg(long)]
    plot: Option<PathBuf>,
}

/// Arguments of `pirouette eval sweep`.
#[derive(clap::Args, Debug)]
pub struct EvalSweepArgs {
    /// Dataset folders with true poses.
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    #[command(flatten)]
    options: SweepOptions,
    /// JSON Lines on stdout: one object per dataset, then the overall scores.
    #[arg(long)]
    json: bool,
}

fn deg(x: f64) -> serde_json::Value {
    json!((x.to_degrees() * 1e3).round() / 1e3)
}

/// `pirouette sweep`.
pub fn sweep(a: SweepArgs) -> Result<()> {
    a.options.check()?;
    let ds = super::open_dataset(&a.dataset)?;
    if let Some(dir) = &a.plot {
        super::check_output_dir(dir)?;
    }
    let sweeps = a.options.run(&ds)?;
    for s in &sweeps {
        let commanded = pipeline::commanded_turns(|i| ds.manifest.frames[i].motion, &s.frames);
        for (k, &i) in s.frames.iter().enumerate() {
            let f = &ds.manifest.frames[i];
            // To a microdegree: the command's own digits, not binary noise.
            let commanded = commanded[k].map(|c| (c.to_degrees() * 1e6).round() / 1e6);
            let t = s.sweep.turns[k];
            if a.json {
                let line = json!({
                    "image": f.image,
                    "sweep": s.id,
                    "commanded_turn_deg": commanded,
                    "estimated_turn_deg": t.map(|t| deg(t.turn_rad)),
                    "confidence": t.map(|t| (t.confidence * 1e3).round() / 1e3),
                    "fallback": t.is_some_and(|t| t.fallback),
                    "evidence": t.map(|t| t.evidence.name()),
                    "candidate_turn_deg": t.and_then(|t| t.candidate_rad).map(deg),
                    "heading_deg": deg(s.sweep.heading_rad[k]),
                });
                outln!("{line}")?;
            } else {
                match (commanded, t) {
                    (Some(c), Some(t)) => outln!(
                        "{:<22} sweep {:>2}  commanded {:>7.2}°  estimated {:>7.2}°  confidence {:.2}  {}",
                        f.image,
                        s.id,
                        c,
                        t.turn_rad.to_degrees(),
                        t.confidence,
                        if t.fallback {
                            format!("FALLBACK ({})", t.evidence.name())
                        } else {
                            format!("verified by {}", t.evidence.name())
                        }
                    )?,
                    _ => outln!("{:<22} sweep {:>2}  first frame of the sweep", f.image, s.id)?,
                }
            }
        }
        if !a.json {
            if let Some(c) = s.sweep.closure {
                if c.applied {
                    outln!(
                        "  loop closed against frame {}: residual {:.2}° spread over the turns",
                        c.frame,
                        c.residual_rad.to_degrees()
                    )?;
                } else if c.residual_rad.is_nan() {
                    outln!(
                        "  loop not closed: the closing match fell back ({})",
                        c.closing.evidence.name()
                    )?;
                } else {
                    outln!(
                        "  loop residual {:.2}° too large to spread: left open",
                        c.residual_rad.to_degrees()
                    )?;
                }
            }
        }
    }
    if let Some(dir) = &a.plot {
        super::plots::sweep_plots(&sweeps, dir)?;
        if !a.json {
            outln!("sweep diagrams written to {}", dir.display())?;
        }
    }
    Ok(())
}

/// `pirouette eval sweep`.
pub fn eval_sweep(a: EvalSweepArgs) -> Result<()> {
    a.options.check()?;
    let mut overall = SweepTally::default();
    // Every dataset opened and checked before the table starts.
    let datasets = a
        .datasets
        .iter()
        .map(|path| {
            let ds = super::open_dataset(path)?;
            if ds.truth_poses().is_none() {
                bail!(
                    "{}: frames without truth poses cannot be evaluated",
                    ds.manifest_path().display()
                );
            }
            Ok(ds)
        })
        .collect::<Result<Vec<_>>>()?;
    if !a.json {
        outln!(
            "{:<16} {:>5} {:>9} {:>5} {:>9} {:>9} {:>9} {:>6} {:>10} {:>9} {:>9}",
            "dataset",
            "turns",
            "verified",
            "loop",
            "med err",
            "p95 err",
            "max err",
            ">3° ok",
            "cmd err",
            "sweep hd",
            "cmd hd"
        )?;
    }
    for ds in &datasets {
        let sweeps = a.options.run(ds)?;
        let tally = tally_sweeps(ds, &sweeps).expect("truth poses checked above");
        print_scores(&ds.label(), &tally, a.json)?;
        overall.merge(&tally);
    }
    if a.datasets.len() > 1 {
        print_scores("overall", &overall, a.json)?;
    }
    if !a.json {
        outln!(
            "\nturns: turns checked; verified: turns whose match was trusted; loop: pirouettes whose loop closure\n\
             was applied; med/p95/max err: |estimated − true turn| over verified turns; >3° ok: verified turns\n\
             more than 3° off (wrong and not flagged); cmd err: median |commanded − true turn|; sweep hd, cmd hd:\n\
             median heading error accumulated over a sweep, estimated and commanded"
        )?;
    }
    Ok(())
}

fn print_scores(name: &str, tally: &SweepTally, json: bool) -> Result<()> {
    let s = tally.scores();
    if json {
        let mut v = serde_json::to_value(&s)?;
        v["dataset"] = json!(name);
        outln!("{v}")?;
    } else {
        outln!(
            "{:<16} {:>5} {:>8.1}% {:>5} {:>8.2}° {:>8.2}° {:>8.2}° {:>6} {:>9.2}° {:>8.2}° {:>8.2}°",
            name,
            s.turns,
            s.verified * 100.0,
            s.loop_fixed,
            s.median_verified_error_deg,
            s.p95_verified_error_deg,
            s.max_verified_error_deg,
            s.wrong_verified,
            s.median_commanded_error_deg,
            s.median_sweep_heading_error_deg,
            s.median_sweep_commanded_heading_error_deg
        )?;
    }
    Ok(())
}
