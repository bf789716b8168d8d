//! `pirouette map` and `pirouette eval map`.

use super::sweep::SweepOptions;
use anyhow::{bail, Context, Result};
use pirouette::eval::map::{
    evaluate_map_dir, truth_in_map_frame, MapInputs, MapQuality, MapReport, TrajectoryScores,
};
use pirouette::geom::Pose2;
use pirouette::grid::{GridConfig, RosMap, BYTES_PER_CELL};
use pirouette::io::{map_names, write_map_dir, BagOptions, Dataset, PoseRecord};
use pirouette::mapping::{MapConfig, MapRun, SweepPose};
use pirouette::pipeline::{self, Mapped, PipelineConfig, Stage, Swept};
use pirouette::slam::{Config, Input, MapOutput, Sensor, Work};
use std::path::{Path, PathBuf};

/// Settings of mapping.
#[derive(clap::Args, Debug, Clone, PartialEq)]
pub struct MapOptions {
    #[command(flatten)]
    sweep: SweepOptions,
    /// Side of a map cell, metres [default: 0.01 for camera datasets,
    /// 0.05 for laser logs].
    #[arg(long)]
    resolution: Option<f64>,
    /// Memory the map's grid may take, MB (nine bytes a cell). A laser
    /// log whose map would take more is mapped with cells 2, 4, 8, …
    /// times as wide, with a warning; a camera dataset whose commanded
    /// moves need more is refused before any image is read.
    #[arg(long, default_value_t = GridConfig::default().max_cells * BYTES_PER_CELL / 1_000_000)]
    max_map_mb: usize,
    /// Registration also matches ranges beyond the soft limit, up to this
    /// many times it (1: only the ranges the map takes). They never enter
    /// the map.
    #[arg(long, default_value_t = MapConfig::default().far_reach)]
    far_reach: f64,
}

impl Default for MapOptions {
    /// The command line's defaults.
    fn default() -> Self {
        #[derive(clap::Parser)]
        struct Wrapper {
            #[command(flatten)]
            options: MapOptions,
        }
        <Wrapper as clap::Parser>::parse_from(["pirouette"]).options
    }
}

impl MapOptions {
    /// The mapping settings' own checks (before any image is read).
    fn check(&self) -> Result<()> {
        self.sweep.check()?;
        if let Some(r) = self
            .resolution
            .filter(|r| !(r.is_finite() && *r >= 0.001 && *r <= 1.0))
        {
            bail!("--resolution {r} m is outside [0.001, 1]");
        }
        if self.max_map_mb == 0 {
            bail!("--max-map-mb 0: the map needs some memory");
        }
        Ok(())
    }

    /// The settings of a map of `input`: a laser log takes only the
    /// grid's settings (a camera's given for it is refused, not ignored),
    /// and a camera dataset no bag topic.
    fn config(&self, input: &Input, bag: BagOptions) -> Result<Config> {
        let mut config = Config::default();
        match input {
            Input::Laser(log) => {
                let camera_only = MapOptions {
                    resolution: None,
                    max_map_mb: MapOptions::default().max_map_mb,
                    ..self.clone()
                };
                if camera_only != MapOptions::default() {
                    bail!(
                        "{} is a laser log: of the map settings only --resolution and --max-map-mb apply to it (the others are a camera's)",
                        log.display()
                    );
                }
                if let Some(r) = self.resolution {
                    config.laser.grid.resolution_m = r;
                }
                config.laser.grid.max_cells = self.max_cells();
                config.bag = bag;
            }
            Input::Camera(ds) => {
                if bag.scan_topic.is_some() || bag.odom_topic.is_some() {
                    bail!(
                        "--scan-topic and --odom-topic are a bag's; {} is a camera dataset",
                        ds.manifest_path().display()
                    );
                }
                config.camera = self.pipeline()?;
            }
        }
        Ok(config)
    }

    /// The grid's cell budget of `--max-map-mb`.
    fn max_cells(&self) -> usize {
        self.max_map_mb.saturating_mul(1_000_000) / BYTES_PER_CELL
    }

