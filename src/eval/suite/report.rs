//! Scores against targets, the base comparison, per-kind summaries, and
//! the scoreboard's two files.

use super::corpus::{Bound, Corpus, Input, Kind, LaserVariant};
use super::CaseResult;
use anyhow::Result;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// Which way a figure is better, and how far it may move between builds
/// before it counts as worse (the figures are deterministic; these are
/// the changes too small to matter).
struct FigureInfo {
    name: &'static str,
    lower_is_better: bool,
    noise: f64,
}

const FIGURES: &[FigureInfo] = &[
    fig("missed", true, 0.002),
    fig("false_range", true, 0.002),
    fig("wrong_verified", true, 0.0),
    fig("max_verified_error_deg", true, 0.05),
    fig("ate_aligned_m", true, 0.001),
    fig("f1", false, 0.005),
    fig("precision", false, 0.0),
    fig("recall_at_1", false, 0.0),
    fig("far_wrong", true, 0.0),
    fig("pose_error_max_deg", true, 0.05),
    fig("pose_error_max_m", true, 0.002),
    fig("ate_m", true, 0.005),
    fig("rpe_1m_m", true, 0.001),
    fig("rpe_1m_deg", true, 0.02),
    fig("rpe_1m_vs_odometry", true, 0.05),
    fig("wrong_unmarked_share", true, 0.005),
    fig("relations_trans_m", true, 0.0005),
    fig("relations_rot_deg", true, 0.01),
    fig("relations_unmatched", true, 0.0),
    fig("relations_trans_vs_cartographer", true, 0.02),
    fig("relations_rot_vs_cartographer", true, 0.02),
    fig("time_vs_cartographer", true, 0.005),
    fig("chi2_vs_reference", true, 0.001),
    fig("inlier_chi2_vs_reference", true, 0.001),
];

const fn fig(name: &'static str, lower_is_better: bool, noise: f64) -> FigureInfo {
    FigureInfo {
        name,
        lower_is_better,
        noise,
    }
}

fn info(name: &str) -> Option<&'static FigureInfo> {
    FIGURES.iter().find(|f| f.name == name)
}

/// The figure a kind's cases are ordered by, worst first, after misses.
fn headline(kind: Kind) -> &'static str {
    match kind {
        Kind::Camera => "ate_aligned_m",
        Kind::Places => "pose_error_max_deg",
        Kind::Laser => "rpe_1m_m",
        Kind::Graph => "chi2_vs_reference",
    }
}

/// A figure short of its target.
#[derive(Debug, Clone, Serialize)]
pub struct Miss {
    /// The figure.
    pub figure: String,
    /// Its value.
    pub value: f64,
    /// The target, as text.
    pub target: String,
}

/// A figure worse than the base's by more than its noise.
#[derive(Debug, Clone, Serialize)]
pub struct Regression {
    /// The figure (`time_s` for time).
    pub figure: String,
    /// This build's value.
    pub value: f64,
    /// The base's.
    pub base: f64,
    /// The change allowed as noise.
    pub noise: f64,
}

/// One row of the scoreboard.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// The case's id.
    pub case: String,
    /// Its kind.
    pub kind: Kind,
    /// Figures, time (`time_s`, the least of the runs) and memory
    /// (`peak_mb`).
    pub figures: BTreeMap<String, f64>,
    /// Why the case failed, if it did.
    pub error: Option<String>,
    /// Figures short of their targets.
    pub misses: Vec<Miss>,
    /// The base's figures, time and memory.
    pub base: Option<BTreeMap<String, f64>>,
    /// Why the base failed, if it did.
    pub base_error: Option<String>,
    /// Base time over this build's time: above 1, this build is faster.
    pub speed_ratio: Option<f64>,
    /// Figures worse than the base's by more than their noise.
    pub regressions: Vec<Regression>,
}

/// One figure over a kind's cases.
#[derive(Debug, Clone, Serialize)]
pub struct FigureSummary {
    /// The target, as text.
    pub target: String,
    /// The worst case and its value.
    pub worst_case: String,
    /// The worst value.
    pub worst: f64,
    /// The median over the cases.
    pub median: f64,
    /// Cases short of the target.
    pub misses: Vec<String>,
}

