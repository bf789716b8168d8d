//! `pirouette eval suite`: the scoreboard; `pirouette measure`: one
//! command's time and peak memory, for the suite.

use anyhow::{bail, Context, Result};
use pirouette::eval::suite::{prepare, run_cases, Corpus, Kind, Provenance, Runner, Scoreboard, SuiteConfig};
use std::ffi::OsString;
use std::path::PathBuf;

/// Arguments of `pirouette eval suite`.
#[derive(clap::Args, Debug)]
pub struct SuiteArgs {
    /// Only the cases marked quick (CI's subset, a few minutes).
    #[arg(long)]
    quick: bool,
    /// Only the cases of these kinds (repeat or comma-separate).
    #[arg(long, value_enum, value_delimiter = ',')]
    only: Vec<Kind>,
    /// Another `pirouette` build to run side by side (for example one
    /// built from an older commit): speed ratios and figures worse than
    /// its own.
    #[arg(long)]
    base: Option<PathBuf>,
    /// Folder for scoreboard.json, scoreboard.md and the inputs made
    /// (renders, log and graph variants, kept for the next run).
    #[arg(long)]
    out: PathBuf,
    /// The corpus file [default: datasets/corpus.toml of this checkout].
    #[arg(long)]
    corpus: Option<PathBuf>,
    /// Timed runs of each build per case, interleaved; the least counts
    /// [default: 3 with --base, else 1].
    #[arg(long)]
    repeats: Option<usize>,
    /// Cases run at once [default: 1 with --base, so that timings are
    /// not disturbed; else the number of cores].
    #[arg(long)]
    jobs: Option<usize>,
    /// Exit 1 on a loss of quality: with --base, a case missing a target
    /// it met at the base; without, a case failing a gated target
    /// (`gate` in the corpus). The scoreboard is written first.
    #[arg(long)]
    check: bool,
}

/// The most timed runs per case and build.
const MAX_REPEATS: usize = 20;

