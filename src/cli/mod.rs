//! Command-line parsing and dispatch.

/// `println!` that returns the write error instead of panicking, so that a
/// closed pipe (`pirouette profile ... | head`) ends the command quietly.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($arg)*)
    }};
}

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};

mod bench;
mod camera;
mod choices;
mod graph;
mod laser;
mod map;
mod places;
mod plots;
mod profile;
mod render;
mod suite;
mod sweep;

/// Maps from a cheap camera: Radial Obstacle Profiles, vision-based
/// pirouettes and occupancy grids.
#[derive(Parser, Debug)]
#[command(
    name = "pirouette",
    version = concat!(env!("CARGO_PKG_VERSION"), " (", env!("PIROUETTE_COMMIT"), ")"),
    about, long_about = None, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render the built-in example dataset and run the pipeline on it.
    Example(render::ExampleArgs),
    /// Render a scene (built-in name or JSON scene file) into a dataset.
    Render(render::RenderArgs),
    /// Compare the paper's camera model with the pinhole model of a dataset.
    Camera(camera::CameraArgs),
    /// Radial Obstacle Profiles of every frame of a dataset.
    Profile(profile::ProfileArgs),
    /// Verified turns and 360° radial sweeps of a dataset.
    Sweep(sweep::SweepArgs),
    /// Build the occupancy grid map of a dataset or laser log.
    Map(map::MapArgs),
    /// Place index: build it from datasets, or describe one.
    #[command(subcommand)]
    Places(PlacesCommand),
    /// Localise the sweeps of a dataset against a place index: the place
    /// and pose of each, or "unknown".
    Localise(places::LocaliseArgs),
    /// Time matching on a dataset's own profiles: turn matches (direct
    /// search and FFT correlation) and place queries, p50/p95/p99 and
    /// throughput.
    Bench(bench::BenchArgs),
    /// Pose graphs in g2o format.
    #[command(subcommand)]
    Graph(GraphCommand),
    /// Evaluate results against ground truth.
    #[command(subcommand)]
    Eval(EvalCommand),
    /// Run a command and record its wall time, CPU time and peak memory
    /// (used by `eval suite`).
    #[command(hide = true)]
    Measure(suite::MeasureArgs),
}

#[derive(Subcommand, Debug)]
enum PlacesCommand {
    /// Build a place index from one or more datasets (one place per
    /// sweep).
    Build(places::PlacesBuildArgs),
    /// Places, bytes per place, size on disk and format of an index; the
    /// checksum verified.
    Info(places::PlacesInfoArgs),
}

#[derive(Subcommand, Debug)]
enum GraphCommand {
    /// Optimise a 2D pose graph (g2o VERTEX_SE2 / EDGE_SE2) and write the
    /// optimised graph; a file without vertices is initialised from its
    /// edges.
    Optimise(graph::GraphOptimiseArgs),
}

#[derive(Subcommand, Debug)]
enum EvalCommand {
    /// Profiles against truth/rop: median |relative range error|, share of
    /// truth bins within 10 %, missed, and false ranges on obstacle-free bins
    /// (again, as "(scene)", counting only those where truth/world.json cast
    /// densely has no obstacle within the limit in the bin's view either).
    Profile(profile::EvalProfileArgs),
    /// Verified turns against true headings: per-turn error of the estimate
    /// and of the command, heading error over each sweep, fallbacks.
    Sweep(sweep::EvalSweepArgs),
    /// Trajectory and map against truth: ATE after a best-fit rigid
    /// alignment and anchored at the first frame (beside the commanded
    /// motion's), per-sweep errors, and precision, recall and F1 of the
    /// occupied cells within 2 cells of the true obstacle outlines (recall
    /// over the outline visible from the true poses; in the map frame and
    /// after the trajectory's best-fit alignment, with how far that
    /// alignment turns and moves the map and the scale a best-fit
    /// similarity finds), beside those of a map built from the true poses.
    Map(map::EvalMapArgs),
    /// Localisation against truth: recall@1 over queries within 15 cm of
    /// a stored place, precision over all answers, pose errors of right
    /// answers (within 10 cm and 5° of the true pose), far queries
    /// answered wrongly, and the precision-recall curve over the score
    /// threshold (--out DIR: places-pr.png).
    Places(places::EvalPlacesArgs),
    /// A laser log's map folder against the trajectory the log records:
    /// absolute error after rigid alignment, and mean relative
    /// translation and rotation errors between scans 1 m and 10 m apart
    /// along the path, with dead reckoning from the raw odometry beside.
    Laser(laser::EvalLaserArgs),
    /// The SLAM benchmark's relations metric of a trajectory (poses.tum
    /// or a map folder): per relation the error of the trajectory's
    /// relative pose between the poses nearest its two stamps (within
    /// 0.1 s); mean ± std of the absolute and squared translational and
    /// rotational errors, relations used and unmatched.
    Relations(laser::EvalRelationsArgs),
    /// The scoreboard: every case of the corpus (datasets/corpus.toml),
    /// its figures, time and peak memory against its targets, worst first;
    /// per kind the worst case, the median and the cases short of target;
    /// with --base, another build side by side (speed ratios, figures that
    /// got worse). Writes OUT/scoreboard.json and OUT/scoreboard.md.
    Suite(suite::SuiteArgs),
}

