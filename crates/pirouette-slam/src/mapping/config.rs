//! The settings of mapping.

use pirouette_grid::GridConfig;
use pirouette_profile::sweep::SweepConfig;
use pirouette_register::{MotionNoise, RegisterConfig};

use crate::localise::LocaliseConfig;
use crate::revisit::RevisitTest;

/// Settings of mapping.
#[derive(Debug, Clone, PartialEq)]
pub struct MapConfig {
    /// The occupancy grid and its sensor model.
    pub grid: GridConfig,
    /// Sweep registration.
    pub register: RegisterConfig,
    /// Registering one frame alone about its sweep's centre (the anchors of
    /// the heading chain).
    pub turn: RegisterConfig,
    /// Errors of forward moves.
    pub motion: MotionNoise,
    /// Standard deviations of verified and commanded turns (the sweep
    /// assembly's).
    pub sweep: SweepConfig,
    /// Registration also matches ranges beyond the soft limit, up to this
    /// many times it (1: none). They never enter the grid.
    pub far_reach: f64,
    /// A commanded turn errs by this share of its angle where that is more
    /// than [`SweepConfig::commanded_sigma_rad`] (one standard deviation):
    /// odometry's rotation error grows with the rotation.
    pub turn_error_frac: f64,
    /// Revisits recognised by the place index become candidate loop
    /// edges of the joint adjustment ([`revisits`](super::revisits)); `None`: not looked
    /// for.
    pub revisits: Option<LocaliseConfig>,
    /// When a recognised revisit's match, beyond the reach of the pairwise
    /// matching, becomes a loop edge (the test laser logs use too).
    pub revisit: RevisitTest,
}

impl MapConfig {
    /// The standard deviation of a commanded turn by `turn_rad` (see
    /// [`MapConfig::turn_error_frac`]).
    pub fn command_sigma(&self, turn_rad: f64) -> f64 {
        self.sweep
            .commanded_sigma_rad
            .max(self.turn_error_frac * turn_rad.abs())
    }
}

impl Default for MapConfig {
    /// Default grid, registration, motion and sweep settings; a frame's
    /// heading about a known centre (one unknown, not three) trusts 6
    /// endpoints on the map (18 cm of edge) instead of 10; registration
    /// matches ranges out to twice the soft limit. A floor boundary's range
    /// error grows with the square of its range (one image row spans more
    /// floor the farther it is): at twice the limit it is four times the
    /// error at the limit, where profiles err by a few millimetres, so
    /// still within the likelihood field's 1.5 cm. A commanded turn errs by
    /// a tenth of its angle, at least the sweep settings' 3°: the 3° of a
    /// pirouette's 30° turns in proportion.
    fn default() -> Self {
        let register = RegisterConfig::default();
        Self {
            grid: GridConfig::default(),
            turn: RegisterConfig {
                min_matched: 6,
                ..register.clone()
            },
            register,
            motion: MotionNoise::default(),
            sweep: SweepConfig::default(),
            far_reach: 2.0,
            turn_error_frac: 0.1,
            revisits: Some(LocaliseConfig::default()),
            revisit: RevisitTest::default(),
        }
    }
}
