//! Per-pixel lookup tables from a camera model.

use crate::CameraModel;
use pirouette_geom::Point2;

/// Polar coordinates of a floor point seen from the robot centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Polar {
    /// Distance from the robot centre, metres.
    pub range_m: f32,
    /// Bearing from the robot's forward axis, radians, positive left.
    pub bearing_rad: f32,
}

/// Robot-frame floor coordinates and polar coordinates of every pixel
/// centre, built once per camera. Pixels at or above the horizon hold NaN
/// ("no floor").
///
/// # Memory
/// Four `f32` per pixel: 1.2 MiB for a 320 × 240 image.
#[derive(Debug, Clone)]
pub struct FloorTable {
    width: u32,
    height: u32,
    /// Row-major `[x, y]` robot-frame floor point per pixel.
    xy: Vec<[f32; 2]>,
    /// Row-major `[range, bearing]` per pixel.
    polar: Vec<[f32; 2]>,
}

impl FloorTable {
    /// Builds the tables by evaluating `model` at every pixel centre.
    pub fn new(model: &(impl CameraModel + ?Sized)) -> Self {
        let (width, height) = (model.width(), model.height());
        let n = width as usize * height as usize;
        let mut xy = Vec::with_capacity(n);
        let mut polar = Vec::with_capacity(n);
        for v in 0..height {
            for u in 0..width {
                match model.pixel_to_floor(u as f64, v as f64) {
                    Some(p) => {
                        xy.push([p.x as f32, p.y as f32]);
                        polar.push([p.norm() as f32, p.bearing() as f32]);
                    }
                    None => {
                        xy.push([f32::NAN; 2]);
                        polar.push([f32::NAN; 2]);
                    }
                }
            }
        }
        Self {
            width,
            height,
            xy,
            polar,
        }
    }

