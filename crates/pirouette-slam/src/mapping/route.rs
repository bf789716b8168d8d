//! The commanded route alone: its dead-reckoned poses, the extent it
//! spans, and the map that given poses make.

use pirouette_geom::Pose2;
use pirouette_grid::{GridConfig, OccupancyGrid};
use pirouette_io::Motion;
use pirouette_profile::Rop;

use crate::error::{Result, SlamError};
use crate::final_grid::grid_of;

/// Refuses, before any work, a dataset whose commanded moves alone span a
/// grid beyond [`GridConfig::max_cells`] (each sweep may still move by up
/// to the registration window, which the final grid's own check catches).
/// `reach_m` is how far a profile reaches (the soft range limit).
pub fn check_extent(motions: &[Option<Motion>], reach_m: f64, grid: &GridConfig) -> Result<()> {
    let reach = reach_m;
    let poses = dead_reckoning(motions);
    let (lo, hi) = poses
        .iter()
        .fold(((f64::MAX, f64::MAX), (f64::MIN, f64::MIN)), |(lo, hi), p| {
            ((lo.0.min(p.x), lo.1.min(p.y)), (hi.0.max(p.x), hi.1.max(p.y)))
        });
    let s = grid.resolution_m;
    let (w, h) = ((hi.0 - lo.0 + 2.0 * reach) / s, (hi.1 - lo.1 + 2.0 * reach) / s);
    if w.is_nan() || h.is_nan() || w * h > grid.max_cells as f64 {
        return Err(SlamError::Input {
            problem: format!(
                "the commanded moves span {:.1} × {:.1} m: a map of {:.0} × {:.0} cells of {} cm is beyond the budget of {} million cells \
                 (is a forward move given in millimetres?)",
                hi.0 - lo.0,
                hi.1 - lo.1,
                w,
                h,
                s * 100.0,
                grid.max_cells / 1_000_000
            ),
        });
    }
    Ok(())
}

/// A grid of the profiles seen from given poses (the map a perfect
/// registration would make).
pub fn map_with_poses<'r>(
    rops: impl IntoIterator<Item = &'r Rop>,
    poses: &[Pose2],
    blind_m: f64,
    config: &GridConfig,
) -> Result<OccupancyGrid> {
    grid_of(
        poses.iter().zip(rops),
        blind_m,
        config,
        "the given poses span too far",
    )
}

/// The trajectory the commands alone predict, from `(0, 0, 0)`: one pose
/// per frame, from each frame's motion.
pub fn dead_reckoning(motions: &[Option<Motion>]) -> Vec<Pose2> {
    let mut pose = Pose2::IDENTITY;
    motions
        .iter()
        .map(|motion| {
            if let Some(m) = motion {
                pose = pose * m.relative_pose();
            }
            pose
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dead_reckoning_follows_the_commands() {
        let motions = [
            None,
            Some(Motion::Turn { turn_deg: 90.0 }),
            Some(Motion::Forward { forward: 0.5 }),
            Some(Motion::Turn { turn_deg: -45.0 }),
        ];
        let poses = dead_reckoning(&motions);
        assert_eq!(poses[0], Pose2::IDENTITY);
        assert!((poses[2].x).abs() < 1e-12 && (poses[2].y - 0.5).abs() < 1e-12);
        assert!((poses[3].theta - 45f64.to_radians()).abs() < 1e-12);
    }
}
