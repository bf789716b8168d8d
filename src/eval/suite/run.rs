//! Running one case with one binary: its timed commands under `pirouette
//! measure`, then the figures read from the evaluation's JSON.

use super::corpus::{Case, GraphVariant, Input};
use super::prepare::Places;
use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

/// What `pirouette measure` records of one finished command.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct Usage {
    /// Wall-clock seconds.
    pub wall_s: f64,
    /// User CPU seconds.
    pub user_s: f64,
    /// System CPU seconds.
    pub sys_s: f64,
    /// Peak resident memory, kilobytes.
    pub max_rss_kb: u64,
}

/// One run of a case.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Outcome {
    /// Named figures (see docs/scoreboard.md).
    pub figures: BTreeMap<String, f64>,
    /// Wall-clock seconds of the timed commands.
    pub time_s: f64,
    /// The largest peak memory of a timed command, megabytes.
    pub peak_mb: f64,
}

/// The binaries and folders a run uses.
#[derive(Debug, Clone)]
pub struct Runner {
    /// This build (`pirouette measure`, and the evaluation of outputs).
    pub this: PathBuf,
    /// The inputs.
    pub places: Places,
}

impl Runner {
    /// Runs `bin ARGS` under `pirouette measure`, its stdout returned;
    /// a failure carries the command's last line on stderr.
    fn timed(&self, work: &Path, bin: &Path, args: &[OsString]) -> Result<(Usage, String)> {
        let record = work.join(format!("usage-{}.json", std::process::id()));
        let out = Command::new(&self.this)
            .arg("measure")
            .arg("--record")
            .arg(&record)
            .arg("--")
            .arg(bin)
            .args(args)
            .output()
            .with_context(|| format!("cannot run {}", self.this.display()))?;
        check(&out, bin, args)?;
        let usage: Usage = serde_json::from_slice(&std::fs::read(&record)?).context("measure record")?;
        let _ = std::fs::remove_file(&record);
        Ok((usage, String::from_utf8_lossy(&out.stdout).into_owned()))
    }

    /// Runs `bin ARGS` untimed, its stdout returned.
    fn plain(&self, bin: &Path, args: &[OsString]) -> Result<String> {
        let out = Command::new(bin)
            .args(args)
            .output()
            .with_context(|| format!("cannot run {}", bin.display()))?;
        check(&out, bin, args)?;
        Ok(String::from_utf8_lossy(&out.stdout).into_owned())
    }

    /// Times `bin map INPUT --out WORK/map`: its usage and the map folder.
    fn timed_map(&self, work: &Path, bin: &Path, input: &Path) -> Result<(Usage, PathBuf)> {
        let map = work.join("map");
        let (u, _) = self.timed(
            work,
            bin,
            &args([
                "map".as_ref(),
                input.as_os_str(),
                "--out".as_ref(),
                map.as_os_str(),
            ]),
        )?;
        Ok((u, map))
    }

    /// This build's `eval WHAT A B --json`, read.
    fn evaluated(&self, what: &str, a: &Path, b: &Path) -> Result<serde_json::Value> {
        json(&self.plain(
            &self.this,
            &args([
                "eval".as_ref(),
                what.as_ref(),
                a.as_os_str(),
                b.as_os_str(),
                "--json".as_ref(),
            ]),
        )?)
    }