/// Runs the suite and writes the scoreboard.
pub fn suite(a: SuiteArgs) -> Result<()> {
    let corpus_path = a
        .corpus
        .clone()
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("datasets/corpus.toml"));
    // Absolute: scene files and rigs are named relative to its folder, and
    // inputs made from them are read from elsewhere.
    let corpus_path = std::path::absolute(&corpus_path)
        .with_context(|| format!("{}: no such corpus", corpus_path.display()))?;
    let corpus = Corpus::read(&corpus_path)?;
    if let Some(b) = &a.base {
        if !b.is_file() {
            bail!("{}: no such binary (--base)", b.display());
        }
    }
    let repeats = a.repeats.unwrap_or(if a.base.is_some() { 3 } else { 1 });
    if !(1..=MAX_REPEATS).contains(&repeats) {
        bail!("--repeats must be within 1-{MAX_REPEATS}");
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let jobs = a.jobs.unwrap_or(if a.base.is_some() { 1 } else { cores });
    if !(1..=64).contains(&jobs) {
        bail!("--jobs must be within 1-64");
    }
    super::check_output_dir(&a.out)?;
    let config = SuiteConfig {
        quick: a.quick,
        only: a.only.clone(),
        base: a.base.as_ref().map(std::path::absolute).transpose()?,
        repeats,
        jobs,
    };
    let cases: Vec<_> = (corpus.cases.iter())
        .filter(|c| !config.quick || c.quick)
        .filter(|c| config.only.is_empty() || config.only.contains(&c.kind))
        .cloned()
        .collect();
    if cases.is_empty() {
        bail!("{}: no case matches", corpus_path.display());
    }
    let shared = std::env::var_os("PIROUETTE_SHARED")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from);
    if shared.is_none() && cases.iter().any(|c| c.needs_shared()) {
        bail!(
            "{}: cases read the shared data (camera sets, laser logs, pose graphs): set PIROUETTE_SHARED",
            corpus_path.display()
        );
    }
    let out = std::path::absolute(&a.out)?;
    let runner = Runner {
        this: std::env::current_exe().context("cannot find this binary")?,
        places: prepare::Places {
            shared,
            corpus_dir: corpus_path.parent().map(PathBuf::from).unwrap_or_default(),
            data: out.join("data"),
            making: Default::default(),
        },
    };
    let start = std::time::Instant::now();
    let bar = super::progress(cases.len(), "cases");
    let ticker = |id: &str| {
        bar.set_message(id.chars().take(28).collect::<String>());
        bar.inc(1);
    };
    let results = run_cases(&runner, &cases, &config, &out.join("runs"), &ticker);
    bar.finish_and_clear();
    let mut provenance = Provenance::here(config.base.as_deref());
    provenance.wall_s = start.elapsed().as_secs_f64();
    let board = Scoreboard::new(&corpus, results, &config, &runner.this, provenance);
    board.write(&out)?;
    for (kind, sum) in &board.summary {
        let short: Vec<String> = (sum.figures.iter())
            .filter(|(_, f)| !f.misses.is_empty())
            .map(|(n, f)| format!("{n} {}", f.misses.len()))
            .collect();
        outln!(
            "{:<7} {:>3} cases, {} failed; short of target: {}{}",
            kind.name(),
            sum.cases,
            sum.failed.len(),
            if short.is_empty() {
                "none".into()
            } else {
                short.join(", ")
            },
            sum.speed_ratio_median.map_or(String::new(), |m| format!(
                "; speed vs base median {m:.2}×, least {:.2}×, {} slower",
                sum.speed_ratio_min.unwrap_or(f64::NAN),
                sum.slower_than_base.len()
            ))
        )?;
    }
    outln!(
        "{} of {} cases short of a target or failed; scoreboard.md and scoreboard.json in {}",
        board.short(),
        board.rows.len(),
        out.display()
    )?;
    let failed = board.rows.iter().filter(|r| r.error.is_some()).count();
    if failed > 0 {
        bail!("{failed} case(s) failed to run with this build (see scoreboard.md)");
    }
    if a.check {
        let failures = board.check_failures();
        if !failures.is_empty() {
            for f in &failures {
                eprintln!("check: {f}");
            }
            bail!(
                "--check: {} target(s) {} (see scoreboard.md)",
                failures.len(),
                if config.base.is_some() {
                    "met at the base are missed"
                } else {
                    "gated in the corpus are failed"
                }
            );
        }
        outln!("check: passed")?;
    }
    Ok(())
}

/// Arguments of `pirouette measure`.
#[derive(clap::Args, Debug)]
pub struct MeasureArgs {
    /// Where to write the record (JSON: wall_s, user_s, sys_s, max_rss_kb).
    #[arg(long)]
    record: PathBuf,
    /// The command and its arguments.
    #[arg(last = true, required = true)]
    command: Vec<OsString>,
}

/// Runs a command, then records its wall time, CPU time and peak memory
/// (the operating system's account of this process's children), and exits
/// with its code.
pub fn measure(a: MeasureArgs) -> Result<()> {
    use nix::sys::resource::{getrusage, UsageWho};
    let start = std::time::Instant::now();
    let status = std::process::Command::new(&a.command[0])
        .args(&a.command[1..])
        .status()
        .with_context(|| format!("cannot run {}", a.command[0].to_string_lossy()))?;
    let wall_s = start.elapsed().as_secs_f64();
    let u = getrusage(UsageWho::RUSAGE_CHILDREN).context("getrusage")?;
    let secs = |t: nix::sys::time::TimeVal| t.tv_sec() as f64 + t.tv_usec() as f64 * 1e-6;
    let record = serde_json::json!({
        "wall_s": wall_s,
        "user_s": secs(u.user_time()),
        "sys_s": secs(u.system_time()),
        "max_rss_kb": u.max_rss(),
    });
    pirouette::io::atomic_write(&a.record, record.to_string().as_bytes())?;
    if !status.success() {
        std::process::exit(status.code().unwrap_or(1));
    }
    Ok(())
}
