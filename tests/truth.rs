//! The renderer's true profiles against an independent 2D ray cast.
//!
//! The renderer intersects rays with obstacle footprints analytically; this
//! oracle marches along each ray in 0.25 mm steps and tests whether the
//! point lies inside any footprint.

use crate::util::rendered;
use pirouette::camera::CameraModel;
use pirouette::geom::{Point2, Pose2};
use pirouette::io::{Dataset, Obstacle, World};

const STEP_M: f64 = 0.000_25;

fn inside(o: &Obstacle, p: [f64; 2]) -> bool {
    match *o {
        Obstacle::Box {
            center,
            size,
            yaw_deg,
            ..
        } => {
            let (s, c) = yaw_deg.to_radians().sin_cos();
            let (dx, dy) = (p[0] - center[0], p[1] - center[1]);
            (c * dx + s * dy).abs() <= size[0] / 2.0 && (-s * dx + c * dy).abs() <= size[1] / 2.0
        }
        Obstacle::Cylinder { center, radius, .. } => (p[0] - center[0]).hypot(p[1] - center[1]) <= radius,
    }
}

fn march(world: &World, origin: [f64; 2], dir: [f64; 2], limit: f64) -> Option<f64> {
    let steps = (limit / STEP_M) as usize;
    (0..=steps).map(|k| k as f64 * STEP_M).find(|t| {
        world
            .obstacles
            .iter()
            .any(|o| inside(o, [origin[0] + t * dir[0], origin[1] + t * dir[1]]))
    })
}

#[test]
fn truth_profiles_agree_with_marching_ray_cast() {
    let mut checked_hits = 0;
    let mut checked_empty = 0;
    for scene in ["field-pirouette", "room-multi"] {
        let ds = Dataset::open(&rendered(scene, 17)).unwrap();
        let world = ds.world().unwrap().unwrap();
        let camera = ds.camera(None).unwrap();
        let max_range = ds.manifest.max_range;
        for (i, f) in ds.manifest.frames.iter().enumerate().step_by(3) {
            let pose = Pose2::from(f.truth.unwrap());
            let truth = ds.truth_rop(i).unwrap().unwrap();
            for (b, r) in truth.range.iter().enumerate() {
                let start = (truth.bearing_start_deg + b as f64 * truth.bin_deg).to_radians();
                let w = truth.bin_deg.to_radians();
                // The oracle: nearest in-image hit over nine rays of the bin.
                let oracle = (0..9)
                    .filter_map(|k| {
                        let bearing = start + (k as f64 + 0.5) / 9.0 * w;
                        let d = pose.rotate_vector(Point2::from_polar(1.0, bearing));
                        let t = march(&world, [pose.x, pose.y], [d.x, d.y], max_range + 0.01)?;
                        // The hit lies in [t − step, t]: visible if either end is.
                        let seen = [t - STEP_M, t].iter().any(|&r| {
                            camera
                                .floor_to_pixel(Point2::from_polar(r, bearing))
                                .is_some_and(|(u, v)| camera.contains(u, v))
                        });
                        seen.then_some(t)
                    })
                    .fold(f64::INFINITY, f64::min);
                match r {
                    Some(r) => {
                        assert!(
                            (r - oracle).abs() <= 2.0 * STEP_M,
                            "{scene} frame {i} bin {b}: truth {r}, oracle {oracle}"
                        );
                        checked_hits += 1;
                    }
                    None => {
                        // Nothing within max_range (allowing the march's step).
                        assert!(
                            oracle > max_range - 2.0 * STEP_M,
                            "{scene} frame {i} bin {b}: truth null, oracle {oracle}"
                        );
                        checked_empty += 1;
                    }
                }
            }
        }
    }
    // Guard against a vacuous pass: both kinds of bin were checked.
    assert!(
        checked_hits > 200 && checked_empty > 50,
        "hits {checked_hits}, empty {checked_empty}"
    );
}
