//! `pirouette places build`, `places info`, `localise` and `eval places`.

use super::sweep::SweepOptions;
use anyhow::{bail, Context, Result};
use pirouette::frame::DatasetSweep;
use pirouette::geom::{wrap_angle, Pose2};
use pirouette::io::{read_place_index, write_place_index, Dataset};
use pirouette::localise::{file_sweeps, localise, Answer, LocaliseConfig, Verdict};
use pirouette::pipeline;
use pirouette::places::{PlaceIndex, SignatureConfig};
use serde_json::json;
use std::path::{Path, PathBuf};

/// Arguments of `pirouette places build`.
#[derive(clap::Args, Debug)]
pub struct PlacesBuildArgs {
    /// Dataset folders (one place per sweep).
    #[arg(required = true)]
    datasets: Vec<PathBuf>,
    /// The index file to write (replaced atomically).
    #[arg(long)]
    out: PathBuf,
    /// DCT coefficients kept per place.
    #[arg(long, default_value_t = SignatureConfig::default().coefficients)]
    coefficients: usize,
    #[command(flatten)]
    sweep: SweepOptions,
}

/// Arguments of `pirouette places info`.
#[derive(clap::Args, Debug)]
pub struct PlacesInfoArgs {
    /// The place index file.
    index: PathBuf,
    /// One JSON line on stdout.
    #[arg(long)]
    json: bool,
}

/// Arguments of `pirouette localise`.
#[derive(clap::Args, Debug)]
pub struct LocaliseArgs {
    /// The place index file.
    #[arg(long)]
    index: PathBuf,
    /// The query dataset folder.
    dataset: PathBuf,
    /// JSON Lines on stdout: one object per sweep.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    sweep: SweepOptions,
}

/// Arguments of `pirouette eval places`.
#[derive(clap::Args, Debug)]
pub struct EvalPlacesArgs {
    /// The query dataset folder, with true poses.
    query: PathBuf,
    /// The place index, built from datasets with true poses in the same
    /// world frame (the same scene).
    index: PathBuf,
    /// Folder for the precision-recall curve (`places-pr.png`).
    #[arg(long)]
    out: Option<PathBuf>,
    /// One JSON object on stdout.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    sweep: SweepOptions,
}

/// Runs `pirouette places build`.
pub fn build(a: PlacesBuildArgs) -> Result<()> {
    let config = a.sweep.pipeline()?;
    config.check()?;
    super::check_output_file(&a.out)?;
    let mut index = PlaceIndex::new(SignatureConfig {
        coefficients: a.coefficients,
        ..SignatureConfig::default()
    })
    .context("--coefficients")?;
    for path in &a.datasets {
        let ds = super::open_dataset(path)?;
        let swept = sweep_with_bar(&ds, &a.sweep)?;
        // The sweeps placed in the dataset's map: a query's matches to two
        // places then agree or not by where they put it.
        let bar = super::progress(
            pirouette::mapping::progress_steps(swept.sweeps.len()),
            "map steps",
        );
        let run = pipeline::map_swept(&ds, &swept, &swept.map_config(&config), &|_| bar.inc(1));
        bar.finish_and_clear();
        // A dataset that cannot be mapped is filed without map poses: its
        // places' look-alikes are then told apart by their views alone.
        let run = run
            .map_err(|e| {
                eprintln!(
                    "{}: not mapped ({e:#}); its places are filed without map poses",
                    ds.manifest.name
                )
            })
            .ok();
        let (filed, left_out) = file_sweeps(
            &mut index,
            &ds,
            &swept.sweeps,
            run.as_ref(),
            &LocaliseConfig::default(),
        )?;
        eprintln!("{}: {filed} places", ds.manifest.name);
        if !left_out.is_empty() {
            eprintln!(
                "{}: sweeps {left_out:?} saw too little of the circle and were left out",
                ds.manifest.name
            );
        }
    }
    if index.is_empty() {
        bail!("no sweep of the datasets saw enough of the circle to be a place; nothing written");
    }
    write_place_index(&a.out, &index)?;
    let bytes = std::fs::metadata(&a.out).map(|m| m.len()).unwrap_or(0);
    outln!(
        "{} places, {} bytes each (signature and key), {bytes} bytes on disk → {}",
        index.len(),
        index.contents().config.signature_bytes(),
        a.out.display()
    )?;
    Ok(())
}

