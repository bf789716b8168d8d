//! A submap: obstacle points and their likelihood field in the frame of an
//! anchor pose, which the pose graph moves as one rigid piece. Scans (or a
//! camera sweep's profiles) are inserted while it is active, each touching
//! only the cells it reaches; a finished submap is frozen and only matched
//! against.

use pirouette_geom::{Point2, Pose2};
use pirouette_register::{
    register, thin_points, LikelihoodField, PosePrior, RegisterConfig, RegisterError, Registration,
};

/// Obstacle points and their likelihood field in the frame of `anchor`.
#[derive(Debug, Clone)]
pub struct Submap {
    /// The pose of the submap's frame in the world: its first frame's
    /// pose (the pose graph moves it with that frame).
    pub anchor: Pose2,
    field: LikelihoodField,
    /// Frames inserted.
    frames: usize,
    frozen: bool,
}

impl Submap {
    /// An empty submap anchored at `anchor`, whose field has cells of
    /// `resolution_m` and the Gaussian and floor of `config`.
    pub fn new(anchor: Pose2, resolution_m: f64, config: &RegisterConfig) -> Self {
        Self {
            anchor,
            field: LikelihoodField::from_points(&[], resolution_m, config.sigma_m, config.epsilon),
            frames: 0,
            frozen: false,
        }
    }

    /// Adds a frame's obstacle points (in its own frame) seen from
    /// `pose` (world), one per cell of the field that holds none near its
    /// centre yet: a wall seen by every frame is kept once, not once per
    /// frame. A frozen submap takes nothing: `false`.
    pub fn insert(&mut self, pose: &Pose2, points: &[Point2]) -> bool {
        if self.frozen {
            return false;
        }
        let to_anchor = self.anchor.inverse() * *pose;
        let moved: Vec<Point2> = points.iter().map(|p| to_anchor.transform_point(*p)).collect();
        let moved: Vec<Point2> = thin_points(&moved, self.field.resolution_m())
            .into_iter()
            .filter(|p| !self.field.covers(*p))
            .collect();
        self.field.insert(&moved);
        self.frames += 1;
        true
    }

    /// Takes no more frames.
    pub fn freeze(&mut self) {
        self.frozen = true;
    }

    /// Whether it takes no more frames.
    pub fn is_frozen(&self) -> bool {
        self.frozen
    }

    /// Frames inserted.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Its field, in the anchor's frame.
    pub fn field(&self) -> &LikelihoodField {
        &self.field
    }

    /// A world prior in the anchor's frame (its spreads are in its own
    /// mean's frame, which moves with it).
    pub fn local_prior(&self, prior: &PosePrior) -> PosePrior {
        PosePrior {
            mean: self.anchor.inverse() * prior.mean,
            ..*prior
        }
    }

    /// A world pose in the anchor's frame.
    pub fn local_pose(&self, pose: &Pose2) -> Pose2 {
        self.anchor.inverse() * *pose
    }

    /// Registers a frame's points (in its own frame) on the submap from a
    /// world prior, searched in the anchor's frame; the registration in
    /// world terms (pose, covariance and rival).
    pub fn register(
        &self,
        points: &[Point2],
        prior: &PosePrior,
        config: &RegisterConfig,
    ) -> Result<Registration, RegisterError> {
        let reg = register(&self.field, points, &self.local_prior(prior), config)?;
        Ok(self.to_world(reg))
    }

    /// A registration in the anchor's frame in world terms.
    fn to_world(&self, mut reg: Registration) -> Registration {
        reg.pose = self.anchor * reg.pose;
        reg.covariance = self.anchor.rotate_covariance(&reg.covariance);
        if let Some(rival) = reg.rival.as_mut() {
            rival.pose = self.anchor * rival.pose;
        }
        reg
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A wall and a post seen from two poses, inserted into a submap
    /// anchored elsewhere: a third view registers on it at its true pose,
    /// and moving the anchor moves the answer with it.
    #[test]
    fn a_submap_registers_in_the_world_and_moves_with_its_anchor() {
        let world: Vec<Point2> = (0..400)
            .map(|k| Point2::new(-1.0 + 0.005 * k as f64, 1.0))
            .chain((0..60).map(|k| {
                let a = k as f64 / 60.0 * std::f64::consts::TAU;
                Point2::new(0.3 + 0.05 * a.cos(), 0.4 + 0.05 * a.sin())
            }))
            .collect();
        let seen_from = |pose: &Pose2| -> Vec<Point2> {
            let inv = pose.inverse();
            world.iter().map(|p| inv.transform_point(*p)).collect()
        };
        let config = RegisterConfig::default();
        let anchor = Pose2::new(0.2, -0.1, 0.3);
        let mut submap = Submap::new(anchor, 0.01, &config);
        for pose in [Pose2::new(0.0, 0.0, 0.1), Pose2::new(0.1, 0.05, -0.2)] {
            assert!(submap.insert(&pose, &seen_from(&pose)));
        }
        assert_eq!(submap.frames(), 2);
        let truth = Pose2::new(0.05, 0.02, 0.05);
        let prior = PosePrior {
            mean: truth * Pose2::new(0.02, -0.015, 0.02),
            sigma_forward_m: 0.03,
            sigma_left_m: 0.03,
            sigma_theta_rad: 0.03,
        };
        let reg = submap.register(&seen_from(&truth), &prior, &config).unwrap();
        assert!(reg.accepted);
        let err = truth.between(&reg.pose);
        // (Within half the 1 cm lattice: its refinement.)
        assert!(
            err.translation().norm() < 0.005 && err.theta.abs() < 0.002,
            "{err:?}"
        );
        // The graph moves the anchor by `shift`: the answer moves alike.
        let shift = Pose2::new(0.5, -0.3, 0.4);
        let mut moved = submap.clone();
        moved.anchor = shift * anchor;
        let prior = PosePrior {
            mean: shift * prior.mean,
            ..prior
        };
        let again = moved.register(&seen_from(&truth), &prior, &config).unwrap();
        let err = (shift * reg.pose).between(&again.pose);
        assert!(
            err.translation().norm() < 1e-9 && err.theta.abs() < 1e-9,
            "{err:?}"
        );
        // Frozen, it takes nothing more.
        submap.freeze();
        assert!(!submap.insert(&truth, &seen_from(&truth)));
        assert_eq!(submap.frames(), 2);
    }
}
