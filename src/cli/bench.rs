//! `pirouette bench`: matching timed on a dataset's own profiles.

use super::sweep::SweepOptions;
use anyhow::{bail, Result};
use pirouette::geom::wrap_angle;
use pirouette::io::{Dataset, Motion};
use pirouette::localise::{file_sweeps, localise_signature, LocaliseConfig};
use pirouette::pipeline::Swept;
use pirouette::places::{PlaceIndex, SignatureConfig};
use pirouette::profile::matching::fft::FftCorrelation;
use pirouette::profile::matching::match_turn;
use serde_json::json;
use std::hint::black_box;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Arguments of `pirouette bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// The dataset folder whose profiles are matched.
    dataset: PathBuf,
    /// Timed passes over the dataset's turns and sweeps, after one
    /// untimed warm-up pass.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    repeat: u32,
    /// One JSON line per measured kind on stdout.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    sweep: SweepOptions,
}

/// Latencies of one kind of call.
struct Timing {
    kind: &'static str,
    calls: usize,
    p50: Duration,
    p95: Duration,
    p99: Duration,
    per_s: f64,
}

/// Calls `f` once on every item (warm-up), then `repeat` timed passes;
/// each call timed on its own.
fn measure(kind: &'static str, items: usize, repeat: u32, mut f: impl FnMut(usize)) -> Timing {
    for i in 0..items {
        f(i);
    }
    let mut samples = Vec::with_capacity(items * repeat as usize);
    let start = Instant::now();
    for _ in 0..repeat {
        for i in 0..items {
            let t = Instant::now();
            f(i);
            samples.push(t.elapsed());
        }
    }
    let total = start.elapsed().as_secs_f64();
    samples.sort_unstable();
    // Nearest rank: the smallest sample with at least p of them at or below.
    let at = |p: f64| samples[((p * samples.len() as f64).ceil() as usize).clamp(1, samples.len()) - 1];
    Timing {
        kind,
        calls: samples.len(),
        p50: at(0.50),
        p95: at(0.95),
        p99: at(0.99),
        per_s: samples.len() as f64 / total.max(1e-12),
    }
}

/// Runs `pirouette bench`.
pub fn bench(a: BenchArgs) -> Result<()> {
    let ds = super::open_dataset(&a.dataset)?;
    let swept = super::places::sweep_with_bar(&ds, &a.sweep)?;
    let mut timings = Vec::new();
    let mut notes = Vec::new();
    // Every verified turn's two matchers, and their errors against truth.
    let turns = time_turns(&ds, &swept, a.repeat, &mut timings, &mut notes);
    // The dataset's sweeps filed as places, then each looked up.
    let places = time_places(&ds, &swept, a.repeat, &mut timings, &mut notes)?;
    if timings.is_empty() {
        bail!(
            "{}: nothing to time: {}",
            ds.manifest_path().display(),
            notes.join("; ")
        );
    }
    if a.json {
        return print_json(&timings, &notes);
    }
    outln!(
        "{}: {turns} turns, {places} places; {} timed passes after one warm-up, single thread",
        ds.manifest.name,
        a.repeat
    )?;
    print_table(&timings, &notes)
}

/// Times both turn matchers on every commanded turn between two frames of
/// a sweep, and notes their median errors against the true turns where
/// the dataset has true poses: the number of turns.
fn time_turns(
    ds: &Dataset,
    swept: &Swept,
    repeat: u32,
    timings: &mut Vec<Timing>,
    notes: &mut Vec<String>,
) -> usize {
    let matching = &swept.sweep_config.matching;
    let pairs: Vec<(usize, usize, f64)> = swept
        .sweeps
        .iter()
        .flat_map(|s| s.frames.windows(2).map(|w| (w[0], w[1])))
        .filter_map(|(b, c)| match swept.frames[c].commanded() {
            Some(Motion::Turn { turn_deg }) => Some((b, c, turn_deg.to_radians())),
            _ => None,
        })
        .collect();
    if pairs.is_empty() {
        notes.push("no turns to match: turn timings left out".to_string());
        return 0;
    }
    // The direct search reads the profiles with their cue, as sweeps do;
    // the FFT correlation has no use for it.
    let view = |i: usize| swept.frames[i].match_view();
    let matched = |i: usize| &swept.frames[i].matched;
    timings.push(measure("turn: direct search", pairs.len(), repeat, |k| {
        let (b, c, cmd) = pairs[k];
        black_box(match_turn(view(b), view(c), cmd, matching));
    }));
    let mut fft = FftCorrelation::new();
    let (window, overlap) = (matching.window_rad, matching.min_overlap_rad);
    timings.push(measure("turn: FFT correlation", pairs.len(), repeat, |k| {
        let (b, c, cmd) = pairs[k];
        black_box(fft.match_turn(matched(b), matched(c), cmd, window, overlap));
    }));
    // Each matcher's error against the true turn.
    let truth = |i: usize| ds.manifest.frames[i].truth.map(|p| p.theta_deg.to_radians());
    let mut errors: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for &(b, c, cmd) in &pairs {
        let (Some(tb), Some(tc)) = (truth(b), truth(c)) else {
            continue;
        };
        let turn = tc - tb;
        let direct = match_turn(view(b), view(c), cmd, matching).turn_rad;
        let f = fft
            .match_turn(matched(b), matched(c), cmd, window, overlap)
            .unwrap_or(cmd);
        for (e, t) in errors.iter_mut().zip([direct, f]) {
            e.push(wrap_angle(t - turn).abs().to_degrees());
        }
    }
    if !errors[0].is_empty() {
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (d, f) = (median(&mut errors[0]), median(&mut errors[1]));
        notes.push(format!(
            "median error against the true turns: direct search {d:.2}°, FFT correlation {f:.2}° ({} turns)",
            errors[0].len()
        ));
    }
    pairs.len()
}

/// Files the dataset's sweeps as places and times looking each up (the
/// index's query, and the whole localisation): the number of places.
fn time_places(
    ds: &Dataset,
    swept: &Swept,
    repeat: u32,
    timings: &mut Vec<Timing>,
    notes: &mut Vec<String>,
) -> Result<usize> {
    let mut index = PlaceIndex::new(SignatureConfig::default())?;
    file_sweeps(&mut index, ds, &swept.sweeps, None, &Default::default())?;
    let queries: Vec<_> = swept
        .sweeps
        .iter()
        .filter_map(|s| {
            let sig = index.transforms().signature(&s.sweep.rop).ok()?;
            Some((sig, &s.sweep.rop))
        })
        .collect();
    if queries.is_empty() {
        notes.push("no sweep saw enough of the circle: place timings left out".to_string());
        return Ok(0);
    }
    let config = LocaliseConfig::default();
    timings.push(measure("place: index query", queries.len(), repeat, |k| {
        black_box(index.query(&queries[k].0, &config.query));
    }));
    timings.push(measure("place: localise", queries.len(), repeat, |k| {
        black_box(localise_signature(&index, &queries[k].0, queries[k].1, &config));
    }));
    Ok(queries.len())
}

/// Microseconds.
fn us(d: Duration) -> f64 {
    d.as_secs_f64() * 1e6
}

/// The timings as JSON Lines on stdout, the notes on stderr.
fn print_json(timings: &[Timing], notes: &[String]) -> Result<()> {
    for t in timings {
        outln!(
            "{}",
            json!({
                "kind": t.kind,
                "calls": t.calls,
                "p50_us": us(t.p50),
                "p95_us": us(t.p95),
                "p99_us": us(t.p99),
                "per_s": t.per_s,
            })
        )?;
    }
    for n in notes {
        eprintln!("{n}");
    }
    Ok(())
}

/// The timings as a table, then the notes.
fn print_table(timings: &[Timing], notes: &[String]) -> Result<()> {
    outln!(
        "{:<24} {:>8} {:>10} {:>10} {:>10} {:>10}",
        "kind",
        "calls",
        "p50 µs",
        "p95 µs",
        "p99 µs",
        "per s"
    )?;
    for t in timings {
        outln!(
            "{:<24} {:>8} {:>10.1} {:>10.1} {:>10.1} {:>10.0}",
            t.kind,
            t.calls,
            us(t.p50),
            us(t.p95),
            us(t.p99),
            t.per_s
        )?;
    }
    for n in notes {
        outln!("{n}")?;
    }
    Ok(())
}