/// Runs `pirouette places info`.
pub fn info(a: PlacesInfoArgs) -> Result<()> {
    let (index, header) = read_place_index(&a.index)?;
    let c = index.contents();
    let profile_bytes: usize = c
        .meta
        .iter()
        .filter_map(|m| m.profile.as_ref())
        .map(|p| 2 * p.range_mm.len())
        .sum();
    let per_profile = if index.is_empty() {
        0
    } else {
        profile_bytes / index.len()
    };
    if a.json {
        outln!(
            "{}",
            json!({
                "places": index.len(),
                "bytes_per_place": c.config.signature_bytes(),
                "profile_bytes_per_place": per_profile,
                "file_bytes": header.file_bytes,
                "format": header.format,
                "coefficients": c.config.coefficients,
                "datasets": c.datasets,
                "limit_m": c.limit_m,
            })
        )?;
        return Ok(());
    }
    outln!(
        "{}: place index, format {}, checksum verified",
        a.index.display(),
        header.format
    )?;
    outln!("places            {}", index.len())?;
    outln!("datasets          {}", c.datasets.join(", "))?;
    outln!(
        "bytes per place   {} (signature and key: K = {} DCT coefficients, a {}-number key, {} colour sectors)",
        c.config.signature_bytes(),
        c.config.coefficients,
        pirouette::places::KEY_DIMS,
        c.config.sectors
    )?;
    outln!("profile per place {per_profile} bytes (kept for metric refinement)")?;
    outln!("size on disk      {} bytes", header.file_bytes)?;
    if let Some(l) = c.limit_m {
        outln!("soft range limit  {l} m")?;
    }
    Ok(())
}

/// A query dataset's sweeps, after checking it can be compared with the
/// index.
fn query_sweeps(
    index: &PlaceIndex,
    path: &Path,
    options: &SweepOptions,
) -> Result<(Dataset, Vec<DatasetSweep>)> {
    let ds = super::open_dataset(path)?;
    if let Some(limit) = index.contents().limit_m {
        if (ds.manifest.max_range as f32) != limit {
            bail!(
                "{}: soft range limit {} m, the index's places {limit} m: profiles of other limits cannot be compared",
                ds.manifest_path().display(),
                ds.manifest.max_range
            );
        }
    }
    let swept = sweep_with_bar(&ds, options)?;
    Ok((ds, swept.sweeps))
}

pub(super) fn sweep_with_bar(ds: &Dataset, options: &SweepOptions) -> Result<pipeline::Swept> {
    let config = options.pipeline()?;
    config.check()?;
    let bar = super::progress(ds.manifest.frames.len(), "profile");
    let swept = pipeline::sweep_dataset(ds, &config, &|_| bar.inc(1))?;
    bar.finish_and_clear();
    Ok(swept)
}

/// Every query sweep's answer, in order.
fn answer_all(index: &PlaceIndex, ds: &Dataset, sweeps: &[DatasetSweep]) -> Result<Vec<Answer>> {
    let config = LocaliseConfig::default();
    let bar = super::progress(sweeps.len(), "localise");
    let answers = sweeps
        .iter()
        .map(|s| {
            let a = localise(index, s, &config)
                .with_context(|| format!("{}: sweep {}", ds.manifest_path().display(), s.id));
            bar.inc(1);
            a
        })
        .collect::<Result<Vec<_>>>()?;
    bar.finish_and_clear();
    if answers.iter().all(|a| a.verdict == Verdict::Incomplete) {
        bail!(
            "{}: no sweep saw enough of the circle ({:.0} %) to be looked up",
            ds.manifest_path().display(),
            100.0 * index.contents().config.min_coverage
        );
    }
    Ok(answers)
}

