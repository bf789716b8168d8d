//! The final map, built one way for every sensor: each frame's profile
//! fused into one occupancy grid at the frame's solved pose.

use pirouette_geom::{Point2, Pose2};
use pirouette_grid::{GridConfig, OccupancyGrid};
use pirouette_profile::Rop;

use crate::error::{Result, SlamError};

/// A grid taking frames one by one (a camera run's from memory, a laser
/// log's streamed from its file again), refusing to outgrow its budget.
pub struct FinalGrid {
    grid: OccupancyGrid,
    blind_m: f64,
    hint: &'static str,
}

impl FinalGrid {
    /// An empty grid of `config`. Floor nearer than `blind_m` is not seen
    /// (a camera's bottom row; 0 for a laser). `hint` says, should the map
    /// outgrow its budget, what likely made it so.
    pub fn new(config: &GridConfig, blind_m: f64, hint: &'static str) -> Result<Self> {
        Ok(Self {
            grid: OccupancyGrid::new(config.clone())?,
            blind_m,
            hint,
        })
    }

    /// An empty grid of `config` (see [`FinalGrid::new`]) holding at once
    /// every profile reaching `reach_m` from a sensor within `sensors`
    /// (`lo`, `hi`); refused where that passes the budget.
    pub fn covering(
        config: &GridConfig,
        blind_m: f64,
        hint: &'static str,
        sensors: (Point2, Point2),
        reach_m: f64,
    ) -> Result<Self> {
        let mut grid = Self::new(config, blind_m, hint)?;
        if !grid.grid.reserve(sensors.0, sensors.1, reach_m) {
            return Err(SlamError::Budget {
                max_cells: config.max_cells,
                hint,
            });
        }
        Ok(grid)
    }

    /// Fuses a frame's profile seen from `pose` (the sensor's, in the
    /// map's frame). Refuses once the grid would outgrow its budget.
    pub fn insert(&mut self, pose: &Pose2, rop: &Rop) -> Result<()> {
        self.grid.insert_profile(pose, rop, self.blind_m);
        if self.grid.overflowed() {
            return Err(SlamError::Budget {
                max_cells: self.grid.config().max_cells,
                hint: self.hint,
            });
        }
        Ok(())
    }

    /// The grid of every frame inserted.
    pub fn finish(self) -> OccupancyGrid {
        self.grid
    }
}

/// The grid of profiles seen from given poses, in one call.
pub fn grid_of<'p, 'r>(
    frames: impl IntoIterator<Item = (&'p Pose2, &'r Rop)>,
    blind_m: f64,
    config: &GridConfig,
    hint: &'static str,
) -> Result<OccupancyGrid> {
    let mut grid = FinalGrid::new(config, blind_m, hint)?;
    for (pose, rop) in frames {
        grid.insert(pose, rop)?;
    }
    Ok(grid.finish())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_beyond_the_budget_is_refused_and_the_hint_said() {
        let mut rop = Rop::covering(-0.5, 0.5, 1f64.to_radians(), 1.0).unwrap();
        rop.range_m.iter_mut().for_each(|r| *r = 0.5);
        let config = GridConfig {
            max_cells: 100_000,
            ..GridConfig::default()
        };
        let near = grid_of([(&Pose2::IDENTITY, &rop)], 0.0, &config, "hint").unwrap();
        assert!(!near.cells_above(0.6).is_empty());
        // 10 m away: 1000 × 1000 cells would be needed.
        let far = Pose2::new(10.0, 0.0, 0.0);
        let err = grid_of(
            [(&Pose2::IDENTITY, &rop), (&far, &rop)],
            0.0,
            &config,
            "use coarser cells",
        )
        .unwrap_err();
        assert!(matches!(
            err,
            SlamError::Budget {
                max_cells: 100_000,
                ..
            }
        ));
        assert!(err.to_string().ends_with("use coarser cells"), "{err}");
    }
}
