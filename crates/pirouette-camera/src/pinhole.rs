//! The exact pinhole camera model.

use crate::{CameraModel, Distortion, IpmMeasurements, Point3};
use pirouette_geom::Point2;

/// A pinhole camera looking forward and tilted down, standing at a mount
/// offset from the robot's rotation centre, seen through a lens model
/// ([`Distortion`]; [`Distortion::None`] for an ideal pinhole, whose
/// every figure is the same to the bit as without a lens model).
#[derive(Debug, Clone, PartialEq)]
pub struct PinholeModel {
    /// Image width `m`, pixels.
    pub width: u32,
    /// Image height `n`, pixels.
    pub height: u32,
    /// Focal length along `u`, pixels.
    pub fx: f64,
    /// Focal length along `v`, pixels.
    pub fy: f64,
    /// Principal point column, pixels.
    pub cx: f64,
    /// Principal point row, pixels.
    pub cy: f64,
    /// Height of the optical centre above the floor, metres.
    pub height_m: f64,
    /// Downward tilt of the optical axis from horizontal, radians.
    pub tilt_rad: f64,
    /// Camera offset ahead of the rotation centre, metres.
    pub mount_forward_m: f64,
    /// Camera offset to the left of the rotation centre, metres.
    pub mount_left_m: f64,
    /// The lens: how it bends rays on their way to the pixels.
    pub distortion: Distortion,
}

impl PinholeModel {
    /// Unit axes of the camera in the robot frame: (right, down, forward).
    fn axes(&self) -> ([f64; 3], [f64; 3], [f64; 3]) {
        let (s, c) = self.tilt_rad.sin_cos();
        let right = [0.0, -1.0, 0.0];
        let down = [-s, 0.0, -c];
        let forward = [c, 0.0, -s];
        (right, down, forward)
    }

    /// The ray direction (robot frame, not normalised) through pixel `(u, v)`,
    /// the lens's bending undone; `None` where the lens model has no ray
    /// for the pixel (see [`Distortion::undistort`]).
    pub fn ray(&self, u: f64, v: f64) -> Option<[f64; 3]> {
        let (r, d, f) = self.axes();
        let (xc, yc) = self
            .distortion
            .undistort((u - self.cx) / self.fx, (v - self.cy) / self.fy)?;
        Some([
            xc * r[0] + yc * d[0] + f[0],
            xc * r[1] + yc * d[1] + f[1],
            xc * r[2] + yc * d[2] + f[2],
        ])
    }

    /// The optical centre in the robot frame.
    pub fn centre(&self) -> Point3 {
        [self.mount_forward_m, self.mount_left_m, self.height_m]
    }

    /// The paper's four tape measurements that this camera would give, taken
    /// as the dataset format defines them: `b` from the robot centre to the
    /// floor point of the bottom scanline (row `n−1`) on the principal
    /// column, `d` from there to the point of the centre scanline (row
    /// `(n−1)/2`), `w` from the centre line to column 0 along that scanline.
    /// `None` when the centre scanline does not see the floor.
    pub fn ipm_measurements(&self) -> Option<IpmMeasurements> {
        let mid_v = (self.height as f64 - 1.0) / 2.0;
        let bottom = self.pixel_to_floor(self.cx, self.height as f64 - 1.0)?;
        let centre = self.pixel_to_floor(self.cx, mid_v)?;
        let edge = self.pixel_to_floor(0.0, mid_v)?;
        Some(IpmMeasurements {
            b: bottom.x,
            h: self.height_m,
            d: centre.x - bottom.x,
            w: (edge.y - centre.y).abs(),
        })
    }
}

impl CameraModel for PinholeModel {
    fn width(&self) -> u32 {
        self.width
    }
    fn height(&self) -> u32 {
        self.height
    }

    fn pixel_to_floor(&self, u: f64, v: f64) -> Option<Point2> {
        let ray = self.ray(u, v)?;
        // Rays that do not descend never reach the floor (horizon and above).
        if ray[2] >= -1e-12 {
            return None;
        }
        let t = self.height_m / -ray[2];
        Some(Point2::new(
            self.mount_forward_m + t * ray[0],
            self.mount_left_m + t * ray[1],
        ))
    }