    /// The run's settings.
    pub fn pipeline(&self) -> Result<PipelineConfig> {
        self.check()?;
        Ok(PipelineConfig {
            map: MapConfig {
                grid: GridConfig {
                    resolution_m: self.resolution.unwrap_or(GridConfig::default().resolution_m),
                    max_cells: self.max_cells(),
                    ..GridConfig::default()
                },
                far_reach: self.far_reach,
                ..MapConfig::default()
            },
            ..self.sweep.pipeline()?
        })
    }
}

/// Arguments of `pirouette map`.
#[derive(clap::Args, Debug)]
pub struct MapArgs {
    /// Camera dataset folder; or a laser log: a CARMEN log (FLASER or
    /// ROBOTLASER1 scans, with ODOM lines or raw odometry in the FLASER
    /// fields), a ROS 1 bag (.bag), a ROS 2 bag folder (with its
    /// metadata.yaml) or its .mcap / .db3 storage file.
    dataset: PathBuf,
    /// Folder for map.pgm, map.yaml, map.png, poses.json and poses.tum
    /// (created if missing; files in it are replaced atomically).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    options: MapOptions,
    /// A bag's sensor_msgs/LaserScan topic, where it has several.
    #[arg(long)]
    scan_topic: Option<String>,
    /// A bag's nav_msgs/Odometry topic, where it has several (without
    /// one, the /tf transform from the odometry frame to the robot's base
    /// is the motion).
    #[arg(long)]
    odom_topic: Option<String>,
}

/// Arguments of `pirouette eval map`.
#[derive(clap::Args, Debug)]
pub struct EvalMapArgs {
    /// The dataset folder, with true poses and truth/world.json.
    dataset: PathBuf,
    /// The folder `pirouette map` wrote.
    dir: PathBuf,
    /// Settings the map was made with (for the true-pose map beside it).
    #[command(flatten)]
    options: MapOptions,
    /// Tolerance of map quality, in cells.
    #[arg(long, default_value_t = 2.0)]
    tolerance_cells: f64,
    /// One JSON object on stdout.
    #[arg(long)]
    json: bool,
}

fn open_camera_dataset(path: &Path) -> Result<Dataset> {
    if Sensor::of(path) == Sensor::Laser {
        bail!(
            "{}: not a camera dataset (give its folder or dataset.json; a laser log maps with `pirouette map LOG`)",
            path.display()
        );
    }
    super::open_dataset(path)
}

/// A rival peak of a sweep's registration within this many nats of the
/// best is reported (its weight is `e⁻¹⁰ ≈ 4.5·10⁻⁵` of the best's or more).
const RIVAL_REPORTED_LN: f64 = 10.0;

/// Profiles and sweeps of a dataset, with a progress bar.
pub fn sweep_dataset(ds: &Dataset, options: &MapOptions) -> Result<(Swept, MapConfig)> {
    let config = options.pipeline()?;
    let bar = super::progress(ds.manifest.frames.len(), "profile");
    let swept = pipeline::sweep_dataset(ds, &config, &|_| bar.inc(1))?;
    bar.finish_and_clear();
    let map_config = swept.map_config(&config);
    Ok((swept, map_config))
}

/// The progress bars of a map: a camera's frames profiled, then its map's
/// steps; a laser log's scans (counted where that is cheap).
struct Bars {
    first: indicatif::ProgressBar,
    then: indicatif::ProgressBar,
}

impl Bars {
    fn new(work: &Work, sensor: Sensor) -> Self {
        let (first, then) = match sensor {
            Sensor::Camera => (
                super::progress(work.profiled, "profile"),
                super::progress(work.placed, "map steps"),
            ),
            Sensor::Laser => (
                match work.scans {
                    Some(n) => super::progress(n, "register"),
                    None => super::progress(0, "scans read"),
                },
                indicatif::ProgressBar::hidden(),
            ),
        };
        then.set_draw_target(indicatif::ProgressDrawTarget::hidden());
        Self { first, then }
    }

