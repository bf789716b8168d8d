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
    },
    /// Floor up to `top_row`, the last row that sees floor: nothing in sight.
    Clear {
        /// The topmost floor row of the column.
        top_row: u32,
    },
    /// The column sees no floor at all (it looks above the horizon).
    NoFloor,
}
