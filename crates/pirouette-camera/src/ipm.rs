//! The paper's inverse perspective mapping (eq. 1-5).

use crate::{CameraModel, Point3};
use pirouette_geom::Point2;
use serde::{Deserialize, Serialize};

/// The four floor measurements of the paper, as taped by a user (metres).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct IpmMeasurements {
    /// Blind distance from the robot centre to the floor point seen by the
    /// bottom scanline.
    pub b: f64,
    /// Camera height above the floor.
    pub h: f64,
    /// Floor distance from the bottom scanline's point to the centre
    /// scanline's point.
    pub d: f64,
    /// Lateral floor distance from the centre line to the image edge along
    /// the centre scanline.
    pub w: f64,
}

/// The angles of eq. 1-3, radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IpmAngles {
    /// β, eq. 1: angle from the vertical to the bottom scanline's ray.
    pub beta: f64,
    /// α, eq. 2: half the vertical field of view.
    pub alpha: f64,
    /// γ, eq. 3: half the horizontal field of view.
    pub gamma: f64,
}

impl IpmMeasurements {
    /// Eq. 1-3, exactly as printed: `β = atan(b/h)`,
    /// `α = atan((b+d)/h) − β`, `γ = atan(w/(b+d))`.
    pub fn angles(&self) -> IpmAngles {
        let beta = (self.b / self.h).atan();
        let alpha = ((self.b + self.d) / self.h).atan() - beta;
        let gamma = (self.w / (self.b + self.d)).atan();
        IpmAngles { beta, alpha, gamma }
    }

    /// Eq. 4 and 5 exactly as printed for an `m × n` image: the paper's
    /// floor coordinates `(x, y)` of pixel `(u, v)`, `y` forward and `x`
    /// lateral (to the right for `u > (m−1)/2`). `None` at or above the
    /// horizon, where eq. 4's angle reaches 90°.
    pub fn paper_xy(&self, m: u32, n: u32, u: f64, v: f64) -> Option<(f64, f64)> {
        let IpmAngles { beta, alpha, gamma } = self.angles();
        let (m, n) = (m as f64, n as f64);
        let angle_from_vertical = beta + 2.0 * alpha * (n - 1.0 - v) / (n - 1.0);
        if angle_from_vertical >= std::f64::consts::FRAC_PI_2 || angle_from_vertical <= 0.0 {
            return None;
        }
        let y = self.h * angle_from_vertical.tan();
        let x = y * (gamma * (2.0 * u - m + 1.0) / (m - 1.0)).tan();
        Some((x, y))
    }

    /// All four values finite and positive.
    pub fn is_valid(&self) -> bool {
        [self.b, self.h, self.d, self.w]
            .iter()
            .all(|v| v.is_finite() && *v > 0.0)
    }
}

/// The paper's camera model: angle-linear rows and columns, measured with a
/// tape. The measurement `b` is taken from the robot centre (as the dataset
/// format defines it); with a camera mounted `mount_forward_m` ahead of the
/// centre, eq. 1-5 are applied to the camera-centred blind distance
/// `b − mount_forward_m` and the result is shifted by the mount offset.
#[derive(Debug, Clone, PartialEq)]
pub struct IpmModel {
    /// The tape measurements.
    pub measurements: IpmMeasurements,
    /// Image width `m`, pixels.
    pub width: u32,
    /// Image height `n`, pixels.
    pub height: u32,
    /// Camera offset ahead of the rotation centre, metres.
    pub mount_forward_m: f64,
    /// Camera offset to the left of the rotation centre, metres.
    pub mount_left_m: f64,
}

impl IpmModel {
    /// The measurements as seen from the camera (blind distance from the
    /// camera's foot rather than the robot centre).
    pub fn camera_centred(&self) -> IpmMeasurements {
        IpmMeasurements {
            b: self.measurements.b - self.mount_forward_m,
            ..self.measurements
        }
    }
}

impl CameraModel for IpmModel {
    fn width(&self) -> u32 {
        self.width
    }
    fn height(&self) -> u32 {
        self.height
    }

    fn pixel_to_floor(&self, u: f64, v: f64) -> Option<Point2> {
        let (x, y) = self.camera_centred().paper_xy(self.width, self.height, u, v)?;
        // Paper frame: y forward, x to the right. Robot frame: x forward, y left.
        Some(Point2::new(self.mount_forward_m + y, self.mount_left_m - x))
    }