    /// One step of a stage: the second bar shows once its stage begins.
    fn report(&self, stage: Stage) {
        match stage {
            Stage::Profiled | Stage::Scan => self.first.inc(1),
            Stage::Placed => {
                if !self.first.is_finished() {
                    self.first.finish_and_clear();
                    self.then.set_draw_target(indicatif::ProgressDrawTarget::stderr());
                }
                self.then.inc(1)
            }
        }
    }

    fn finish(&self) {
        self.first.finish_and_clear();
        self.then.finish_and_clear();
    }
}

/// Opens a map's input, a camera dataset's warnings said.
fn open_input(path: &Path) -> Result<Input> {
    let input = Input::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    if let Input::Camera(ds) = &input {
        for w in &ds.warnings {
            eprintln!("warning: {w}");
        }
    }
    Ok(input)
}

/// Maps a camera dataset with a progress bar per stage; the dataset back
/// with its map.
pub fn map_dataset(ds: Dataset, options: &MapOptions) -> Result<(Dataset, Mapped)> {
    let input = Input::Camera(Box::new(ds));
    let config = options.config(&input, BagOptions::default())?;
    let bars = Bars::new(&input.work(&config)?, Sensor::Camera);
    let output = pirouette::slam::map(input, &config, &|stage| bars.report(stage));
    bars.finish();
    match output? {
        MapOutput::Camera { dataset, mapped } => Ok((*dataset, *mapped)),
        MapOutput::Laser(_) => bail!("a camera dataset gave a laser log's map"),
    }
}

/// Writes the map folder of a mapped dataset.
pub fn write_map(ds: &Dataset, mapped: &Mapped, dir: &Path) -> Result<()> {
    let ros = RosMap::from_grid(&mapped.map.grid);
    let sweep_poses: Vec<Pose2> = mapped.map.sweeps.iter().map(|s| s.pose).collect();
    let title = format!(
        "Map of {}: {} frames, {} sweeps, {} cm cells",
        ds.label(),
        mapped.map.frame_poses.len(),
        sweep_poses.len(),
        ros.resolution_m * 100.0
    );
    let picture = pirouette::plot::map_figure(&ros, &mapped.map.frame_poses, &sweep_poses, &title);
    let mut png = Vec::new();
    picture.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    let records: Vec<PoseRecord> = ds
        .manifest
        .frames
        .iter()
        .zip(&mapped.map.frame_poses)
        .map(|(f, p)| PoseRecord::frame(&f.image, p))
        .collect();
    write_map_dir(dir, &ros, &png, &records)?;
    Ok(())
}

/// Evaluates the map folder `dir` of `ds`, made from `swept` with
/// `config` (whose profiles also make the true-pose map beside it).
pub fn evaluate(
    ds: &Dataset,
    swept: &Swept,
    config: &MapConfig,
    dir: &Path,
    tolerance_cells: f64,
) -> Result<MapReport> {
    let span_rad = swept
        .extractor
        .table()
        .bearing_span()
        .with_context(|| format!("{}: the camera sees no floor", ds.manifest_path().display()))?;
    evaluate_map_dir(
        ds,
        dir,
        MapInputs {
            frames: &swept.frames,
            blind_m: swept.blind_m,
            span_rad,
            grid: &config.grid,
            pivot_m: config.sweep.matching.pivot_m,
        },
        tolerance_cells,
    )
}

/// `pirouette map`.
pub fn map(a: MapArgs) -> Result<()> {
    a.options.check()?;
    let input = open_input(&a.dataset)?;
    let bag = BagOptions {
        scan_topic: a.scan_topic,
        odom_topic: a.odom_topic,
    };
    let config = a.options.config(&input, bag)?;
    super::check_output_dir(&a.out)?;
    let start = std::time::Instant::now();
    let bars = Bars::new(&input.work(&config)?, input.sensor());
    let output = pirouette::slam::map(input, &config, &|stage| bars.report(stage));
    bars.finish();
    match output? {
        MapOutput::Laser(out) => super::laser::write_and_report(*out, &config.laser, &a.out, start),
        MapOutput::Camera { dataset, mapped } => {
            write_map(&dataset, &mapped, &a.out)?;
            report_camera(&mapped, &a.out)
        }
    }
}

