//! The one test of a true revisit, for every sensor: a frame registered
//! on the map of a place seen before counts as being there only where
//! registration trusts the match, enough of the frame's points lie on
//! that map, and no pose elsewhere explains the frame nearly as well.
//! A camera run asks it of the revisits its place index recognises, a
//! laser log of every keyframe it may be revisiting.

use pirouette_geom::Point2;
use pirouette_register::{register, LikelihoodField, PosePrior, RegisterConfig, Registration};

use crate::error::Result;

/// When a registration on an earlier place's map is a revisit.
#[derive(Debug, Clone, PartialEq)]
pub struct RevisitTest {
    /// At least this share of the frame's points lie on the map ...
    pub min_matched_share: f64,
    /// ... and no rival pose scores within this many nats of the best (a
    /// rival: a peak farther from the best than `rival_apart_m` or
    /// `rival_apart_rad`, within which two matches agree).
    pub min_rival_gap_ln: f64,
    /// Metres.
    pub rival_apart_m: f64,
    /// Radians.
    pub rival_apart_rad: f64,
}

impl Default for RevisitTest {
    /// Six points in ten on the map; no rival within 10 nats (a factor of
    /// 22,000 in likelihood) farther than 30 cm or 5° from the best.
    fn default() -> Self {
        Self {
            min_matched_share: 0.6,
            min_rival_gap_ln: 10.0,
            rival_apart_m: 0.3,
            rival_apart_rad: 5f64.to_radians(),
        }
    }
}

impl RevisitTest {
    /// Whether every figure is in range: a share in [0, 1], a gap of zero
    /// or more, tolerances positive.
    pub fn is_valid(&self) -> bool {
        (0.0..=1.0).contains(&self.min_matched_share)
            && self.min_rival_gap_ln >= 0.0
            && self.rival_apart_m > 0.0
            && self.rival_apart_rad > 0.0
            && self.rival_apart_m.is_finite()
            && self.rival_apart_rad.is_finite()
    }

    /// Whether `reg` (a registration made with [`RevisitTest::register`]'s
    /// settings) passes.
    pub fn passes(&self, reg: &Registration) -> bool {
        let share = reg.matched as f64 / reg.points.max(1) as f64;
        let rival_far = reg.rival.is_none_or(|r| r.below_best_ln >= self.min_rival_gap_ln);
        reg.accepted && share >= self.min_matched_share && rival_far
    }

    /// Registers `points` on `field` from `prior` (searched within
    /// `window_m` of its mean, rivals counted at this test's tolerances):
    /// the registration where it is a revisit.
    pub fn register(
        &self,
        field: &LikelihoodField,
        points: &[Point2],
        prior: &PosePrior,
        window_m: f64,
        config: &RegisterConfig,
    ) -> Result<Option<Registration>> {
        let config = RegisterConfig {
            max_window_m: window_m,
            rival_apart_m: self.rival_apart_m,
            rival_apart_rad: self.rival_apart_rad,
            rival_gap_ln: self.min_rival_gap_ln,
            ..config.clone()
        };
        let reg = register(field, points, prior, &config)?;
        Ok(self.passes(&reg).then_some(reg))
    }
}
