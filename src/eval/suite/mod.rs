//! The scoreboard: every case of the corpus run, scored against its
//! targets, worst first, beside a base build.
//!
//! - [`corpus`]: the corpus file and its cases.
//! - [`prepare`]: inputs made once (renders, log and graph variants).
//! - [`run`]: one case with one binary, timed and measured.
//! - [`report`]: targets, base comparison, summaries, the files written.

pub mod corpus;
pub mod prepare;
pub mod report;
pub mod run;

pub use corpus::{Bound, Case, Corpus, Kind};
pub use report::{Provenance, Scoreboard, Summary};
pub use run::{Outcome, Runner, Usage};

use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// How the suite runs.
#[derive(Debug, Clone)]
pub struct SuiteConfig {
    /// Only the cases marked quick.
    pub quick: bool,
    /// Only these kinds (all when empty).
    pub only: Vec<Kind>,
    /// Another build to run side by side.
    pub base: Option<PathBuf>,
    /// Timed runs of each build per case, interleaved; the minimum counts.
    pub repeats: usize,
    /// Cases run at once.
    pub jobs: usize,
}

/// One case's runs with each build.
#[derive(Debug, Clone, Serialize)]
pub struct CaseResult {
    /// The case.
    pub case: Case,
    /// This build's outcome (time and memory: the minimum over repeats),
    /// or why it failed.
    pub this: Result<Outcome, String>,
    /// Every timed run of this build, seconds.
    pub times_s: Vec<f64>,
    /// The base build's, where one is given.
    pub base: Option<Result<Outcome, String>>,
    /// Every timed run of the base build, seconds.
    pub base_times_s: Vec<f64>,
}

/// Runs `cases` (already filtered) with this build and the base, calling
/// `tick` after each case.
pub fn run_cases(
    runner: &Runner,
    cases: &[Case],
    config: &SuiteConfig,
    work: &Path,
    tick: &(dyn Fn(&str) + Sync),
) -> Vec<CaseResult> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(config.jobs.max(1))
        .build();
    let one = |(i, case): (usize, &Case)| {
        let r = run_case(runner, case, config, &work.join(format!("{i:04}")));
        tick(&case.id);
        r
    };
    match pool {
        Ok(pool) => pool.install(|| cases.par_iter().enumerate().map(one).collect()),
        Err(_) => cases.iter().enumerate().map(one).collect(),
    }
}

/// One case: this build and the base in turn, `repeats` times; figures
/// from each build's first run, time and memory the minimum over runs.
fn run_case(runner: &Runner, case: &Case, config: &SuiteConfig, work: &Path) -> CaseResult {
    let this_bin = runner.this.clone();
    let mut this: Option<Result<Outcome, String>> = None;
    let mut base: Option<Result<Outcome, String>> = None;
    let (mut times, mut base_times) = (Vec::new(), Vec::new());
    for r in 0..config.repeats.max(1) {
        let mut bins = vec![(&this_bin, "this", &mut this, &mut times)];
        if let Some(b) = &config.base {
            bins.push((b, "base", &mut base, &mut base_times));
        }
        for (bin, tag, slot, times) in bins {
            if matches!(slot, Some(Err(_))) {
                continue;
            }
            let got = runner
                .run(case, bin, &work.join(tag), r == 0)
                .map_err(|e| format!("{e:#}"));
            match (slot.as_mut(), got) {
                (None, got) => {
                    if let Ok(o) = &got {
                        times.push(o.time_s);
                    }
                    *slot = Some(got);
                }
                (Some(Ok(first)), Ok(o)) => {
                    times.push(o.time_s);
                    first.time_s = first.time_s.min(o.time_s);
                    first.peak_mb = first.peak_mb.min(o.peak_mb);
                }
                (Some(_), Err(e)) => *slot = Some(Err(e)),
                (Some(Err(_)), Ok(_)) => {}
            }
        }
    }
    let _ = std::fs::remove_dir_all(work);
    CaseResult {
        case: case.clone(),
        this: this.unwrap_or_else(|| Err("not run".into())),
        times_s: times,
        base: config
            .base
            .as_ref()
            .map(|_| base.unwrap_or_else(|| Err("not run".into()))),
        base_times_s: base_times,
    }
}