/// What a camera map found, on stdout.
fn report_camera(mapped: &Mapped, out: &Path) -> Result<()> {
    let [px, py] = mapped.config.sweep.matching.pivot_m;
    outln!(
        "the robot turns about ({:+.1}, {:+.1}) mm from its centre (x forward, y left), as its verified turns measure it",
        px * 1000.0,
        py * 1000.0
    )?;
    // Where each sweep went, then the revisits the place index found.
    report_sweeps(&mapped.map.sweeps)?;
    report_revisits(&mapped.map)?;
    let ros = RosMap::from_grid(&mapped.map.grid);
    outln!(
        "map {} × {} cells of {} cm written to {} (look at {})",
        ros.width,
        ros.height,
        ros.resolution_m * 100.0,
        out.display(),
        out.join(map_names::PNG).display()
    )?;
    Ok(())
}

/// A line per sweep: its pose, how registration moved it from the
/// command and how sure it is, and a look-alike pose it nearly took.
fn report_sweeps(sweeps: &[SweepPose]) -> Result<()> {
    for s in sweeps {
        match (&s.prior, &s.registration) {
            (Some(prior), Some(reg)) => {
                let shift = prior.mean.between(&s.pose);
                outln!(
                    "sweep {:>2}  ({:>6.3}, {:>6.3}) m {:>7.2}°  {}: {:>5.1} cm, {:>5.2}° from the command; σ {:.1} cm {:.2}°; {} of {} endpoints on the map",
                    s.id,
                    s.pose.x,
                    s.pose.y,
                    s.pose.theta_deg(),
                    if reg.accepted { "registered" } else { "NOT REGISTERED (kept the command)" },
                    shift.translation().norm() * 100.0,
                    shift.theta.to_degrees(),
                    100.0 * reg.covariance[(0, 0)].max(reg.covariance[(1, 1)]).sqrt(),
                    reg.covariance[(2, 2)].sqrt().to_degrees(),
                    reg.matched,
                    reg.points
                )?;
                // A look-alike pose the search found nearly as good.
                if let Some(r) = reg.rival.filter(|r| r.below_best_ln < RIVAL_REPORTED_LN) {
                    let off = reg.pose.between(&r.pose);
                    outln!(
                        "          a rival pose {:.1} cm, {:.2}° away scores only {:.1} nats lower: the match may be ambiguous",
                        off.translation().norm() * 100.0,
                        off.theta.to_degrees(),
                        r.below_best_ln
                    )?;
                }
            }
            _ => outln!(
                "sweep {:>2}  ({:>6.3}, {:>6.3}) m {:>7.2}°  defines the map frame",
                s.id,
                s.pose.x,
                s.pose.y,
                s.pose.theta_deg()
            )?,
        }
    }
    Ok(())
}

/// The revisits the place index recognised, and those not kept.
fn report_revisits(map: &MapRun) -> Result<()> {
    let revisits = &map.revisits;
    if !revisits.is_empty() {
        let far = revisits.iter().filter(|r| r.beyond_reach).count();
        let registered = revisits.iter().filter(|r| r.registered).count();
        let kept = revisits.iter().filter(|r| r.kept).count();
        outln!(
            "revisits recognised by the place index: {} ({far} beyond the reach of the pairwise matching); {registered} matched as loop edges, {kept} kept by the adjustment",
            revisits.len()
        )?;
        for r in revisits.iter().filter(|r| !r.kept) {
            outln!(
                "          sweep {} at the place of sweep {} (score {:.2}): {}",
                map.sweeps[r.later].id,
                map.sweeps[r.earlier].id,
                r.score,
                if r.registered {
                    "dropped, the other matches disagree"
                } else {
                    "not confirmed by registration"
                }
            )?;
        }
    }
    Ok(())
}