    /// Runs `case` with `bin` in `work`; `figures` false for timing
    /// repeats, which run only the timed commands.
    pub fn run(&self, case: &Case, bin: &Path, work: &Path, figures: bool) -> Result<Outcome> {
        std::fs::create_dir_all(work).with_context(|| format!("cannot create {}", work.display()))?;
        let mut o = Outcome::default();
        let mut add = |u: Usage| {
            o.time_s += u.wall_s;
            o.peak_mb = o.peak_mb.max(u.max_rss_kb as f64 / 1024.0);
        };
        let mut f = BTreeMap::new();
        match &case.input {
            Input::Camera(source) => {
                let ds = self.places.dataset(source)?;
                let (u, map) = self.timed_map(work, bin, &ds)?;
                add(u);
                if figures {
                    let prof = self.plain(
                        bin,
                        &args([
                            "eval".as_ref(),
                            "profile".as_ref(),
                            ds.as_os_str(),
                            "--json".as_ref(),
                        ]),
                    )?;
                    let pinhole = (prof
                        .lines()
                        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok()))
                    .max_by_key(|v| v["model"] == "pinhole")
                    .context("eval profile printed no JSON")?;
                    take(
                        &mut f,
                        &pinhole,
                        &[("missed", "/missed"), ("false_range", "/false_range")],
                    );
                    let sweep = json(&self.plain(
                        bin,
                        &args([
                            "eval".as_ref(),
                            "sweep".as_ref(),
                            ds.as_os_str(),
                            "--json".as_ref(),
                        ]),
                    )?)?;
                    take(
                        &mut f,
                        &sweep,
                        &[
                            ("wrong_verified", "/wrong_verified"),
                            ("max_verified_error_deg", "/max_verified_error_deg"),
                        ],
                    );
                    let eval = self.evaluated("map", &ds, &map)?;
                    take(
                        &mut f,
                        &eval,
                        &[("ate_aligned_m", "/trajectory/ate_aligned_m"), ("f1", "/map/f1")],
                    );
                }
            }
            Input::Real {
                rig,
                frame_times,
                every,
            } => {
                let rig = self.places.real_rig(rig, frame_times, *every)?;
                let (u, map) = self.timed_map(work, bin, &rig)?;
                add(u);
                if figures {
                    let eval = self.evaluated("map", &rig, &map)?;
                    take(
                        &mut f,
                        &eval,
                        &[
                            ("ate_aligned_m", "/trajectory/ate_aligned_m"),
                            ("heading_rmse_deg", "/trajectory/heading_rmse_deg"),
                            ("turn_error_median_deg", "/trajectory/turn_error_median_deg"),
                            ("turn_error_p95_deg", "/trajectory/turn_error_p95_deg"),
                            (
                                "heading_after_full_turn_deg",
                                "/trajectory/heading_after_full_turn_deg",
                            ),
                            ("profile_agreement", "/profile_agreement/share"),
                        ],
                    );
                }
            }
            Input::Places { index, query } => {
                let (index, query) = (self.places.dataset(index)?, self.places.dataset(query)?);
                let idx = work.join("index.places");
                add(self
                    .timed(
                        work,
                        bin,
                        &args([
                            "places".as_ref(),
                            "build".as_ref(),
                            index.as_os_str(),
                            "--out".as_ref(),
                            idx.as_os_str(),
                        ]),
                    )?
                    .0);
                let (u, out) = self.timed(
                    work,
                    bin,
                    &args([
                        "eval".as_ref(),
                        "places".as_ref(),
                        query.as_os_str(),
                        idx.as_os_str(),
                        "--json".as_ref(),
                    ]),
                )?;
                add(u);
                if figures {
                    let v = json(&out)?;
                    take(
                        &mut f,
                        &v,
                        &[
                            ("answers", "/answers"),
                            ("precision", "/precision"),
                            ("recall_at_1", "/recall_at_1"),
                            ("far_wrong", "/far_wrong"),
                            ("pose_error_max_deg", "/pose_error_max_deg"),
                            ("pose_error_max_m", "/pose_error_max_m"),
                        ],
                    );
                    // Precision over no answers, and pose errors over no
                    // right answers, are not figures: left out, they are
                    // misses where the case must give them.
                    let answers = f.get("answers").copied().unwrap_or(0.0);
                    let right = answers * f.get("precision").copied().unwrap_or(0.0);
                    if answers == 0.0 {
                        f.remove("precision");
                    }
                    if right < 0.5 {
                        f.remove("pose_error_max_deg");
                        f.remove("pose_error_max_m");
                    }
                }
            }
            Input::Laser { log, variant } => {
                let log = self.places.laser_log(log, *variant)?;
                let (u, map) = self.timed_map(work, bin, &log)?;
                add(u);
                if figures {
                    let v = self.evaluated("laser", &log, &map)?;
                    take(
                        &mut f,
                        &v,
                        &[
                            ("ate_m", "/estimated/ate_m"),
                            ("rpe_1m_m", "/estimated/relative/0/translation_mean_m"),
                            ("rpe_1m_deg", "/estimated/relative/0/rotation_mean_deg"),
                        ],
                    );
                    // Steps wrong without a mark, as a share of the steps.
                    if let (Some(w), Some(n)) = (v["wrong_unmarked"].as_f64(), v["steps"].as_f64()) {
                        f.insert("wrong_unmarked_share".into(), w / n.max(1.0));
                    }
                }
            }
            Input::Bag {
                name,
                cartographer_trans_m,
                cartographer_rot_deg,
                cartographer_time_s,
            } => {
                let bag = self.places.shared_file(&format!("laser/benchmark/{name}.bag"))?;
                let relations = self
                    .places
                    .shared_file(&format!("laser/benchmark/{name}.relations"))?;
                let (u, map) = self.timed_map(work, bin, &bag)?;
                add(u);
                if figures {
                    let v = self.evaluated("relations", &map, &relations)?;
                    take(
                        &mut f,
                        &v,
                        &[
                            ("relations_trans_m", "/trans_abs_m"),
                            ("relations_rot_deg", "/rot_abs_deg"),
                            ("relations_unmatched", "/unmatched"),
                        ],
                    );
                    for (k, to, by) in [
                        (
                            "relations_trans_m",
                            "relations_trans_vs_cartographer",
                            *cartographer_trans_m,
                        ),
                        (
                            "relations_rot_deg",
                            "relations_rot_vs_cartographer",
                            *cartographer_rot_deg,
                        ),
                    ] {
                        if let Some(v) = f.get(k).copied() {
                            f.insert(to.into(), v / by);
                        }
                    }
                    f.insert("time_vs_cartographer".into(), u.wall_s / cartographer_time_s);
                }
            }
            Input::Graph {
                file,
                variant,
                reference_chi2,
            } => {
                let g = self.places.graph(file, *variant)?;
                let out_g = work.join("optimised.g2o");
                let (u, out) = self.timed(
                    work,
                    bin,
                    &args([
                        "graph".as_ref(),
                        "optimise".as_ref(),
                        g.as_os_str(),
                        "--out".as_ref(),
                        out_g.as_os_str(),
                        "--json".as_ref(),
                    ]),
                )?;
                add(u);
                if figures {
                    let v = json(&out)?;
                    take(
                        &mut f,
                        &v,
                        &[("chi2_final", "/chi2_final"), ("iterations", "/iterations")],
                    );
                    if *variant == GraphVariant::Outliers10 {
                        let truth = self.places.graph(file, GraphVariant::AsPublished)?;
                        f.insert(
                            "inlier_chi2_vs_reference".into(),
                            inlier_chi2(&truth, &out_g)? / reference_chi2,
                        );
                    } else if let Some(c) = f.get("chi2_final") {
                        f.insert("chi2_vs_reference".into(), c / reference_chi2);
                    }
                }
            }
        }
        o.figures = f;
        Ok(o)
    }
}