/// Runs `pirouette localise`.
pub fn run_localise(a: LocaliseArgs) -> Result<()> {
    let (index, _) = read_place_index(&a.index)?;
    let (ds, sweeps) = query_sweeps(&index, &a.dataset, &a.sweep)?;
    let answers = answer_all(&index, &ds, &sweeps)?;
    let c = index.contents();
    let mut rows = Vec::new();
    for (s, ans) in sweeps.iter().zip(&answers) {
        let name = |m: &pirouette::localise::PlaceMatch| {
            let meta = &c.meta[m.place];
            (c.datasets[meta.dataset as usize].as_str(), meta.sweep, m.pose)
        };
        let named = ans.trusted().map(name);
        // An ambiguous answer's look-alikes: the best and its rival.
        let alike: Vec<_> = match (ans.verdict, ans.best, ans.rival) {
            (Verdict::Ambiguous, Some(best), Some(rival)) => vec![name(&best), name(&rival)],
            _ => Vec::new(),
        };
        let score = ans.best.map_or(0.0, |m| m.score);
        if a.json {
            let as_json = |(dataset, sweep, p): (&str, u32, Pose2)| {
                json!({
                    "dataset": dataset, "sweep": sweep,
                    "x": round6(p.x), "y": round6(p.y), "theta_deg": round6(p.theta.to_degrees()),
                })
            };
            let mut line = json!({"sweep": s.id, "match": named.map(as_json), "score": round6(score),
                                  "margin": round6(ans.margin), "status": ans.verdict.as_str()});
            if !alike.is_empty() {
                line["ambiguous"] = alike.iter().copied().map(as_json).collect();
            }
            outln!("{line}")?;
        } else {
            let place = match (named, alike.as_slice()) {
                (Some((d, sw, _)), _) => format!("{d} #{sw}"),
                (None, [(d, a, _), (e, b, _)]) if d == e && a == b => format!("{d} #{a} or its look-alike"),
                (None, [(d, a, _), (e, b, _)]) => format!("{d} #{a} or {e} #{b}"),
                _ => "-".to_string(),
            };
            let pose = named.map_or_else(
                || format!("{:>6}  {:>6}  {:>6}", "-", "-", "-"),
                |(_, _, p)| format!("{:>6.3}  {:>6.3}  {:>6.1}", p.x, p.y, p.theta.to_degrees()),
            );
            rows.push((s.id, ans.verdict.as_str(), place, pose, score, ans.margin));
        }
    }
    let width = rows.iter().map(|r| r.2.chars().count()).max().unwrap_or(0).max(5);
    if !a.json {
        outln!(
            "sweep  status      {:<width$} {:>6}  {:>6}  {:>6}  score  margin",
            "place",
            "x (m)",
            "y (m)",
            "θ (°)"
        )?;
    }
    for (id, status, place, pose, score, margin) in rows {
        outln!("{id:>5}  {status:<10}  {place:<width$} {pose}  {score:>5.2}  {margin:>6.2}")?;
    }
    if !a.json {
        outln!(
            "(pose: the query sweep's first frame in the matched sweep's first-frame frame; score: share of both views' obstacle points the other explains)"
        )?;
    }
    Ok(())
}

