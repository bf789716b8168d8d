//! `pirouette map LOG` for laser logs, and `pirouette eval laser`.

use anyhow::{bail, Result};
use pirouette::eval::laser::{evaluate_laser, LaserScores};
use pirouette::eval::relations::{score_relations, MATCH_WINDOW_S};
use pirouette::geom::Pose2;
use pirouette::grid::RosMap;
use pirouette::io::{
    map_names, read_relations, read_tum, write_map_files, write_pose_graph, write_tum, OdometrySource,
    PoseRecord,
};
use pirouette::laser::{LaserConfig, RegisteredLog};
use pirouette::slam::LaserOutput;
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

/// Writes a mapped laser log into `out` and sums it up on stdout: the
/// poses first, so that whatever befell the grid the registration's work
/// is kept; `start` is when the run began.
pub fn write_and_report(mapped: LaserOutput, config: &LaserConfig, out: &Path, start: Instant) -> Result<()> {
    let LaserOutput {
        log,
        registered,
        grid,
        coarsened,
    } = mapped;
    let (log, r) = (log.as_path(), &registered);
    write_poses(log, r, out)?;
    // The grid gives way to its ROS map before the picture is drawn: the
    // two are never held beside the picture at once.
    let ros = match grid {
        Ok(grid) => RosMap::from_grid(&grid),
        Err(e) => bail!("{e}; the poses are written to {}, the map is not", out.display()),
    };
    if let Some(w) = &coarsened {
        eprintln!("warning: {}: {w}", log.display());
    }
    write_map(log, r, &ros, out)?;
    let seconds = start.elapsed().as_secs_f64();
    let scans = &r.scans;
    let unregistered = scans.iter().filter(|s| !s.registered).count();
    let path_m: f64 = scans
        .windows(2)
        .map(|w| w[0].pose.between(&w[1].pose).translation().norm())
        .sum();
    let info = &r.info;
    match (&info.scan_topic, &info.motion) {
        (Some(scan), motion) => outln!(
            "{}: scans from {scan}, motion from {}",
            info.format,
            motion
                .as_deref()
                .unwrap_or("nothing (no odometry topic and no /tf)")
        )?,
        _ => outln!("{}", info.format)?,
    }
    if info.mount != Pose2::IDENTITY {
        let m = info.mount;
        outln!(
            "the laser sits at ({:+.3}, {:+.3}) m, {:+.1}° on the robot (/tf_static)",
            m.x,
            m.y,
            m.theta_deg()
        )?;
    }
    for (why, n) in &info.skipped {
        outln!("{n} skipped: {why}")?;
    }
    for w in &info.warnings {
        eprintln!("warning: {w}");
    }
    outln!(
        "{} scans over {:.0} m registered ({} more the motion filter skipped, each placed by its match alone) in {:.2} s{}",
        scans.len(),
        path_m,
        r.skipped.len(),
        seconds,
        peak_memory_bytes().map_or(String::new(), |b| format!(
            ", peak memory {:.0} MB",
            b as f64 / 1e6
        ))
    )?;
    let loops = &r.loops;
    let kept = loops.iter().filter(|l| l.kept).count();
    let recognised = loops.iter().filter(|l| l.kept && l.recognised).count();
    outln!(
        "{kept} loops closed, {recognised} of them found by the place index ({} revisit searches among {} places kept; {} matches dropped as inconsistent with the rest of the graph; the graph solved {} times)",
        r.loop_searches,
        r.keyframes,
        loops.len() - kept,
        r.solves
    )?;
    if unregistered > 0 {
        outln!("{unregistered} scans matched too little of the map and were placed by their motion prior alone (odometry where the log has it)")?;
    }
    let ambiguous: Vec<usize> = scans.iter().filter(|s| s.ambiguous).map(|s| s.scan).collect();
    if let Some(first) = ambiguous.first() {
        outln!(
            "{} of {} steps ambiguous, the first at scan {first}: another pose {:.0} cm or {:.0}° away explained the scan within {:.0} nats, and the map may be wrong from there (poses.json marks them)",
            ambiguous.len(),
            scans.len().saturating_sub(1),
            config.loops.revisit.rival_apart_m * 100.0,
            config.loops.revisit.rival_apart_rad.to_degrees(),
            config.loops.revisit.min_rival_gap_ln
        )?;
    }
    // Which odometry convention the log holds, step by step.
    let mut sources: Vec<(OdometrySource, usize)> = Vec::new();
    let mut none = 0;
    for s in scans.iter().skip(1) {
        match s.odometry {
            Some(src) => match sources.iter_mut().find(|(k, _)| *k == src) {
                Some((_, n)) => *n += 1,
                None => sources.push((src, 1)),
            },
            None => none += 1,
        }
    }
    for (src, n) in sources {
        outln!("odometry of {n} steps from {}", src.describe())?;
    }
    if none > 0 {
        outln!("{none} steps had no odometry in the log and were matched under each motion the robot may have made")?;
    }
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

/// Writes the poses of a registered log into its map folder: `poses.json`
/// one pose per scan registered, `poses.tum` one per scan read (skipped
/// ones placed by their match), and the pose graph.
fn write_poses(log: &Path, r: &RegisteredLog, out: &Path) -> Result<()> {
    let records: Vec<PoseRecord> = r
        .scans
        .iter()
        .map(|s| PoseRecord::scan(s.scan, s.t, &s.pose).with_trust(s.trust()))
        .collect();
    if records.is_empty() {
        bail!("{}: no scan was mapped", log.display());
    }
    let every: Vec<PoseRecord> = (r.every_scan().iter())
        .map(|&(k, t, pose)| PoseRecord::scan(k, t, &pose))
        .collect();
    pirouette::io::write_poses(out, &records)?;
    pirouette::io::atomic_write_with(&out.join(map_names::POSES_TUM), |w| write_tum(w, &every))?;
    let ids: Vec<u64> = r.nodes.iter().map(|&k| r.scans[k].scan as u64).collect();
    write_pose_graph(&out.join(GRAPH_FILE), &r.graph, &ids)?;
    Ok(())
}

/// Writes the map of a registered log into its folder: the ROS map and
/// its picture.
fn write_map(log: &Path, r: &RegisteredLog, ros: &RosMap, out: &Path) -> Result<()> {
    let poses: Vec<Pose2> = r.scans.iter().map(|s| s.pose).collect();
    let name = log
        .file_name()
        .map_or_else(|| log.display().to_string(), |n| n.to_string_lossy().into_owned());
    let title = format!(
        "Map of {name}: {} laser scans, {} cm cells",
        poses.len(),
        ros.resolution_m * 100.0
    );
    let picture = pirouette::plot::map_figure(ros, &poses, &[], &title);
    let mut png = Vec::new();
    picture.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
    write_map_files(out, ros, &png)?;
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
    outln!(
        "{} of {} steps off the recorded step by more than {:.0} cm or {:.0}°, {} of them unmarked; {} marked ambiguous or unmatched",
        r.wrong_steps,
        r.steps,
        pirouette::eval::laser::WRONG_STEP_M * 100.0,
        pirouette::eval::laser::WRONG_STEP_DEG,
        r.wrong_unmarked,
        r.marked
    )?;
    Ok(())
}

/// Arguments of `pirouette eval relations`.
#[derive(clap::Args, Debug)]
pub struct EvalRelationsArgs {
    /// The trajectory: a `poses.tum` file, or the map folder holding one.
    poses: PathBuf,
    /// The benchmark's relations (`t1 t2 x y z roll pitch yaw` per line).
    relations: PathBuf,
    /// One JSON object on stdout.
    #[arg(long)]
    json: bool,
}

/// `pirouette eval relations`.
pub fn eval_relations(a: EvalRelationsArgs) -> Result<()> {
    let tum = if a.poses.is_dir() {
        a.poses.join(map_names::POSES_TUM)
    } else {
        a.poses.clone()
    };
    let trajectory = read_tum(&tum)?;
    let relations = read_relations(&a.relations)?;
    if relations.is_empty() {
        bail!("{}: no relation in the file", a.relations.display());
    }
    let s = score_relations(&trajectory, &relations);
    if a.json {
        outln!("{}", serde_json::to_string(&s)?)?;
        return Ok(());
    }
    outln!(
        "{}: {} of {} relations used ({} with a stamp no pose lies within {} s of)",
        tum.display(),
        s.used,
        s.relations,
        s.unmatched,
        MATCH_WINDOW_S
    )?;
    outln!(
        "translational error {:.4} ± {:.4} m (squared {:.5} ± {:.5} m²)",
        s.trans_abs_m,
        s.trans_abs_m_std,
        s.trans_sq_m2,
        s.trans_sq_m2_std
    )?;
    outln!(
        "rotational error    {:.3} ± {:.3}° (squared {:.3} ± {:.3} deg²)",
        s.rot_abs_deg,
        s.rot_abs_deg_std,
        s.rot_sq_deg2,
        s.rot_sq_deg2_std
    )?;
    if s.used == 0 {
        bail!("{}: no relation's stamps match the trajectory's", tum.display());
    }
    Ok(())
}
