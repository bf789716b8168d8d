//! A laser log's estimated trajectory against the trajectory the log
//! records (for the published logs, a corrected one): absolute error
//! after alignment and relative errors between scans a given path length
//! apart, with dead reckoning from the raw odometry scored alike.

use super::map::align_rigid;
use anyhow::{bail, Context, Result};
use pirouette_geom::{wrap_angle, Point2, Pose2};
use pirouette_io::{read_poses, CarmenReader};
use serde::Serialize;
use std::path::Path;

/// Relative errors between pairs of scans a path length apart.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RelativeErrors {
    /// Path length between the scans of a pair (along the reference), metres.
    pub distance_m: f64,
    /// Pairs measured: each scan with the first scan at least
    /// `distance_m` farther along.
    pub pairs: usize,
    /// Mean translation error of the relative motion, metres.
    pub translation_mean_m: f64,
    /// Its standard deviation, metres.
    pub translation_sd_m: f64,
    /// Mean rotation error of the relative motion, degrees.
    pub rotation_mean_deg: f64,
    /// Its standard deviation, degrees.
    pub rotation_sd_deg: f64,
}

/// A trajectory's scores against the reference.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct LaserScores {
    /// RMS position error after the best rigid alignment, metres.
    pub ate_m: f64,
    /// Relative errors at each distance asked for.
    pub relative: Vec<RelativeErrors>,
}

/// `pirouette eval laser`'s report.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct LaserReport {
    /// The log's file name.
    pub log: String,
    /// Scans compared.
    pub scans: usize,
    /// The estimated trajectory.
    pub estimated: LaserScores,
    /// Raw odometry alone (steps without odometry taken as standing still).
    pub dead_reckoning: LaserScores,
    /// Steps between consecutive poses whose estimate is off the recorded
    /// step by more than [`WRONG_STEP_M`] or [`WRONG_STEP_DEG`] ...
    pub wrong_steps: usize,
    /// ... and of those, the ones `poses.json` does not mark ambiguous or
    /// unmatched: wrong without warning.
    pub wrong_unmarked: usize,
    /// Steps marked ambiguous or unmatched.
    pub marked: usize,
    /// Steps compared (poses less one).
    pub steps: usize,
}

/// A step off the recorded one by more than this is wrong, metres ...
pub const WRONG_STEP_M: f64 = 0.2;
/// ... or by more than this, degrees.
pub const WRONG_STEP_DEG: f64 = 3.0;

/// The relative errors of `estimated` against `reference` (paired) for
/// scan pairs `distance_m` apart along the reference's path.
pub fn relative_errors(estimated: &[Pose2], reference: &[Pose2], distance_m: f64) -> RelativeErrors {
    let mut along = Vec::with_capacity(reference.len());
    let mut s = 0.0;
    for (k, p) in reference.iter().enumerate() {
        if k > 0 {
            s += reference[k - 1].between(p).translation().norm();
        }
        along.push(s);
    }
    let (mut t, mut r) = (Vec::new(), Vec::new());
    let mut j = 0;
    for i in 0..reference.len() {
        j = j.max(i + 1);
        while j < reference.len() && along[j] - along[i] < distance_m {
            j += 1;
        }
        if j >= reference.len() {
            break;
        }
        let truth = reference[i].between(&reference[j]);
        let est = estimated[i].between(&estimated[j]);
        let e = truth.between(&est);
        t.push(e.translation().norm());
        r.push(wrap_angle(e.theta).abs().to_degrees());
    }
    let stats = |v: &[f64]| {
        let n = v.len().max(1) as f64;
        let mean = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
        (mean, var.sqrt())
    };
    let ((tm, ts), (rm, rs)) = (stats(&t), stats(&r));
    RelativeErrors {
        distance_m,
        pairs: t.len(),
        translation_mean_m: tm,
        translation_sd_m: ts,
        rotation_mean_deg: rm,
        rotation_sd_deg: rs,
    }
}

/// RMS position error of `estimated` after its best rigid alignment onto
/// `reference`.
pub fn aligned_ate(estimated: &[Pose2], reference: &[Pose2]) -> f64 {
    let a: Vec<Point2> = estimated.iter().map(Pose2::translation).collect();
    let b: Vec<Point2> = reference.iter().map(Pose2::translation).collect();
    let t = align_rigid(&a, &b);
    let sq: f64 = a
        .iter()
        .zip(&b)
        .map(|(p, q)| {
            let p = t.transform_point(*p);
            (p.x - q.x).powi(2) + (p.y - q.y).powi(2)
        })
        .sum();
    (sq / a.len().max(1) as f64).sqrt()
}

fn scores(estimated: &[Pose2], reference: &[Pose2], distances_m: &[f64]) -> LaserScores {
    LaserScores {
        ate_m: aligned_ate(estimated, reference),
        relative: distances_m
            .iter()
            .map(|&d| relative_errors(estimated, reference, d))
            .collect(),
    }
}