/// A kind's summary.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// Cases run.
    pub cases: usize,
    /// Cases that failed to run, with why.
    pub failed: Vec<String>,
    /// Per targeted figure, plus `time_s` and `peak_mb`.
    pub figures: BTreeMap<String, FigureSummary>,
    /// With a base: cases slower than the base by more than their timing
    /// noise, and the cases with a worse figure.
    pub slower_than_base: Vec<String>,
    /// With a base: the least and median speed ratio.
    pub speed_ratio_min: Option<f64>,
    /// With a base: the median speed ratio.
    pub speed_ratio_median: Option<f64>,
    /// With a base: cases with a figure worse than the base's.
    pub regressed: Vec<String>,
}

/// The whole scoreboard.
#[derive(Debug, Clone, Serialize)]
pub struct Scoreboard {
    /// The corpus file.
    pub corpus: String,
    /// Whether only the quick cases ran.
    pub quick: bool,
    /// This build.
    pub binary: String,
    /// The base build, if any.
    pub base: Option<String>,
    /// Timed runs per build and case.
    pub repeats: usize,
    /// Cases run at once.
    pub jobs: usize,
    /// Per kind.
    pub summary: BTreeMap<Kind, Summary>,
    /// Per case, worst first within each kind.
    pub rows: Vec<Row>,
}

/// Figures computed across cases: a laser variant's RPE over its log's
/// as recorded (same build).
fn add_relative(results: &mut [CaseResult]) {
    let reference = |results: &[CaseResult], log: &str, base: bool| -> Option<f64> {
        results.iter().find_map(|r| match &r.case.input {
            Input::Laser {
                log: l,
                variant: LaserVariant::AsRecorded,
            } if l == log => {
                let o = if base {
                    r.base.as_ref()?.as_ref().ok()?
                } else {
                    r.this.as_ref().ok()?
                };
                o.figures.get("rpe_1m_m").copied()
            }
            _ => None,
        })
    };
    for i in 0..results.len() {
        let Input::Laser { log, variant } = &results[i].case.input else {
            continue;
        };
        if *variant == LaserVariant::AsRecorded {
            continue;
        }
        let log = log.clone();
        for base in [false, true] {
            let Some(r0) = reference(results, &log, base) else {
                continue;
            };
            let slot = if base {
                results[i].base.as_mut().and_then(|b| b.as_mut().ok())
            } else {
                results[i].this.as_mut().ok()
            };
            if let Some(o) = slot {
                if let Some(v) = o.figures.get("rpe_1m_m").copied() {
                    o.figures.insert("rpe_1m_vs_odometry".into(), v / r0);
                }
            }
        }
    }
}

fn with_time(o: &super::Outcome) -> BTreeMap<String, f64> {
    let mut f = o.figures.clone();
    f.insert("time_s".into(), o.time_s);
    f.insert("peak_mb".into(), o.peak_mb);
    f
}

/// Relative spread of timed runs, `(max − min) / min`.
fn spread(times: &[f64]) -> f64 {
    let lo = times.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = times.iter().copied().fold(0.0, f64::max);
    if lo > 0.0 && lo.is_finite() {
        (hi - lo) / lo
    } else {
        0.0
    }
}