    /// Image width, pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Image height, pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    fn index(&self, u: u32, v: u32) -> usize {
        assert!(
            u < self.width && v < self.height,
            "pixel ({u}, {v}) outside {}x{}",
            self.width,
            self.height
        );
        v as usize * self.width as usize + u as usize
    }

    /// The robot-frame floor point of pixel `(u, v)`, or `None` above the
    /// horizon.
    ///
    /// # Panics
    /// When the pixel lies outside the image; see [`FloorTable::floor_checked`].
    pub fn floor(&self, u: u32, v: u32) -> Option<Point2> {
        let [x, y] = self.xy[self.index(u, v)];
        x.is_finite().then(|| Point2::new(x as f64, y as f64))
    }

    /// As [`FloorTable::floor`], `None` outside the image too.
    pub fn floor_checked(&self, u: u32, v: u32) -> Option<Point2> {
        (u < self.width && v < self.height)
            .then(|| self.floor(u, v))
            .flatten()
    }

    /// Polar coordinates of pixel `(u, v)`, or `None` above the horizon.
    ///
    /// # Panics
    /// When the pixel lies outside the image; see [`FloorTable::polar_checked`].
    pub fn polar(&self, u: u32, v: u32) -> Option<Polar> {
        let [range_m, bearing_rad] = self.polar[self.index(u, v)];
        range_m.is_finite().then_some(Polar { range_m, bearing_rad })
    }

    /// As [`FloorTable::polar`], `None` outside the image too.
    pub fn polar_checked(&self, u: u32, v: u32) -> Option<Polar> {
        (u < self.width && v < self.height)
            .then(|| self.polar(u, v))
            .flatten()
    }

    /// The bearings (radians) spanned by the floor the camera sees: the
    /// extremes over every floor pixel. `None` when no pixel sees floor.
    pub fn bearing_span(&self) -> Option<(f64, f64)> {
        let (lo, hi) = self
            .polar
            .iter()
            .filter(|p| p[0].is_finite())
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p[1]), hi.max(p[1]))
            });
        (lo <= hi).then_some((lo as f64, hi as f64))
    }

    /// The blind distance: the range of the nearest floor point the camera
    /// sees (metres). `None` when no pixel sees floor.
    pub fn blind_range(&self) -> Option<f64> {
        let r = self
            .polar
            .iter()
            .map(|p| p[0])
            .filter(|r| r.is_finite())
            .fold(f32::INFINITY, f32::min);
        r.is_finite().then_some(r as f64)
    }

    /// The least change of inverse range (1/m) between two vertically
    /// adjacent floor pixels: how finely one image row resolves range
    /// where it resolves it worst (toward the horizon). `None` when no two
    /// such pixels see floor.
    pub fn finest_inverse_range_step(&self) -> Option<f64> {
        let step = (0..self.width)
            .flat_map(|u| (1..self.height).map(move |v| (u, v)))
            .filter_map(|(u, v)| {
                let (a, b) = (self.polar(u, v - 1)?, self.polar(u, v)?);
                let d = (1.0 / a.range_m as f64 - 1.0 / b.range_m as f64).abs();
                (d > 0.0).then_some(d)
            })
            .fold(f64::INFINITY, f64::min);
        step.is_finite().then_some(step)
    }

    /// The topmost row of column `u` that sees floor, if any.
    ///
    /// # Panics
    /// When `u` lies outside the image.
    pub fn top_floor_row(&self, u: u32) -> Option<u32> {
        (0..self.height).find(|&v| self.xy[self.index(u, v)][0].is_finite())
    }

    /// The floor point at column `u` and fractional row `v` (sub-pixel),
    /// interpolated linearly between the two nearest rows. `None` above the
    /// horizon or outside the image.
    pub fn floor_at_row(&self, u: u32, v: f32) -> Option<Point2> {
        if u >= self.width || !(0.0..=(self.height - 1) as f32).contains(&v) {
            return None;
        }
        let v0 = v.floor() as u32;
        let v1 = (v0 + 1).min(self.height - 1);
        let t = v - v0 as f32;
        let a = self.xy[self.index(u, v0)];
        let b = self.xy[self.index(u, v1)];
        let x = a[0] + t * (b[0] - a[0]);
        let y = a[1] + t * (b[1] - a[1]);
        x.is_finite().then(|| Point2::new(x as f64, y as f64))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PinholeModel;

    fn cam() -> PinholeModel {
        PinholeModel {
            width: 32,
            height: 24,
            fx: 27.7,
            fy: 27.7,
            cx: 15.5,
            cy: 11.5,
            height_m: 0.1,
            tilt_rad: 0.2,
            mount_forward_m: 0.01,
            mount_left_m: 0.0,
            distortion: Default::default(),
        }
    }

    #[test]
    fn table_matches_model_and_marks_horizon() {
        let c = cam();
        let t = FloorTable::new(&c);
        let mut floor = 0;
        let mut sky = 0;
        for v in 0..24 {
            for u in 0..32 {
                match (t.floor(u, v), c.pixel_to_floor(u as f64, v as f64)) {
                    (Some(a), Some(b)) => {
                        floor += 1;
                        assert!((a.x - b.x).abs() < 1e-5 * b.x.max(1.0));
                        let p = t.polar(u, v).unwrap();
                        assert!((p.range_m as f64 - b.norm()).abs() < 1e-5 * b.norm().max(1.0));
                    }
                    (None, None) => sky += 1,
                    other => panic!("table and model disagree at ({u},{v}): {other:?}"),
                }
            }
        }
        // Tilt 0.2 rad with fy 27.7 puts the horizon at v ≈ 5.9.
        assert!(floor > 0 && sky > 0, "floor {floor}, sky {sky}");
        assert!(t.floor_checked(32, 0).is_none());
        let top = t.top_floor_row(5).unwrap();
        assert!(t.floor(5, top).is_some() && (top == 0 || t.floor(5, top - 1).is_none()));
        let (lo, hi) = t.bearing_span().unwrap();
        assert!(
            lo < 0.0 && hi > 0.0 && (lo + hi).abs() < 1e-6,
            "symmetric camera: {lo} {hi}"
        );
        // The nearest floor point lies on the bottom row's centre column
        // (the row of largest v, the column closest to the optical axis).
        let bottom = (0..32).filter_map(|u| t.polar(u, 23)).map(|p| p.range_m as f64);
        let nearest = bottom.fold(f64::INFINITY, f64::min);
        assert_eq!(t.blind_range(), Some(nearest));
    }

    /// A camera one column wide sees the floor straight ahead: row `v`
    /// looks down at `tilt + atan((v − cy) / fy)`, and its inverse range is
    /// the tangent of that over the camera height.
    #[test]
    fn the_finest_inverse_range_step_is_the_smallest_change_a_row_makes() {
        let c = PinholeModel {
            width: 1,
            cx: 0.0,
            mount_forward_m: 0.0,
            ..cam()
        };
        let inverse_range = |v: u32| (c.tilt_rad + ((v as f64 - c.cy) / c.fy).atan()).tan() / c.height_m;
        let expected = (1..c.height)
            .filter(|&v| inverse_range(v - 1) > 0.0)
            .map(|v| inverse_range(v) - inverse_range(v - 1))
            .fold(f64::INFINITY, f64::min);
        let step = FloorTable::new(&c).finest_inverse_range_step().unwrap();
        assert!(
            (step - expected).abs() < 1e-5 * expected,
            "{step} against {expected}"
        );
    }

    #[test]
    fn sub_pixel_rows_interpolate_between_rows() {
        let t = FloorTable::new(&cam());
        let a = t.floor(10, 20).unwrap();
        let b = t.floor(10, 21).unwrap();
        let m = t.floor_at_row(10, 20.5).unwrap();
        assert!((m.x - (a.x + b.x) / 2.0).abs() < 1e-6);
    }
}
