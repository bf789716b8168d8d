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
    #[allow(clippy::expect_used, reason = "a camera's view and a checked bin width")]
    let mut rop = Rop::covering(lo, hi, bin_width_rad, max_range_m as f32)
        .expect("camera view and bin width are valid");
    for i in 0..rop.len() {
        let start = rop.bearing_start_rad + i as f64 * bin_width_rad;
        if let Some(nearest) = nearest_in_view(
            world,
            camera,
            world_from_robot,
            start,
            bin_width_rad,
            RAYS_PER_BIN,
        ) {
            rop.range_m[i] = nearest as f32;
        }
    }
    rop
}

/// The nearest obstacle at bearings `[start_rad, start_rad + width_rad)`
/// of the robot at `world_from_robot`, over `rays` rays cast from its
/// centre at the middles of equal parts of the interval, counting only
/// hits whose floor point lies inside the image; `None` where no ray hits
/// in view.
pub fn nearest_in_view<C: CameraModel + ?Sized>(
    world: &World,
    camera: &C,
    world_from_robot: &Pose2,
    start_rad: f64,
    width_rad: f64,
    rays: usize,
) -> Option<f64> {
    let origin = [world_from_robot.x, world_from_robot.y];
    (0..rays)
        .filter_map(|k| {
            let bearing = start_rad + (k as f64 + 0.5) / rays as f64 * width_rad;
            let dir = world_from_robot.rotate_vector(Point2::from_polar(1.0, bearing));
            let (t, _) = world.ray_cast(origin, [dir.x, dir.y])?;
            let (u, v) = camera.floor_to_pixel(Point2::from_polar(t, bearing))?;
            camera.contains(u, v).then_some(t)
        })
        .reduce(f64::min)
}
