//! The SLAM benchmark's relations metric (Kümmerle et al. 2009): for each
//! relation, the trajectory's poses nearest in time to its two stamps
//! (within [`MATCH_WINDOW_S`]), their relative pose `T1⁻¹·T2`, and its
//! component-wise difference from the relation: the translational error
//! is the length of the (x, y) difference, the rotational error the
//! absolute wrapped heading difference. Mean and standard deviation over
//! the relations used, of the absolute and of the squared errors.

use pirouette_geom::wrap_angle;
use pirouette_io::{Relation, StampedPose};
use serde::Serialize;

/// A relation's stamp matches the trajectory's nearest pose within this,
/// seconds.
pub const MATCH_WINDOW_S: f64 = 0.1;

/// The metric's figures (`pirouette eval relations --json`).
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct RelationScores {
    /// Relations in the file.
    pub relations: usize,
    /// Relations whose both stamps matched a pose.
    pub used: usize,
    /// Relations with a stamp no pose lies near.
    pub unmatched: usize,
    /// Mean translational error, metres ...
    pub trans_abs_m: f64,
    /// ... and its standard deviation.
    pub trans_abs_m_std: f64,
    /// Mean squared translational error, m² ...
    pub trans_sq_m2: f64,
    /// ... and its standard deviation.
    pub trans_sq_m2_std: f64,
    /// Mean rotational error, degrees ...
    pub rot_abs_deg: f64,
    /// ... and its standard deviation.
    pub rot_abs_deg_std: f64,
    /// Mean squared rotational error, deg² ...
    pub rot_sq_deg2: f64,
    /// ... and its standard deviation.
    pub rot_sq_deg2_std: f64,
}

/// Mean and standard deviation (over `n`: the relations scored are the
/// whole population); zeros for none.
fn mean_std(values: &[f64]) -> (f64, f64) {
    if values.is_empty() {
        return (0.0, 0.0);
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    (mean, var.sqrt())
}

/// The pose whose time is nearest `t`, if within the window; `sorted` is
/// ordered by time.
fn nearest(sorted: &[StampedPose], t: f64) -> Option<&StampedPose> {
    let i = sorted.partition_point(|p| p.t < t);
    let before = i.checked_sub(1).map(|j| &sorted[j]);
    let after = sorted.get(i);
    let best = match (before, after) {
        (Some(b), Some(a)) => {
            if t - b.t <= a.t - t {
                b
            } else {
                a
            }
        }
        (Some(b), None) => b,
        (None, Some(a)) => a,
        (None, None) => return None,
    };
    ((best.t - t).abs() <= MATCH_WINDOW_S).then_some(best)
}

/// The relations metric of `trajectory` (any order) on `relations`.
pub fn score_relations(trajectory: &[StampedPose], relations: &[Relation]) -> RelationScores {
    let mut sorted = trajectory.to_vec();
    sorted.sort_by(|a, b| a.t.total_cmp(&b.t));
    let (mut trans, mut rot) = (Vec::new(), Vec::new());
    for r in relations {
        let (Some(a), Some(b)) = (nearest(&sorted, r.t1), nearest(&sorted, r.t2)) else {
            continue;
        };
        let rel = a.pose.between(&b.pose);
        trans.push(rel.translation().distance(r.pose.translation()));
        rot.push(wrap_angle(rel.theta - r.pose.theta).abs().to_degrees());
    }
    let squares = |v: &[f64]| v.iter().map(|e| e * e).collect::<Vec<f64>>();
    let (ta, tas) = mean_std(&trans);
    let (ts, tss) = mean_std(&squares(&trans));
    let (ra, ras) = mean_std(&rot);
    let (rs, rss) = mean_std(&squares(&rot));
    RelationScores {
        relations: relations.len(),
        used: trans.len(),
        unmatched: relations.len() - trans.len(),
        trans_abs_m: ta,
        trans_abs_m_std: tas,
        trans_sq_m2: ts,
        trans_sq_m2_std: tss,
        rot_abs_deg: ra,
        rot_abs_deg_std: ras,
        rot_sq_deg2: rs,
        rot_sq_deg2_std: rss,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pirouette_geom::Pose2;

    fn at(t: f64, x: f64, y: f64, deg: f64) -> StampedPose {
        StampedPose {
            t,
            pose: Pose2::from_deg(x, y, deg),
        }
    }

    #[test]
    fn errors_are_the_relative_poses_differences() {
        // The robot turned 90° at (1, 0): in the first frame the second
        // pose is (1, 0, 90°); then it went 1 m along its new heading.
        let traj = [
            at(0.0, 0.0, 0.0, 0.0),
            at(1.0, 1.0, 0.0, 90.0),
            at(2.0, 1.0, 1.0, 90.0),
        ];
        let rel = |t1, t2, x, y, deg: f64| Relation {
            t1,
            t2,
            pose: Pose2::new(x, y, deg.to_radians()),
        };
        let relations = [
            // Exact.
            rel(0.0, 1.0, 1.0, 0.0, 90.0),
            // 0.3, 0.4 off (0.5 m) and 2° off; stamps 0.05 s from the poses.
            rel(1.05, 1.95, 1.3, 0.4, -2.0),
            // A stamp no pose lies near.
            rel(0.0, 5.0, 0.0, 0.0, 0.0),
        ];
        let s = score_relations(&traj, &relations);
        assert_eq!((s.relations, s.used, s.unmatched), (3, 2, 1));
        assert!((s.trans_abs_m - 0.25).abs() < 1e-12);
        assert!((s.trans_abs_m_std - 0.25).abs() < 1e-12);
        assert!((s.trans_sq_m2 - 0.125).abs() < 1e-12);
        assert!((s.rot_abs_deg - 1.0).abs() < 1e-9);
        assert!((s.rot_sq_deg2 - 2.0).abs() < 1e-9);
        assert!((s.rot_sq_deg2_std - 2.0).abs() < 1e-9);
    }

    #[test]
    fn headings_wrap() {
        let traj = [at(0.0, 0.0, 0.0, 179.0), at(1.0, 0.0, 0.0, -179.0)];
        let r = Relation {
            t1: 0.0,
            t2: 1.0,
            pose: Pose2::new(0.0, 0.0, -2f64.to_radians()),
        };
        // The true turn is +2°: 4° off, not 356°.
        let s = score_relations(&traj, &[r]);
        assert!((s.rot_abs_deg - 4.0).abs() < 1e-9, "{s:?}");
    }
}