fn row(r: &CaseResult, targets: &BTreeMap<String, Bound>) -> Row {
    let (figures, error) = match &r.this {
        Ok(o) => (with_time(o), None),
        Err(e) => (BTreeMap::new(), Some(e.clone())),
    };
    let misses = (targets.iter())
        .filter_map(|(name, b)| {
            let v = *figures.get(name)?;
            (!b.holds(v)).then(|| Miss {
                figure: name.clone(),
                value: v,
                target: b.text(),
            })
        })
        .collect();
    let (base, base_error) = match &r.base {
        Some(Ok(o)) => (Some(with_time(o)), None),
        Some(Err(e)) => (None, Some(e.clone())),
        None => (None, None),
    };
    let mut regressions = Vec::new();
    let mut speed_ratio = None;
    if let (Some(b), false) = (&base, figures.is_empty()) {
        for (name, &v) in &figures {
            let (Some(fi), Some(&bv)) = (info(name), b.get(name)) else {
                continue;
            };
            let worse = if fi.lower_is_better { v - bv } else { bv - v };
            if worse > fi.noise + 1e-12 {
                regressions.push(Regression {
                    figure: name.clone(),
                    value: v,
                    base: bv,
                    noise: fi.noise,
                });
            }
        }
        if let (Some(&t), Some(&bt)) = (figures.get("time_s"), b.get("time_s")) {
            if t > 0.0 {
                speed_ratio = Some(bt / t);
            }
            let noise = spread(&r.times_s).max(spread(&r.base_times_s)).max(0.05);
            if t > bt * (1.0 + noise) {
                regressions.push(Regression {
                    figure: "time_s".into(),
                    value: t,
                    base: bt,
                    noise,
                });
            }
        }
    }
    Row {
        case: r.case.id.clone(),
        kind: r.case.kind,
        figures,
        error,
        misses,
        base,
        base_error,
        speed_ratio,
        regressions,
    }
}

/// The worse of two values of `name` (NaN-free), as an ordering key where
/// larger is worse.
fn badness(name: &str, v: f64) -> f64 {
    match info(name) {
        Some(fi) if !fi.lower_is_better => -v,
        _ => v,
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => (v[n / 2 - 1] + v[n / 2]) / 2.0,
    }
}

fn summarise(rows: &[&Row], targets: &BTreeMap<String, Bound>) -> Summary {
    let mut figures = BTreeMap::new();
    let names = targets
        .keys()
        .cloned()
        .chain(["time_s".to_string(), "peak_mb".to_string()]);
    for name in names {
        let vals: Vec<(&str, f64)> = rows
            .iter()
            .filter_map(|r| Some((r.case.as_str(), *r.figures.get(&name)?)))
            .collect();
        let Some(&(wc, w)) = vals
            .iter()
            .max_by(|a, b| badness(&name, a.1).total_cmp(&badness(&name, b.1)))
        else {
            continue;
        };
        let bound = targets.get(&name);
        figures.insert(
            name.clone(),
            FigureSummary {
                target: bound.map_or("-".into(), Bound::text),
                worst_case: wc.to_string(),
                worst: w,
                median: median(&mut vals.iter().map(|v| v.1).collect::<Vec<_>>()),
                misses: (vals.iter())
                    .filter(|(_, v)| bound.is_some_and(|b| !b.holds(*v)))
                    .map(|(c, _)| c.to_string())
                    .collect(),
            },
        );
    }
    let mut ratios: Vec<f64> = rows.iter().filter_map(|r| r.speed_ratio).collect();
    Summary {
        cases: rows.len(),
        failed: (rows.iter())
            .filter_map(|r| r.error.as_ref().map(|e| format!("{}: {e}", r.case)))
            .collect(),
        figures,
        slower_than_base: (rows.iter())
            .filter(|r| r.regressions.iter().any(|g| g.figure == "time_s"))
            .map(|r| r.case.clone())
            .collect(),
        speed_ratio_min: ratios.iter().copied().reduce(f64::min),
        speed_ratio_median: (!ratios.is_empty()).then(|| median(&mut ratios)),
        regressed: (rows.iter())
            .filter(|r| r.regressions.iter().any(|g| g.figure != "time_s"))
            .map(|r| r.case.clone())
            .collect(),
    }
}

