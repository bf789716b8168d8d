//! True radial profiles by 2D ray casting of the scene.

use pirouette_camera::CameraModel;
#[cfg(doc)]
use pirouette_camera::FloorTable;
use pirouette_geom::{Point2, Pose2};
use pirouette_io::World;
use pirouette_profile::Rop;

/// Rays cast per bin; the bin holds the nearest obstacle over them.
pub const RAYS_PER_BIN: usize = 9;

/// The true profile seen from `world_from_robot`: bins of `bin_width_rad`
/// centred on its multiples over `view_bearings_rad` (the camera's floor
/// view, [`FloorTable::bearing_span`]); each holds the
/// nearest obstacle over [`RAYS_PER_BIN`] rays cast from the robot centre,
/// counting only hits whose floor point lies inside the image. Unseen bins
/// are NaN; ranges beyond `max_range_m` are kept (they are not reliable).
pub fn true_profile(
    world: &World,
    camera: &impl CameraModel,
    world_from_robot: &Pose2,
    max_range_m: f64,
    bin_width_rad: f64,
    view_bearings_rad: (f64, f64),
) -> Rop {
    let (lo, hi) = view_bearings_rad;
    let mut rop = Rop::covering(lo, hi, bin_width_rad, max_range_m as f32)
        .expect("camera view and bin width are valid");
    let origin = [world_from_robot.x, world_from_robot.y];
    for i in 0..rop.len() {
        let start = rop.bearing_start_rad + i as f64 * bin_width_rad;
        let nearest = (0..RAYS_PER_BIN)
            .filter_map(|k| {
                let bearing = start + (k as f64 + 0.5) / RAYS_PER_BIN as f64 * bin_width_rad;
                let dir = world_from_robot.rotate_vector(Point2::from_polar(1.0, bearing));
                let (t, _) = world.ray_cast(origin, [dir.x, dir.y])?;
                let (u, v) = camera.floor_to_pixel(Point2::from_polar(t, bearing))?;
                camera.contains(u, v).then_some(t)
            })
            .fold(f64::INFINITY, f64::min);
        if nearest.is_finite() {
            rop.range_m[i] = nearest as f32;
        }
    }
    rop
}
