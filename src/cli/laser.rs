//! `pirouette map LOG` for laser logs, and `pirouette eval laser`.

use anyhow::{bail, Result};
use pirouette::eval::laser::{evaluate_laser, LaserScores};
use pirouette::geom::Pose2;
use pirouette::grid::RosMap;
use pirouette::io::{map_names, write_map_dir, write_pose_graph, PoseRecord};
use pirouette::laser::{count_scans, map_log, LaserConfig, LaserMap};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The pose graph of a laser map, beside the map's files: vertex `k` is
/// scan `k`.
const GRAPH_FILE: &str = "graph.g2o";

/// The peak resident memory of this process, bytes (Linux), if known.
fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Maps a laser log into `out`, with a progress bar and a summary.
pub fn map(log: &Path, out: &Path, config: &LaserConfig) -> Result<()> {
    pirouette::laser::check_config(config)?;
    super::check_output_dir(out)?;
    let start = Instant::now();
    let bar = super::progress(count_scans(log)?, "register");
    let mapped = map_log(log, config, &|| bar.inc(1))?;
    bar.finish_and_clear();
    write(log, &mapped, out)?;
    let seconds = start.elapsed().as_secs_f64();
    let scans = &mapped.registered.scans;
    let unregistered = scans.iter().filter(|s| !s.registered).count();
    let no_odometry = scans.iter().skip(1).filter(|s| !s.odometry).count();
    let path_m: f64 = scans
        .windows(2)
        .map(|w| w[0].pose.between(&w[1].pose).translation().norm())
        .sum();
    outln!(
        "{} scans over {:.0} m registered in {:.2} s{}",
        scans.len(),
        path_m,
        seconds,
        peak_memory_bytes().map_or(String::new(), |b| format!(
            ", peak memory {:.0} MB",
            b as f64 / 1e6
        ))
    )?;
    let loops = &mapped.registered.loops;
    let kept = loops.iter().filter(|l| l.kept).count();
    let recognised = loops.iter().filter(|l| l.kept && l.recognised).count();
    outln!(
        "{kept} loops closed, {recognised} of them found by the place index ({} revisit searches among {} places kept; {} matches dropped as inconsistent with the rest of the graph; the graph solved {} times)",
        mapped.registered.loop_searches,
        mapped.registered.keyframes,
        loops.len() - kept,
        mapped.registered.solves
    )?;
    if unregistered > 0 {
        outln!("{unregistered} scans matched too little of the map and kept their odometry")?;
    }
    if no_odometry > 0 {
        outln!("{no_odometry} steps had no odometry in the log and were searched without a motion prior")?;
    }
    let ros = RosMap::from_grid(&mapped.grid);
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

/// Writes the map folder of a mapped log.
fn write(log: &Path, mapped: &LaserMap, out: &Path) -> Result<()> {
    let ros = RosMap::from_grid(&mapped.grid);
    let poses: Vec<Pose2> = mapped.registered.scans.iter().map(|s| s.pose).collect();
    let name = log
        .file_name()
        .map_or_else(|| log.display().to_string(), |n| n.to_string_lossy().into_owned());
    let title = format!(
        "Map of {name}: {} laser scans, {} cm cells",
        poses.len(),
        ros.resolution_m * 100.0
    );
    let picture = pirouette::plot::map_figure(&ros, &poses, &[], &title);
    let mut png = Vec::new();
    picture.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    let records: Vec<PoseRecord> = mapped
        .registered
        .scans
        .iter()
        .map(|s| PoseRecord::scan(s.scan, s.t, &s.pose))
        .collect();
    if records.is_empty() {
        bail!("{}: no scan was mapped", log.display());
    }
    write_map_dir(out, &ros, &png, &records)?;
    let ids: Vec<u64> = mapped.registered.nodes.iter().map(|&k| k as u64).collect();
    write_pose_graph(&out.join(GRAPH_FILE), &mapped.registered.graph, &ids)?;
    Ok(())
}

/// Arguments of `pirouette eval laser`.
#[derive(clap::Args, Debug)]
pub struct EvalLaserArgs {
    /// The laser log (its recorded poses are the reference).
    log: PathBuf,
    /// The folder `pirouette map LOG` wrote.
    dir: PathBuf,
    /// One JSON object on stdout.
    #[arg(long)]
    json: bool,
}

/// Path lengths between the scans of the relative-error pairs, metres.
const RELATIVE_DISTANCES_M: [f64; 2] = [1.0, 10.0];

/// `pirouette eval laser`.
pub fn eval_laser(a: EvalLaserArgs) -> Result<()> {
    let r = evaluate_laser(&a.log, &a.dir, &RELATIVE_DISTANCES_M)?;
    if a.json {
        outln!("{}", serde_json::to_string(&r)?)?;
        return Ok(());
    }
    outln!(
        "{}: {} scans against the trajectory the log records",
        r.log,
        r.scans
    )?;
    let show = |name: &str, s: &LaserScores| -> std::io::Result<()> {
        let rel: Vec<String> = s
            .relative
            .iter()
            .map(|e| {
                format!(
                    "at {:.0} m {:.1} ± {:.1} cm, {:.2} ± {:.2}° ({} pairs)",
                    e.distance_m,
                    e.translation_mean_m * 100.0,
                    e.translation_sd_m * 100.0,
                    e.rotation_mean_deg,
                    e.rotation_sd_deg,
                    e.pairs
                )
            })
            .collect();
        outln!(
            "{name:<15} ATE {:.1} cm; relative error {}",
            s.ate_m * 100.0,
            rel.join("; ")
        )
    };
    show("mapped", &r.estimated)?;
    show("dead reckoning", &r.dead_reckoning)?;
    Ok(())
}