/// A log's own trajectories, one pose per scan in log order, both in the
/// first scan's frame (as `pirouette map` places the scans).
#[derive(Debug, Clone, PartialEq)]
pub struct LogTrajectories {
    /// The poses the log records (its reference, in a corrected log).
    pub recorded: Vec<Pose2>,
    /// The poses of the log's odometry alone (dead reckoning); a step
    /// without odometry counts as standing still.
    pub dead_reckoning: Vec<Pose2>,
}

/// Reads `log`'s recorded and dead-reckoned trajectories.
///
/// # Errors
/// A log that cannot be read or holds no laser scan.
pub fn log_trajectories(log: &Path) -> Result<LogTrajectories> {
    let mut recorded = Vec::new();
    let mut dead_reckoning = Vec::new();
    let mut first = None;
    for scan in CarmenReader::open(log)? {
        let scan = scan?;
        let first = *first.get_or_insert(scan.recorded);
        let dead = dead_reckoning.last().map_or(Pose2::IDENTITY, |last: &Pose2| {
            *last * scan.odometry.unwrap_or_default()
        });
        dead_reckoning.push(dead);
        recorded.push(first.between(&scan.recorded));
    }
    if recorded.is_empty() {
        bail!("{}: no laser scan in the log", log.display());
    }
    Ok(LogTrajectories {
        recorded,
        dead_reckoning,
    })
}

/// Scores the map folder `dir` that `pirouette map` wrote for `log`.
pub fn evaluate_laser(log: &Path, dir: &Path, distances_m: &[f64]) -> Result<LaserReport> {
    let poses_path = dir.join(pirouette_io::map_names::POSES_JSON);
    let records = read_poses(&poses_path)?;
    let LogTrajectories {
        recorded,
        dead_reckoning: dead,
    } = log_trajectories(log)?;
    let mut estimated = Vec::with_capacity(records.len());
    let mut reference = Vec::with_capacity(records.len());
    let mut reckoned = Vec::with_capacity(records.len());
    for (k, r) in records.iter().enumerate() {
        let scan = r
            .scan
            .with_context(|| format!("{}: pose {k} names no scan", poses_path.display()))?;
        let Some(rec) = recorded.get(scan) else {
            bail!(
                "{}: pose {k} is of scan {scan}, the log has {} scans",
                poses_path.display(),
                recorded.len()
            );
        };
        estimated.push(r.pose());
        reference.push(*rec);
        reckoned.push(dead[scan]);
    }
    if estimated.len() < 2 {
        bail!("{}: fewer than two poses to compare", poses_path.display());
    }
    let (mut wrong_steps, mut wrong_unmarked, mut marked) = (0, 0, 0);
    for k in 1..estimated.len() {
        let e = estimated[k - 1].between(&estimated[k]);
        let r = reference[k - 1].between(&reference[k]);
        let off = r.between(&e);
        let wrong = off.translation().norm() > WRONG_STEP_M || off.theta_deg().abs() > WRONG_STEP_DEG;
        let mark = records[k].trust.is_some();
        wrong_steps += usize::from(wrong);
        wrong_unmarked += usize::from(wrong && !mark);
        marked += usize::from(mark);
    }
    Ok(LaserReport {
        log: log
            .file_name()
            .map_or_else(|| log.display().to_string(), |n| n.to_string_lossy().into_owned()),
        scans: estimated.len(),
        estimated: scores(&estimated, &reference, distances_m),
        dead_reckoning: scores(&reckoned, &reference, distances_m),
        wrong_steps,
        wrong_unmarked,
        marked,
        steps: estimated.len() - 1,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_trajectory_scores_nothing_against_itself_and_a_known_error_exactly() {
        // A straight path of 0.5 m steps.
        let reference: Vec<Pose2> = (0..30).map(|k| Pose2::new(0.5 * k as f64, 0.0, 0.0)).collect();
        let same = relative_errors(&reference, &reference, 1.0);
        assert_eq!(same.pairs, 28);
        assert!(same.translation_mean_m < 1e-12 && same.rotation_mean_deg < 1e-12);
        // Every step 1 % long: scans 1 m apart are 2 steps, 1 cm off.
        let long: Vec<Pose2> = (0..30).map(|k| Pose2::new(0.505 * k as f64, 0.0, 0.0)).collect();
        let e = relative_errors(&long, &reference, 1.0);
        assert!((e.translation_mean_m - 0.01).abs() < 1e-9, "{e:?}");
        // Turned and moved as a whole: no relative error, no aligned error.
        let moved: Vec<Pose2> = reference
            .iter()
            .map(|p| Pose2::new(3.0, -2.0, 0.7) * *p)
            .collect();
        assert!(relative_errors(&moved, &reference, 1.0).translation_mean_m < 1e-9);
        assert!(aligned_ate(&moved, &reference) < 1e-9);
    }
}
