//! Camera models that turn image pixels into floor points in the robot frame.
//!
//! - [`IpmModel`]: the paper's inverse perspective mapping from four tape
//!   measurements `b, h, d, w` (eq. 1-5), angle-linear in the pixel index.
//! - [`PinholeModel`]: an exact pinhole camera with height, downward tilt,
//!   intrinsics, mount offset and lens distortion; both directions.
//! - [`Distortion`]: the lens models (radial-tangential, equidistant
//!   fisheye); [`Calibration`]: intrinsics and lens read from a ROS
//!   `camera_info` or OpenCV calibration YAML.
//! - [`CameraModel`]: what both provide; [`Camera`] holds either.
//! - [`FloorTable`]: per-pixel lookup of robot-frame floor coordinates and of
//!   polar (range, bearing) from the robot centre, built once per camera.
//!
//! Pixel convention: `u` column from the left, `v` row down from the top,
//! pixel centres at integer coordinates.
//!
//! ```
//! use pirouette_camera::{CameraModel, PinholeModel, FloorTable};
//! let cam = PinholeModel { width: 320, height: 240, fx: 277.1, fy: 277.1,
//!     cx: 159.5, cy: 119.5, height_m: 0.1, tilt_rad: 25f64.to_radians(),
//!     mount_forward_m: 0.0, mount_left_m: 0.0, distortion: Default::default() };
//! let p = cam.pixel_to_floor(159.5, 119.5).ok_or("centre pixel sees no floor")?;
//! assert!((p.x - 0.1 / 25f64.to_radians().tan()).abs() < 1e-9);
//! let table = FloorTable::new(&cam);
//! assert!(table.polar(160, 239).is_some());
//! # Ok::<(), &'static str>(())
//! ```
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

mod calibration;
mod ipm;
mod lens;
mod pinhole;
mod table;

pub use calibration::{Calibration, CalibrationError};
pub use ipm::{IpmMeasurements, IpmModel};
pub use lens::Distortion;
pub use pinhole::PinholeModel;
pub use table::{FloorTable, Polar};

use pirouette_geom::Point2;

/// A point in the robot frame (x forward, y left, z up), metres.
pub type Point3 = [f64; 3];

/// A camera that maps pixels to floor points and back.
pub trait CameraModel {
    /// Image width `m`, pixels.
    fn width(&self) -> u32;
    /// Image height `n`, pixels.
    fn height(&self) -> u32;
    /// The floor point (robot frame, metres) seen at pixel `(u, v)`, or
    /// `None` when the pixel looks at or above the horizon.
    fn pixel_to_floor(&self, u: f64, v: f64) -> Option<Point2>;
    /// The pixel `(u, v)` where a robot-frame point projects, or `None` when
    /// it is behind the camera. The pixel may lie outside the image.
    fn project(&self, point: Point3) -> Option<(f64, f64)>;
    /// The pixel where a floor point projects (see [`CameraModel::project`]).
    fn floor_to_pixel(&self, p: Point2) -> Option<(f64, f64)> {
        self.project([p.x, p.y, 0.0])
    }
    /// True when `(u, v)` lies inside the image (pixel centres `0..m-1`,
    /// `0..n-1`, each pixel extending half a pixel around its centre).
    fn contains(&self, u: f64, v: f64) -> bool {
        u >= -0.5 && v >= -0.5 && u <= self.width() as f64 - 0.5 && v <= self.height() as f64 - 0.5
    }
}

/// Which of the two models to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelKind {
    /// The paper's IPM from tape measurements.
    Paper,
    /// The exact pinhole model.
    Pinhole,
}

impl std::str::FromStr for ModelKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "paper" | "ipm" => Ok(ModelKind::Paper),
            "pinhole" => Ok(ModelKind::Pinhole),
            _ => Err(format!("unknown camera model `{s}` (expected paper or pinhole)")),
        }
    }
}

/// One of the camera models, chosen at run time.
#[derive(Debug, Clone, PartialEq)]
pub enum Camera {
    /// The paper's IPM.
    Paper(IpmModel),
    /// The pinhole model.
    Pinhole(PinholeModel),
}

impl Camera {
    /// Which model this is.
    pub fn kind(&self) -> ModelKind {
        match self {
            Camera::Paper(_) => ModelKind::Paper,
            Camera::Pinhole(_) => ModelKind::Pinhole,
        }
    }

    fn inner(&self) -> &dyn CameraModel {
        match self {
            Camera::Paper(m) => m,
            Camera::Pinhole(m) => m,
        }
    }
}

impl CameraModel for Camera {
    fn width(&self) -> u32 {
        self.inner().width()
    }
    fn height(&self) -> u32 {
        self.inner().height()
    }
    fn pixel_to_floor(&self, u: f64, v: f64) -> Option<Point2> {
        self.inner().pixel_to_floor(u, v)
    }
    fn project(&self, point: Point3) -> Option<(f64, f64)> {
        self.inner().project(point)
    }
}
