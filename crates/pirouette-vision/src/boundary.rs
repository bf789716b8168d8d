//! The floor/obstacle boundary of one image column.

use pirouette_profile::ColourTag;

/// What one image column shows, scanning from the bottom up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ColumnBoundary {
    /// Floor up to an obstacle whose base is at sub-pixel row `row` (pixel
    /// centres at integers; rows below `row` are floor).
    Obstacle {
        /// Sub-pixel row of the obstacle's base.
        row: f32,
        /// The obstacle's colour just above the boundary, normalised for
        /// lighting.
        colour: Option<ColourTag>,
        /// The row of an undecided base nearer than the obstacle (see
        /// [`ColumnBoundary::Undecided`]): the floor is known only below
        /// it. `None` when the floor was followed all the way.
        undecided: Option<u32>,
    },
    /// Floor up to `top_row`, the last row that sees floor: nothing in sight.
    Clear {
        /// The topmost floor row of the column.
        top_row: u32,
    },
    /// Floor up to an undecided base at row `row`: above it the floor
    /// shows again within
    /// [`VisionConfig::mark_depth_m`](crate::VisionConfig::mark_depth_m),
    /// so it may be a mark on the floor or an obstacle too low for one view
    /// to tell; beyond it no obstacle up to the column's last floor row.
    Undecided {
        /// The row of the undecided base (its lowest row not floor).
        row: u32,
    },
    /// The column sees no floor at all (it looks above the horizon).
    NoFloor,
}
