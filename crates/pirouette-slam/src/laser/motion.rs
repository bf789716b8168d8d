//! The prior of each scan's pose: from the step's odometry, or, in a
//! log without, under each motion the robot may have made.

use super::config::{LaserConfig, OdometryNoise};
use pirouette_geom::Pose2;
use pirouette_register::{PosePrior, RegisterConfig};

/// The prior of a scan's pose from the previous pose and the step's raw
/// odometry (`None`: the log holds none; the first of [`blind_priors`]).
pub fn step_prior(previous: &Pose2, odometry: Option<&Pose2>, config: &LaserConfig) -> PosePrior {
    match odometry {
        Some(step) => moved_by(previous, step, &config.odometry),
        None => blind_priors(previous, &MotionSoFar::default(), config)[0].1,
    }
}

/// `previous` moved by `step`, measured with `noise`.
pub(super) fn moved_by(previous: &Pose2, step: &Pose2, noise: &OdometryNoise) -> PosePrior {
    let n = noise;
    let (d, t) = (step.translation().norm(), step.theta.abs());
    let sigma_m = (n.per_m * d + n.m_per_rad * t).hypot(n.floor_m);
    PosePrior {
        mean: *previous * *step,
        sigma_forward_m: sigma_m,
        sigma_left_m: sigma_m,
        sigma_theta_rad: (n.per_rad * t + n.rad_per_m * d).hypot(n.floor_rad),
    }
}

/// What a log without odometry tells of the robot's motion: its matched
/// steps so far.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MotionSoFar {
    /// The newest scan's matched step from the scan before it (`None`
    /// where that match was not trusted).
    pub last_step: Option<Pose2>,
    /// The distance of the last step that drove (moved farther than
    /// [`LaserConfig::unknown_step_m`]), metres.
    pub last_drive_m: Option<f64>,
}

impl MotionSoFar {
    /// After a step matched as `step` (`None`: not trusted).
    pub fn after(self, step: Option<Pose2>, config: &LaserConfig) -> Self {
        let drive = step
            .map(|s| s.translation().norm())
            .filter(|&d| d > config.unknown_step_m);
        Self {
            last_step: step,
            last_drive_m: drive.or(self.last_drive_m),
        }
    }
}

/// A motion a robot may have made over a step the log holds no odometry
/// for (see [`blind_priors`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BlindMotion {
    /// Stood, or moved a little.
    Stood,
    /// Turned in place through any angle.
    Turned,
    /// Repeated its last matched step.
    Repeated,
    /// Drove straight on as far as it last drove.
    DroveOn,
}

impl BlindMotion {
    /// Whether the motion keeps the robot's course (it stood or went on
    /// as it was going); the others break it.
    pub fn keeps_course(self) -> bool {
        matches!(self, BlindMotion::Stood | BlindMotion::Repeated)
    }
}

/// The priors of a step the log holds no odometry for, one per motion a
/// robot may have made since the previous scan: stood or moved a little
/// ([`LaserConfig::unknown_step_m`]); turned in place through any angle;
/// repeated its last step (a robot keeps its speed and turn rate from scan
/// to scan); or, where that step did not drive, driven straight on as far
/// as it last drove (a robot that moves by turns in place and straight
/// moves, as the paper's, drives on after a turn). The first is always
/// [`BlindMotion::Stood`].
pub fn blind_priors(
    previous: &Pose2,
    motion: &MotionSoFar,
    config: &LaserConfig,
) -> Vec<(BlindMotion, PosePrior)> {
    let mut priors = vec![
        (
            BlindMotion::Stood,
            PosePrior {
                mean: *previous,
                sigma_forward_m: config.unknown_step_m,
                sigma_left_m: config.unknown_step_m,
                sigma_theta_rad: config.unknown_step_rad,
            },
        ),
        (
            BlindMotion::Turned,
            PosePrior {
                mean: *previous,
                sigma_forward_m: config.unknown_turn_m,
                sigma_left_m: config.unknown_turn_m,
                sigma_theta_rad: std::f64::consts::FRAC_PI_3,
            },
        ),
    ];
    let noise = &config.unknown_repeat;
    priors.extend(
        motion
            .last_step
            .map(|step| (BlindMotion::Repeated, moved_by(previous, &step, noise))),
    );
    let drove = motion
        .last_step
        .is_some_and(|s| s.translation().norm() > config.unknown_step_m);
    if !drove {
        let on = motion.last_drive_m.map(|d| Pose2::new(d, 0.0, 0.0));
        priors.extend(on.map(|step| (BlindMotion::DroveOn, moved_by(previous, &step, noise))));
    }
    priors
}

/// Whether `pose` lies within a cell (or a degree) of the edge of the
/// window [`register`] searched about `prior`.
pub(super) fn at_window_edge(prior: &PosePrior, pose: &Pose2, config: &RegisterConfig, cell_m: f64) -> bool {
    let w = prior.window(config);
    let turn = pirouette_geom::wrap_angle(pose.theta - prior.mean.theta);
    (pose.x - prior.mean.x).abs() >= w.half_x - cell_m
        || (pose.y - prior.mean.y).abs() >= w.half_y - cell_m
        || turn.abs() >= w.half_t - 1f64.to_radians()
}