/// Runs the command line.
///
/// This thread is one of the global pool's workers (as many as cores, or
/// `RAYON_NUM_THREADS`), so that the steps a command takes alone between
/// two parallel searches keep a core: from a thread outside the pool,
/// every worker would spin for work beside it (on two cores a laser log's
/// map took a fifth to a third longer so). Where the pool cannot take
/// this thread, the command runs beside it as before.
pub fn run() -> Result<()> {
    let cli = Cli::parse();
    let _ = rayon::ThreadPoolBuilder::new()
        .use_current_thread()
        .build_global();
    dispatch(cli.command)
}

/// Runs one command.
fn dispatch(command: Command) -> Result<()> {
    match command {
        Command::Example(a) => render::example(a),
        Command::Render(a) => render::render(a),
        Command::Camera(a) => camera::camera(a),
        Command::Profile(a) => profile::profile(a),
        Command::Sweep(a) => sweep::sweep(a),
        Command::Map(a) => map::map(a),
        Command::Places(PlacesCommand::Build(a)) => places::build(a),
        Command::Places(PlacesCommand::Info(a)) => places::info(a),
        Command::Localise(a) => places::run_localise(a),
        Command::Bench(a) => bench::bench(a),
        Command::Graph(GraphCommand::Optimise(a)) => graph::optimise(a),
        Command::Eval(EvalCommand::Profile(a)) => profile::eval_profile(a),
        Command::Eval(EvalCommand::Sweep(a)) => sweep::eval_sweep(a),
        Command::Eval(EvalCommand::Map(a)) => map::eval_map(a),
        Command::Eval(EvalCommand::Places(a)) => places::eval_places(a),
        Command::Eval(EvalCommand::Laser(a)) => laser::eval_laser(a),
        Command::Eval(EvalCommand::Relations(a)) => laser::eval_relations(a),
        Command::Eval(EvalCommand::Suite(a)) => suite::suite(a),
        Command::Measure(a) => suite::measure(a),
    }
}

/// Opens a dataset, with the path in the error.
pub(crate) fn open_dataset(path: &std::path::Path) -> Result<pirouette::io::Dataset> {
    let ds = pirouette::io::Dataset::open(path)
        .with_context(|| format!("cannot open dataset {}", path.display()))?;
    for w in &ds.warnings {
        eprintln!("warning: {w}");
    }
    Ok(ds)
}

/// A progress bar on stderr (hidden when stderr is not a terminal).
pub(crate) fn progress(len: usize, what: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg:>10} [{bar:30}] {pos}/{len} {elapsed}")
            .expect("template is valid")
            .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    bar
}

/// Checks, before any work, that `path` can be written as a file: it is
/// not a folder, and its folder exists (or can be made) and takes a new
/// file.
pub(crate) fn check_output_file(path: &std::path::Path) -> Result<()> {
    if path.is_dir() {
        bail!("{}: is a folder; give a file name to write", path.display());
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => std::path::Path::new("."),
    };
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create the folder", dir.display()))?;
    let probe = dir.join(format!(".pirouette-write-check.{}", std::process::id()));
    std::fs::write(&probe, b"").with_context(|| format!("{}: cannot write in this folder", dir.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Checks, before any work, that `dir` can take the files a command writes:
/// it is a folder (made if missing) in which a new file can be written.
pub(crate) fn check_output_dir(dir: &std::path::Path) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        bail!(
            "{}: is a file, not a folder; give a folder to write into",
            dir.display()
        );
    }
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create the folder", dir.display()))?;
    let probe = dir.join(format!(".pirouette-write-check.{}", std::process::id()));
    std::fs::write(&probe, b"").with_context(|| format!("{}: cannot write in this folder", dir.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}