    fn project(&self, point: Point3) -> Option<(f64, f64)> {
        let meas = self.camera_centred();
        let angles = meas.angles();
        let forward = point[0] - self.mount_forward_m;
        let right = -(point[1] - self.mount_left_m);
        let below = meas.h - point[2];
        if forward <= 0.0 {
            return None;
        }
        let (m, n) = (self.width as f64, self.height as f64);
        // Inverse of eq. 4 (angle from the vertical, linear in v).
        let angle_from_vertical = forward.atan2(below);
        let v = n - 1.0 - (angle_from_vertical - angles.beta) * (n - 1.0) / (2.0 * angles.alpha);
        // Inverse of eq. 5 (lateral angle, linear in u).
        let lateral = (right / forward).atan();
        let u = (lateral * (m - 1.0) / angles.gamma + m - 1.0) / 2.0;
        Some((u, v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// b = h = d = w = 0.1 m gives angles and ranges computable by hand:
    /// β = 45°, tan α = 1/3, tan 2α = 3/4, γ = atan(1/2).
    fn hand() -> IpmMeasurements {
        IpmMeasurements {
            b: 0.1,
            h: 0.1,
            d: 0.1,
            w: 0.1,
        }
    }

    #[test]
    fn angles_match_hand_values() {
        let a = hand().angles();
        assert!((a.beta - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        assert!((a.alpha.tan() - 1.0 / 3.0).abs() < 1e-12);
        assert!((a.gamma.tan() - 0.5).abs() < 1e-12);
    }

    #[test]
    fn eq4_eq5_match_hand_values() {
        let m = hand();
        // Bottom scanline: y = b.
        let (x, y) = m.paper_xy(320, 240, 159.5, 239.0).unwrap();
        assert!((y - 0.1).abs() < 1e-12 && x.abs() < 1e-12);
        // Centre scanline: y = b + d; image edges at ±w.
        let (x, y) = m.paper_xy(320, 240, 0.0, 119.5).unwrap();
        assert!((y - 0.2).abs() < 1e-12);
        assert!((x + 0.1).abs() < 1e-12);
        let (x, _) = m.paper_xy(320, 240, 319.0, 119.5).unwrap();
        assert!((x - 0.1).abs() < 1e-12);
        // Top scanline: y = h tan(β + 2α) = 0.1 · (1 + 3/4)/(1 − 3/4) = 0.7.
        let (_, y) = m.paper_xy(320, 240, 159.5, 0.0).unwrap();
        assert!((y - 0.7).abs() < 1e-12);
    }

    #[test]
    fn robot_frame_puts_left_columns_left() {
        let model = IpmModel {
            measurements: hand(),
            width: 320,
            height: 240,
            mount_forward_m: 0.0,
            mount_left_m: 0.0,
        };
        let p = model.pixel_to_floor(0.0, 119.5).unwrap();
        assert!((p.x - 0.2).abs() < 1e-12 && (p.y - 0.1).abs() < 1e-12);
    }

    #[test]
    fn horizon_gives_no_floor() {
        // A steep field of view that reaches past the horizon at the top rows.
        let m = IpmMeasurements {
            b: 0.1,
            h: 0.1,
            d: 1.0,
            w: 0.1,
        };
        assert!(m.paper_xy(320, 240, 160.0, 0.0).is_none());
        assert!(m.paper_xy(320, 240, 160.0, 239.0).is_some());
    }

    #[test]
    fn project_inverts_pixel_to_floor() {
        let model = IpmModel {
            measurements: hand(),
            width: 320,
            height: 240,
            mount_forward_m: 0.01,
            mount_left_m: -0.005,
        };
        for &(u, v) in &[(0.0, 239.0), (100.0, 50.0), (319.0, 119.5), (200.5, 180.25)] {
            let p = model.pixel_to_floor(u, v).unwrap();
            let (u2, v2) = model.floor_to_pixel(p).unwrap();
            assert!(
                (u - u2).abs() < 1e-9 && (v - v2).abs() < 1e-9,
                "{u},{v} -> {u2},{v2}"
            );
        }
    }
}