    fn project(&self, point: Point3) -> Option<(f64, f64)> {
        let c = self.centre();
        let rel = [point[0] - c[0], point[1] - c[1], point[2] - c[2]];
        let (r, d, f) = self.axes();
        let dot = |a: [f64; 3]| a[0] * rel[0] + a[1] * rel[1] + a[2] * rel[2];
        let zc = dot(f);
        if zc <= 1e-12 {
            return None;
        }
        if self.distortion.is_none() {
            // The ideal pinhole's arithmetic, as it always was.
            return Some((self.cx + self.fx * dot(r) / zc, self.cy + self.fy * dot(d) / zc));
        }
        let (x, y) = self.distortion.distort(dot(r) / zc, dot(d) / zc);
        Some((self.cx + self.fx * x, self.cy + self.fy * y))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::IpmModel;
    use proptest::prelude::*;

    fn cam(mount_forward_m: f64, mount_left_m: f64) -> PinholeModel {
        PinholeModel {
            width: 320,
            height: 240,
            fx: 277.1281,
            fy: 277.1281,
            cx: 159.5,
            cy: 119.5,
            height_m: 0.1,
            tilt_rad: 25f64.to_radians(),
            mount_forward_m,
            mount_left_m,
            distortion: Default::default(),
        }
    }

    #[test]
    fn optical_axis_hits_floor_at_h_over_tan_tilt() {
        let c = cam(0.0, 0.0);
        let p = c.pixel_to_floor(c.cx, c.cy).unwrap();
        assert!((p.x - 0.1 / 25f64.to_radians().tan()).abs() < 1e-12);
        assert!(p.y.abs() < 1e-12);
    }

    /// A lens with barrel distortion (k1 < 0) pulls the image corners in:
    /// the corner pixel looks further out than the ideal pinhole's, and
    /// the principal point not at all.
    #[test]
    fn barrel_distortion_widens_the_corner_ray() {
        let ideal = cam(0.0, 0.0);
        let barrel = PinholeModel {
            distortion: Distortion::RadialTangential {
                k1: -0.2,
                k2: 0.0,
                p1: 0.0,
                p2: 0.0,
                k3: 0.0,
            },
            ..ideal.clone()
        };
        let a = ideal.pixel_to_floor(0.0, 239.0).unwrap();
        let b = barrel.pixel_to_floor(0.0, 239.0).unwrap();
        assert!(
            b.y > a.y,
            "barrel corner bearing {} vs ideal {}",
            b.y.atan2(b.x),
            a.y.atan2(a.x)
        );
        let c0 = ideal.pixel_to_floor(ideal.cx, ideal.cy).unwrap();
        let c1 = barrel.pixel_to_floor(ideal.cx, ideal.cy).unwrap();
        assert_eq!(c0, c1);
    }

    #[test]
    fn above_horizon_is_no_floor() {
        let c = cam(0.0, 0.0);
        // Horizon row: v = cy − fy·tan(tilt) ≈ −9.7, above the image.
        let horizon_v = c.cy - c.fy * c.tilt_rad.tan();
        assert!(c.pixel_to_floor(160.0, horizon_v - 1.0).is_none());
        assert!(c.pixel_to_floor(160.0, horizon_v + 1.0).is_some());
    }

    #[test]
    fn agrees_with_paper_model_where_paper_is_exact() {
        // The paper's model is exact on the principal column at the bottom
        // and centre scanlines, where its measurements were taken.
        for &(fwd, left) in &[(0.0, 0.0), (0.01, 0.0)] {
            let pin = cam(fwd, left);
            let meas = pin.ipm_measurements().unwrap();
            let paper = IpmModel {
                measurements: meas,
                width: 320,
                height: 240,
                mount_forward_m: fwd,
                mount_left_m: left,
            };
            for v in [239.0, 119.5] {
                let a = pin.pixel_to_floor(159.5, v).unwrap();
                let b = paper.pixel_to_floor(159.5, v).unwrap();
                assert!(
                    (a.x - b.x).abs() < 1e-12 && (a.y - b.y).abs() < 1e-12,
                    "v={v}: {a:?} vs {b:?}"
                );
            }
            // The centre scanline's image edge is exact too (w was taken there).
            let a = pin.pixel_to_floor(0.0, 119.5).unwrap();
            let b = paper.pixel_to_floor(0.0, 119.5).unwrap();
            assert!((a.x - b.x).abs() < 1e-12 && (a.y - b.y).abs() < 1e-12);
        }
    }

    #[test]
    fn measurements_match_shared_dataset_convention() {
        // The shared datasets list b = 0.09902, d = 0.12544, w = 0.13619 for
        // this camera with a 1 cm forward mount.
        let m = cam(0.01, 0.0).ipm_measurements().unwrap();
        assert!((m.b - 0.09902).abs() < 1e-5);
        assert!((m.d - 0.12544).abs() < 1e-5);
        assert!((m.w - 0.13619).abs() < 1e-5);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 512, rng_seed: proptest::test_runner::RngSeed::Fixed(3), ..ProptestConfig::default() })]

        #[test]
        fn pixel_floor_pixel_round_trip(u in 0.0f64..319.0, v in 0.0f64..239.0, fwd in -0.02f64..0.02, left in -0.02f64..0.02) {
            let c = cam(fwd, left);
            let p = c.pixel_to_floor(u, v).unwrap();
            let (u2, v2) = c.floor_to_pixel(p).unwrap();
            prop_assert!((u - u2).abs() < 1e-7 && (v - v2).abs() < 1e-7);
        }

        /// Through TUM freiburg2's lens (at 320x240), pixels map to the
        /// floor and back; the floor point differs from the ideal lens's
        /// where the lens bends the ray.
        #[test]
        fn distorted_pixel_floor_pixel_round_trip(u in 0.0f64..319.0, v in 130.0f64..239.0) {
            let c = PinholeModel {
                fx: 260.45, fy: 260.5, cx: 162.3, cy: 124.6, height_m: 0.56, tilt_rad: 6f64.to_radians(),
                distortion: Distortion::RadialTangential { k1: 0.2312, k2: -0.7849, p1: -0.0033, p2: -0.0001, k3: 0.9172 },
                ..cam(0.0, 0.0)
            };
            let p = c.pixel_to_floor(u, v).unwrap();
            let (u2, v2) = c.floor_to_pixel(p).unwrap();
            prop_assert!((u - u2).abs() < 1e-6 && (v - v2).abs() < 1e-6, "({u}, {v}) -> ({u2}, {v2})");
        }

        #[test]
        fn floor_pixel_floor_round_trip(x in 0.12f64..2.0, y in -0.5f64..0.5) {
            let c = cam(0.01, 0.0);
            let (u, v) = c.floor_to_pixel(Point2::new(x, y)).unwrap();
            let p = c.pixel_to_floor(u, v).unwrap();
            prop_assert!((p.x - x).abs() < 1e-9 && (p.y - y).abs() < 1e-9);
        }
    }
}