impl Scoreboard {
    /// Scores `results` against the corpus's targets and the base.
    pub fn new(
        corpus: &Corpus,
        mut results: Vec<CaseResult>,
        config: &super::SuiteConfig,
        binary: &Path,
    ) -> Scoreboard {
        add_relative(&mut results);
        let none = BTreeMap::new();
        let targets = |k: Kind| corpus.targets.get(&k).unwrap_or(&none);
        let mut rows: Vec<Row> = results.iter().map(|r| row(r, targets(r.case.kind))).collect();
        rows.sort_by(|a, b| {
            let key = |r: &Row| {
                let h = headline(r.kind);
                (
                    r.error.is_none(),
                    std::cmp::Reverse(r.misses.len()),
                    -r.figures.get(h).map_or(f64::NEG_INFINITY, |v| badness(h, *v)),
                )
            };
            (a.kind.cmp(&b.kind)).then_with(|| {
                let (ka, kb) = (key(a), key(b));
                (ka.0, ka.1).cmp(&(kb.0, kb.1)).then(ka.2.total_cmp(&kb.2))
            })
        });
        let summary = (Kind::ALL.iter())
            .filter_map(|&k| {
                let of_kind: Vec<&Row> = rows.iter().filter(|r| r.kind == k).collect();
                (!of_kind.is_empty()).then(|| (k, summarise(&of_kind, targets(k))))
            })
            .collect();
        Scoreboard {
            corpus: corpus.path.display().to_string(),
            quick: config.quick,
            binary: binary.display().to_string(),
            base: config.base.as_ref().map(|b| b.display().to_string()),
            repeats: config.repeats,
            jobs: config.jobs,
            summary,
            rows,
        }
    }

    /// Cases short of a target or failed, over every kind.
    pub fn short(&self) -> usize {
        self.rows
            .iter()
            .filter(|r| r.error.is_some() || !r.misses.is_empty())
            .count()
    }

    /// Writes `scoreboard.json` and `scoreboard.md` into `dir`, atomically.
    pub fn write(&self, dir: &Path) -> Result<()> {
        let json = serde_json::to_vec_pretty(self)?;
        pirouette_io::atomic_write(&dir.join("scoreboard.json"), &json)?;
        pirouette_io::atomic_write(&dir.join("scoreboard.md"), self.markdown().as_bytes())?;
        Ok(())
    }

    /// The scoreboard as Markdown: per kind its summary, then its cases
    /// worst first.
    pub fn markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "# Scoreboard\n");
        let _ = writeln!(
            s,
            "Corpus `{}`{}; build `{}`{}; time is the least of {} run(s), {} case(s) at once.\n",
            self.corpus,
            if self.quick { " (quick)" } else { "" },
            self.binary,
            self.base
                .as_ref()
                .map_or(String::new(), |b| format!(" beside base `{b}`")),
            self.repeats,
            self.jobs
        );
        for (kind, sum) in &self.summary {
            let _ = writeln!(s, "## {} ({} cases)\n", kind.name(), sum.cases);
            let _ = writeln!(
                s,
                "| figure | target | worst | worst case | median | short of target |"
            );
            let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- |");
            for (name, f) in &sum.figures {
                let short = if f.misses.is_empty() {
                    "none".to_string()
                } else {
                    format!("{}: {}", f.misses.len(), f.misses.join(", "))
                };
                let _ = writeln!(
                    s,
                    "| {name} | {} | {} | {} | {} | {short} |",
                    f.target,
                    num(f.worst),
                    f.worst_case,
                    num(f.median)
                );
            }
            if !sum.failed.is_empty() {
                let _ = writeln!(s, "\nFailed: {}", sum.failed.join("; "));
            }
            if let (Some(lo), Some(med)) = (sum.speed_ratio_min, sum.speed_ratio_median) {
                let _ = writeln!(
                    s,
                    "\nSpeed against the base (base time / this time): least {lo:.2}×, median {med:.2}×. Slower than the base: {}. Worse figures: {}.",
                    list_or_none(&sum.slower_than_base),
                    list_or_none(&sum.regressed)
                );
            }
            let rows: Vec<&Row> = self.rows.iter().filter(|r| r.kind == *kind).collect();
            let mut names: Vec<String> = Vec::new();
            for r in &rows {
                for k in r.figures.keys() {
                    if !names.contains(k) {
                        names.push(k.clone());
                    }
                }
            }
            names.sort_by_key(|n| (n == "time_s" || n == "peak_mb", n == "peak_mb", n.clone()));
            let base = self.base.is_some();
            let _ = write!(s, "\n| case | {} |", names.join(" | "));
            if base {
                let _ = write!(s, " base time_s | speed × | worse than base |");
            }
            let _ = writeln!(s, " short of target |");
            let _ = writeln!(
                s,
                "|{}",
                " --- |".repeat(names.len() + 2 + if base { 3 } else { 0 })
            );
            for r in rows {
                let _ = write!(s, "| {} |", r.case);
                for n in &names {
                    let _ = write!(s, " {} |", r.figures.get(n).map_or("-".into(), |v| num(*v)));
                }
                if base {
                    let bt = r
                        .base
                        .as_ref()
                        .and_then(|b| b.get("time_s"))
                        .map_or("-".into(), |v| num(*v));
                    let bt = r.base_error.as_ref().map_or(bt, |e| format!("failed: {e}"));
                    let worse: Vec<String> = r.regressions.iter().map(|g| g.figure.clone()).collect();
                    let _ = write!(
                        s,
                        " {bt} | {} | {} |",
                        r.speed_ratio.map_or("-".into(), |v| format!("{v:.2}")),
                        list_or_none(&worse)
                    );
                }
                let short = match &r.error {
                    Some(e) => format!("**failed**: {e}"),
                    None if r.misses.is_empty() => "-".into(),
                    None => (r.misses.iter())
                        .map(|m| format!("**{}** {} (target {})", m.figure, num(m.value), m.target))
                        .collect::<Vec<_>>()
                        .join(", "),
                };
                let _ = writeln!(s, " {short} |");
            }
            s.push('\n');
        }
        s
    }
}