/// `pirouette eval map`.
pub fn eval_map(a: EvalMapArgs) -> Result<()> {
    if !(a.tolerance_cells.is_finite() && a.tolerance_cells > 0.0) {
        bail!("--tolerance-cells {} must be positive", a.tolerance_cells);
    }
    let mut ds = open_camera_dataset(&a.dataset)?;
    let clock = pirouette::eval::sync::put_truth_on_frames(&mut ds)?;
    truth_in_map_frame(&ds)?;
    // Only the profiles are needed: the map and poses are read from DIR.
    let (swept, config) = sweep_dataset(&ds, &a.options)?;
    let mut r = evaluate(&ds, &swept, &config, &a.dir, a.tolerance_cells)?;
    r.clock = clock;
    if a.json {
        outln!("{}", serde_json::to_string(&r)?)?;
        return Ok(());
    }
    outln!("dataset {} ({} frames)", r.dataset, r.trajectory.poses)?;
    if let Some(c) = &r.clock {
        outln!(
            "truth's clock from the images: {:+.3} s, rate {:.5} ({} pairs of frames, median disagreement {:.2}°)",
            c.offset_s,
            c.rate,
            c.pairs,
            c.residual_median_deg
        )?;
    }
    let show_trajectory = |name: &str, t: &TrajectoryScores| {
        outln!(
            "{name:<12} ATE {:.2} cm aligned, {:.2} cm anchored (max {:.2} cm), heading RMSE {:.2}°; turn error median {:.2}°, p95 {:.2}°{}",
            t.ate_aligned_m * 100.0,
            t.ate_anchored_m * 100.0,
            t.max_anchored_m * 100.0,
            t.heading_rmse_deg,
            t.turn_error_median_deg,
            t.turn_error_p95_deg,
            t.heading_after_full_turn_deg
                .map_or(String::new(), |e| format!("; heading off by {e:.2}° after a full turn"))
        )
    };
    show_trajectory("trajectory", &r.trajectory)?;
    show_trajectory("commanded", &r.commanded)?;
    outln!(
        "profiles at the true poses: {:.1} % of {} obstacle points put in one place by a view from elsewhere",
        100.0 * r.profile_agreement.share,
        r.profile_agreement.points
    )?;
    for e in &r.sweeps {
        outln!(
            "  sweep {:>2}: first frame off by {:.2} cm, {:+.2}°",
            e.sweep,
            e.position_error_m * 100.0,
            e.heading_error_deg
        )?;
    }
    let show = |name: &str, q: &MapQuality| {
        outln!(
            "{name:<12} precision {:.3} ({} occupied cells), recall {:.3} ({} visible edge cells), F1 {:.3}",
            q.precision,
            q.occupied_cells,
            q.recall,
            q.visible_edge_cells,
            q.f1
        )
    };
    let turned = |_| {
        outln!(
            "{:<12} turns the map by {:+.2}° and moves its origin {:.2} cm; the trajectory's best-fit scale is {:.4}",
            "alignment",
            r.alignment.heading_deg,
            r.alignment.shift_m * 100.0,
            r.alignment.scale
        )
    };
    match &r.scene {
        Some(scene) => {
            show("map", &scene.map)?;
            show("map aligned", &scene.map_aligned)?;
            turned(())?;
            show("true poses", &scene.true_pose_map)?;
            outln!(
                "F1 is {:.1} % of the true-pose map's ({:.1} % aligned; tolerance {:.1} cm)",
                100.0 * scene.f1_ratio,
                100.0 * scene.f1_ratio_aligned,
                scene.tolerance_m * 100.0
            )?;
        }
        None => {
            turned(())?;
            outln!("map          no scene (truth/world.json) to score it against: the trajectory alone")?;
        }
    }
    let [x, y] = r.pivot.estimated_mm;
    match r.pivot.true_mm {
        Some([tx, ty]) => {
            outln!("pivot ({x:+.1}, {y:+.1}) mm from the turns, ({tx:+.1}, {ty:+.1}) mm in the true poses")?
        }
        None => outln!("pivot ({x:+.1}, {y:+.1}) mm from the turns")?,
    }
    Ok(())
}