/// χ² of the published graph's edges at the poses of `optimised` (which
/// holds them first, in order, with outliers after).
fn inlier_chi2(published: &Path, optimised: &Path) -> Result<f64> {
    let truth = pirouette_io::read_g2o(published)?;
    let got = pirouette_io::read_g2o(optimised)?;
    if got.graph.poses.len() != truth.graph.poses.len() || got.graph.edges.len() < truth.graph.edges.len() {
        bail!(
            "{}: not an optimised copy of {}",
            optimised.display(),
            published.display()
        );
    }
    let p = &got.graph.poses;
    Ok((truth.graph.edges.iter())
        .map(|e| e.chi2(&p[e.from], &p[e.to]))
        .sum())
}

fn args<const N: usize>(a: [&std::ffi::OsStr; N]) -> Vec<OsString> {
    a.iter().map(|s| s.to_os_string()).collect()
}

fn check(out: &std::process::Output, bin: &Path, args: &[OsString]) -> Result<()> {
    if out.status.success() {
        return Ok(());
    }
    let err = String::from_utf8_lossy(&out.stderr);
    let last = err
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("no message");
    let cmd: Vec<String> = args
        .iter()
        .take(2)
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    bail!("{} {} failed: {last}", bin.display(), cmd.join(" "))
}

fn json(text: &str) -> Result<serde_json::Value> {
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with('{'))
        .context("no JSON on stdout")?;
    serde_json::from_str(line).context("JSON on stdout")
}

/// Copies numbers at JSON pointers into `f`; a figure the output lacks
/// (an older build's format) is left out.
fn take(f: &mut BTreeMap<String, f64>, v: &serde_json::Value, what: &[(&str, &str)]) {
    for (name, ptr) in what {
        if let Some(x) = v.pointer(ptr).and_then(serde_json::Value::as_f64) {
            f.insert((*name).to_string(), x);
        }
    }
}