fn round6(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

/// A query within this distance of a stored place (by truth) should be
/// recognised.
pub const NEAR_M: f64 = 0.15;

/// An answer is correct where its pose is within these of the truth.
const CORRECT_M: f64 = 0.10;
const CORRECT_DEG: f64 = 5.0;

/// One query's outcome against truth.
struct Outcome {
    sweep: u32,
    /// Distance to the nearest stored place, metres.
    nearest_m: f64,
    answer: Answer,
    /// Position and heading errors of the best candidate, where it has one.
    error: Option<(f64, f64)>,
}

impl Outcome {
    fn near(&self) -> bool {
        self.nearest_m <= NEAR_M
    }
    fn best_correct(&self) -> bool {
        self.error
            .is_some_and(|(m, deg)| m <= CORRECT_M && deg <= CORRECT_DEG)
    }
}

/// Runs `pirouette eval places`.
pub fn eval_places(a: EvalPlacesArgs) -> Result<()> {
    if let Some(dir) = &a.out {
        super::check_output_dir(dir)?;
    }
    let (index, _) = read_place_index(&a.index)?;
    let c = index.contents();
    let stored: Vec<[f64; 3]> = c
        .meta
        .iter()
        .map(|m| m.truth)
        .collect::<Option<_>>()
        .with_context(|| {
            format!(
                "{}: a place has no true pose (built from a dataset without truth)",
                a.index.display()
            )
        })?;
    let (ds, sweeps) = query_sweeps(&index, &a.query, &a.sweep)?;
    let answers = answer_all(&index, &ds, &sweeps)?;
    let mut outcomes = Vec::new();
    for (s, answer) in sweeps.iter().zip(answers) {
        let t = ds.manifest.frames[s.frames[0]].truth.with_context(|| {
            format!(
                "{}: sweep {} has no true pose",
                ds.manifest_path().display(),
                s.id
            )
        })?;
        let query = Pose2::new(t.x, t.y, t.theta_deg.to_radians());
        let nearest_m = stored
            .iter()
            .map(|p| (p[0] - query.x).hypot(p[1] - query.y))
            .fold(f64::INFINITY, f64::min);
        let error = answer.best.map(|m| {
            let p = stored[m.place];
            let truth = Pose2::new(p[0], p[1], p[2]).inverse() * query;
            (
                m.pose.translation().distance(truth.translation()),
                wrap_angle(m.pose.theta - truth.theta).to_degrees().abs(),
            )
        });
        outcomes.push(Outcome {
            sweep: s.id,
            nearest_m,
            answer,
            error,
        });
    }
    let report = PlacesReport::of(&outcomes);
    if let Some(dir) = &a.out {
        let curve = pr_curve(&outcomes);
        let img = pirouette::plot::pr_figure(
            &curve,
            &format!("{} against {}", ds.manifest.name, c.datasets.join(", ")),
        );
        let mut bytes = Vec::new();
        image::DynamicImage::ImageRgb8(img)
            .write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png)?;
        pirouette::io::atomic_write(&dir.join("places-pr.png"), &bytes)?;
    }
    if a.json {
        outln!("{}", serde_json::to_string(&report.json(&outcomes))?)?;
        return Ok(());
    }
    outln!("sweep  nearest (m)  status      score  margin  error (m)  error (°)  verdict")?;
    for o in &outcomes {
        let (em, ed) = o.error.unwrap_or((f64::NAN, f64::NAN));
        let verdict = match (o.answer.trusted().is_some(), o.best_correct(), o.near()) {
            (true, true, _) => "right",
            (true, false, _) => "WRONG",
            (false, _, true) => "missed",
            (false, _, false) => "unknown (far)",
        };
        outln!(
            "{:>5}  {:>11.3}  {:<10}  {:>5.2}  {:>6.2}  {:>9.3}  {:>9.2}  {verdict}",
            o.sweep,
            o.nearest_m,
            o.answer.verdict.as_str(),
            o.answer.best.map_or(0.0, |m| m.score),
            o.answer.margin,
            em,
            ed
        )?;
    }
    report.print()?;
    Ok(())
}

/// Scores of a set of queries.
struct PlacesReport {
    near: usize,
    near_right: usize,
    answered: usize,
    answered_right: usize,
    far: usize,
    far_wrong: usize,
    max_error_m: f64,
    max_error_deg: f64,
    mean_error_m: f64,
    mean_error_deg: f64,
}

