//! Commanded routes and the actual motion they produce.

use crate::Scene;
use pirouette_geom::{wrap_angle, Point2, Pose2};
use pirouette_io::Motion;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// One frame of a planned route.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedFrame {
    /// The sweep (spot) this frame belongs to.
    pub sweep: u32,
    /// Position of the frame within its sweep.
    pub index_in_sweep: u32,
    /// The commanded motion since the previous frame.
    pub motion: Option<Motion>,
    /// The actual pose at capture.
    pub world_from_robot: Pose2,
}

#[allow(clippy::expect_used, reason = "Scene::validate bounds every spread")]
fn normal(sigma: f64) -> Normal<f64> {
    Normal::new(0.0, sigma.max(0.0)).expect("standard deviation is finite and non-negative")
}

/// The frames of the scene's route with seed `seed`. At each waypoint the
/// robot captures `frames_per_sweep` frames evenly spaced over 360°, then
/// turns towards the next waypoint (one more frame in the same sweep) and
/// moves forward to it (the first frame of the next sweep). The turn and
/// distance towards the next spot are commanded from where the robot
/// actually is (as an operator watching it would), so the route stays
/// clear of obstacles; each motion then strays by the scene's errors.
pub fn plan_route(scene: &Scene, seed: u64) -> Vec<PlannedFrame> {
    let errs = &scene.motion_errors;
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x005E_ED0F_0A11);
    let turn_noise = normal(errs.turn_sigma_deg.to_radians());
    let jitter = normal(errs.rotation_centre_jitter_m);
    let forward_noise = normal(errs.forward_sigma_rel);
    let heading_noise = normal(errs.heading_sigma_deg.to_radians());
    let centre_dir: f64 = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
    let centre = Point2::from_polar(errs.rotation_centre_offset_m, centre_dir);

    let route = &scene.route;
    let start = route.waypoints[0];
    let mut actual = Pose2::from_deg(start[0], start[1], route.start_heading_deg);
    let mut frames = Vec::new();
    // The commanded step in degrees, as a robot's command would be given
    // (360/12 is 30 exactly; 2π/12 turned back into degrees is not).
    let step_deg = 360.0 / route.frames_per_sweep as f64;
    let step_rad = step_deg.to_radians();

    let turn = |actual: &mut Pose2, rng: &mut ChaCha8Rng, cmd_rad: f64| {
        let real = cmd_rad + cmd_rad.signum() * errs.turn_bias_deg.to_radians() + turn_noise.sample(rng);
        let c = Point2::new(centre.x + jitter.sample(rng), centre.y + jitter.sample(rng));
        // Rotation about the point c of the robot frame.
        *actual =
            *actual * Pose2::new(c.x, c.y, 0.0) * Pose2::new(0.0, 0.0, real) * Pose2::new(-c.x, -c.y, 0.0);
    };

    for (sweep, _) in route.waypoints.iter().enumerate() {
        let sweep = sweep as u32;
        if sweep == 0 {
            frames.push(PlannedFrame {
                sweep,
                index_in_sweep: 0,
                motion: None,
                world_from_robot: actual,
            });
        }
        // Later sweeps start with the frame captured on arrival (below).
        for k in 1..route.frames_per_sweep {
            turn(&mut actual, &mut rng, step_rad);
            let motion = Some(Motion::Turn { turn_deg: step_deg });
            frames.push(PlannedFrame {
                sweep,
                index_in_sweep: k,
                motion,
                world_from_robot: actual,
            });
        }
        let Some(next) = route.waypoints.get(sweep as usize + 1) else {
            break;
        };
        // Turn towards the next spot: one more frame in this sweep.
        let to_next = Point2::new(next[0] - actual.x, next[1] - actual.y);
        let cmd = wrap_angle(to_next.bearing() - actual.theta);
        turn(&mut actual, &mut rng, cmd);
        frames.push(PlannedFrame {
            sweep,
            index_in_sweep: route.frames_per_sweep,
            motion: Some(Motion::Turn {
                turn_deg: cmd.to_degrees(),
            }),
            world_from_robot: actual,
        });
        // Forward to it: the first frame of the next sweep.
        let dist = Point2::new(next[0] - actual.x, next[1] - actual.y).norm();
        let real = dist * (1.0 + forward_noise.sample(&mut rng));
        let dh = heading_noise.sample(&mut rng);
        actual = actual * Pose2::new(0.0, 0.0, dh / 2.0) * Pose2::new(real, 0.0, dh / 2.0);
        frames.push(PlannedFrame {
            sweep: sweep + 1,
            index_in_sweep: 0,
            motion: Some(Motion::Forward { forward: dist }),
            world_from_robot: actual,
        });
    }
    frames
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn route_has_sweeps_of_the_right_shape() {
        let scene = Scene::builtin("field-multi").unwrap();
        let frames = plan_route(&scene, 1);
        let n = scene.route.waypoints.len();
        let per = scene.route.frames_per_sweep as usize;
        assert_eq!(frames.len(), n * per + (n - 1));
        assert!(frames[0].motion.is_none());
        for f in &frames[1..] {
            match (f.index_in_sweep, f.motion) {
                (0, Some(Motion::Forward { forward })) => assert!(forward > 0.0),
                (k, Some(Motion::Turn { .. })) => assert!(k > 0),
                other => panic!("unexpected frame {other:?}"),
            }
        }
    }

    #[test]
    fn actual_turns_differ_from_command_but_stay_close() {
        let scene = Scene::builtin("field-pirouette").unwrap();
        let frames = plan_route(&scene, 3);
        let mut errors = Vec::new();
        for w in frames.windows(2) {
            if let Some(Motion::Turn { turn_deg }) = w[1].motion {
                let real = wrap_angle(w[1].world_from_robot.theta - w[0].world_from_robot.theta).to_degrees();
                errors.push(real - turn_deg);
                let moved = w[0].world_from_robot.translation();
                let now = w[1].world_from_robot.translation();
                // The rotation centre is 5 mm off: the robot centre moves at most 2·5 mm plus jitter.
                assert!((moved.x - now.x).hypot(moved.y - now.y) < 0.015);
            }
        }
        assert_eq!(errors.len(), 11);
        assert!(errors.iter().any(|e| e.abs() > 0.1));
        assert!(errors.iter().all(|e| e.abs() < 15.0));
    }

    #[test]
    fn same_seed_same_route() {
        let scene = Scene::builtin("field-multi").unwrap();
        assert_eq!(plan_route(&scene, 9), plan_route(&scene, 9));
        assert_ne!(plan_route(&scene, 9), plan_route(&scene, 10));
    }
}