fn list_or_none(v: &[String]) -> String {
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}

/// A figure with about four significant digits.
fn num(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let digits = (3 - v.abs().log10().floor() as i32).clamp(0, 6) as usize;
    format!("{v:.digits$}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::suite::corpus::{Case, Source};
    use crate::eval::suite::{Outcome, SuiteConfig};

    fn result(id: &str, ate: f64, time: f64, base: Option<(f64, f64)>) -> CaseResult {
        let outcome = |ate: f64, time: f64| Outcome {
            figures: [("ate_aligned_m".to_string(), ate)].into(),
            time_s: time,
            peak_mb: 10.0,
        };
        CaseResult {
            case: Case {
                id: id.into(),
                kind: Kind::Camera,
                quick: false,
                input: Input::Camera(Source::Shared(id.into())),
            },
            this: Ok(outcome(ate, time)),
            times_s: vec![time, time * 1.01],
            base: base.map(|(a, t)| Ok(outcome(a, t))),
            base_times_s: base.map_or(vec![], |(_, t)| vec![t, t * 1.01]),
        }
    }

    fn corpus() -> Corpus {
        Corpus {
            path: "c.toml".into(),
            targets: [(
                Kind::Camera,
                [(
                    "ate_aligned_m".to_string(),
                    Bound {
                        min: None,
                        max: Some(0.02),
                    },
                )]
                .into(),
            )]
            .into(),
            cases: vec![],
        }
    }

    #[test]
    fn misses_come_first_and_the_summary_names_the_worst() {
        let config = SuiteConfig {
            quick: false,
            only: vec![],
            base: Some("base".into()),
            repeats: 2,
            jobs: 1,
        };
        let results = vec![
            result("a", 0.010, 1.0, Some((0.010, 2.0))),
            result("b", 0.030, 1.0, Some((0.020, 1.0))),
            result("c", 0.015, 2.0, Some((0.015, 1.0))),
        ];
        let board = Scoreboard::new(&corpus(), results, &config, Path::new("this"));
        let order: Vec<&str> = board.rows.iter().map(|r| r.case.as_str()).collect();
        assert_eq!(order, ["b", "c", "a"]);
        let sum = &board.summary[&Kind::Camera];
        let ate = &sum.figures["ate_aligned_m"];
        assert_eq!(
            (ate.worst_case.as_str(), ate.worst, ate.median),
            ("b", 0.030, 0.015)
        );
        assert_eq!(ate.misses, ["b"]);
        // b's ATE is 1 cm worse than the base's; c takes twice the base's time.
        assert_eq!(sum.regressed, ["b"]);
        assert_eq!(sum.slower_than_base, ["c"]);
        assert_eq!(sum.speed_ratio_min, Some(0.5));
        assert_eq!(board.short(), 1);
        let md = board.markdown();
        assert!(md.contains("**ate_aligned_m** 0.03000 (target ≤ 0.02)"), "{md}");
    }
}