impl PlacesReport {
    fn of(outcomes: &[Outcome]) -> Self {
        let answered: Vec<&Outcome> = outcomes.iter().filter(|o| o.answer.trusted().is_some()).collect();
        let right: Vec<(f64, f64)> = answered
            .iter()
            .filter(|o| o.best_correct())
            .filter_map(|o| o.error)
            .collect();
        let n = right.len().max(1) as f64;
        Self {
            near: outcomes.iter().filter(|o| o.near()).count(),
            near_right: answered.iter().filter(|o| o.near() && o.best_correct()).count(),
            answered: answered.len(),
            answered_right: right.len(),
            far: outcomes.iter().filter(|o| !o.near()).count(),
            far_wrong: answered.iter().filter(|o| !o.near() && !o.best_correct()).count(),
            max_error_m: right.iter().map(|e| e.0).fold(0.0, f64::max),
            max_error_deg: right.iter().map(|e| e.1).fold(0.0, f64::max),
            mean_error_m: right.iter().map(|e| e.0).sum::<f64>() / n,
            mean_error_deg: right.iter().map(|e| e.1).sum::<f64>() / n,
        }
    }

    fn recall(&self) -> f64 {
        ratio(self.near_right, self.near)
    }

    fn precision(&self) -> f64 {
        ratio(self.answered_right, self.answered)
    }

    fn json(&self, outcomes: &[Outcome]) -> serde_json::Value {
        json!({
            "queries": outcomes.len(),
            "near_queries": self.near,
            "recall_at_1": self.recall(),
            "answers": self.answered,
            "precision": self.precision(),
            "far_queries": self.far,
            "far_wrong": self.far_wrong,
            "pose_error_mean_m": self.mean_error_m,
            "pose_error_max_m": self.max_error_m,
            "pose_error_mean_deg": self.mean_error_deg,
            "pose_error_max_deg": self.max_error_deg,
        })
    }

    fn print(&self) -> std::io::Result<()> {
        outln!(
            "recall@1 {:.3} ({} of {} queries within {NEAR_M} m of a stored place)",
            self.recall(),
            self.near_right,
            self.near
        )?;
        outln!(
            "precision {:.3} ({} of {} answers right)",
            self.precision(),
            self.answered_right,
            self.answered
        )?;
        outln!("far queries {}: {} answered wrong", self.far, self.far_wrong)?;
        outln!(
            "pose error of right answers: mean {:.3} m {:.2}°, max {:.3} m {:.2}°",
            self.mean_error_m,
            self.mean_error_deg,
            self.max_error_m,
            self.max_error_deg
        )?;
        outln!(
            "(right: the answer's pose within {CORRECT_M} m and {CORRECT_DEG}° of the truth; recall over queries within {NEAR_M} m of a stored place; precision over all answers)"
        )
    }
}

fn ratio(a: usize, b: usize) -> f64 {
    if b == 0 {
        1.0
    } else {
        a as f64 / b as f64
    }
}

/// Precision and recall as the score threshold sweeps over the scores
/// seen (each query answered by its best candidate where the score clears
/// the threshold and the margin the default): `(threshold, precision,
/// recall)`.
fn pr_curve(outcomes: &[Outcome]) -> Vec<(f64, f64, f64)> {
    let margin = LocaliseConfig::default().min_margin;
    let mut thresholds: Vec<f64> = outcomes
        .iter()
        .filter_map(|o| o.answer.best.map(|m| m.score))
        .collect();
    thresholds.push(0.0);
    thresholds.sort_by(f64::total_cmp);
    thresholds.dedup();
    let near = outcomes.iter().filter(|o| o.near()).count();
    thresholds
        .into_iter()
        .map(|t| {
            let answered: Vec<&Outcome> = outcomes
                .iter()
                .filter(|o| o.answer.best.is_some_and(|m| m.score >= t) && o.answer.margin >= margin)
                .collect();
            let right = answered.iter().filter(|o| o.best_correct()).count();
            let near_right = answered.iter().filter(|o| o.near() && o.best_correct()).count();
            (t, ratio(right, answered.len()), ratio(near_right, near))
        })
        .collect()
}
