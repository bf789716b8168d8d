//! Camera calibrations as users already have them: a ROS `camera_info`
//! YAML (as `camera_calibration` writes it) or an OpenCV calibration YAML
//! (`cv::FileStorage`, `%YAML:1.0` with `!!opencv-matrix` nodes).
//!
//! Both give the image size, the camera matrix `K` and the distortion
//! model and coefficients; neither gives where the camera stands on the
//! robot, which the dataset adds (height, tilt, mount).

use crate::lens::Distortion;
use crate::PinholeModel;
use std::path::{Path, PathBuf};
use yaml_rust2::{Yaml, YamlLoader};

/// Why a calibration file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file is not YAML, or not a calibration.
    #[error("{path}: {problem}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong, in a sentence.
        problem: String,
    },
}

/// The intrinsics of a calibrated camera.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// Image width the calibration was made at, pixels.
    pub width: u32,
    /// Image height the calibration was made at, pixels.
    pub height: u32,
    /// Focal length along `u`, pixels.
    pub fx: f64,
    /// Focal length along `v`, pixels.
    pub fy: f64,
    /// Principal point column, pixels.
    pub cx: f64,
    /// Principal point row, pixels.
    pub cy: f64,
    /// The lens model.
    pub distortion: Distortion,
}

/// The largest image side a calibration may name (as the dataset reader's).
const MAX_SIDE: u64 = 8192;

impl Calibration {
    /// Reads a ROS `camera_info` or OpenCV calibration YAML file.
    pub fn read(path: &Path) -> Result<Self, CalibrationError> {
        let text = std::fs::read_to_string(path).map_err(|source| CalibrationError::Io {
            path: path.to_owned(),
            source,
        })?;
        Self::parse(&text).map_err(|problem| CalibrationError::Invalid {
            path: path.to_owned(),
            problem,
        })
    }

    /// Parses the text of a ROS `camera_info` or OpenCV calibration YAML.
    pub fn parse(text: &str) -> Result<Self, String> {
        // OpenCV's FileStorage writes `%YAML:1.0`, which YAML 1.2 parsers
        // refuse as a directive: it carries nothing, so it is skipped.
        let body = match text.strip_prefix("%YAML:") {
            Some(rest) => rest.split_once('\n').map_or("", |(_, b)| b),
            None => text,
        };
        let docs = YamlLoader::load_from_str(body).map_err(|e| format!("not YAML: {e}"))?;
        let doc = docs.first().ok_or("an empty file")?;
        if doc.as_hash().is_none() {
            return Err("not a calibration: the file is not a mapping of keys".into());
        }
        let width = size(doc, &["image_width", "width"])?;
        let height = size(doc, &["image_height", "height"])?;
        let k = matrix(doc, &["camera_matrix", "K", "k"])?
            .ok_or("no camera_matrix (ROS camera_info and OpenCV calibrations give one)")?;
        if k.len() != 9 {
            return Err(format!("camera_matrix has {} values, not 9", k.len()));
        }
        let (fx, fy, cx, cy) = (k[0], k[4], k[2], k[5]);
        if !(fx > 0.0 && fy > 0.0 && fx.is_finite() && fy.is_finite() && cx.is_finite() && cy.is_finite()) {
            return Err(format!(
                "camera_matrix: fx {fx} and fy {fy} must be positive, cx {cx} and cy {cy} finite"
            ));
        }
        if k[1] != 0.0 || k[3] != 0.0 || k[6] != 0.0 || k[7] != 0.0 || k[8] != 1.0 {
            return Err(format!(
                "camera_matrix {k:?} is not of the form [fx 0 cx; 0 fy cy; 0 0 1] (a skewed camera is not supported)"
            ));
        }
        let d = matrix(doc, &["distortion_coefficients", "D", "d", "dist_coeffs"])?.unwrap_or_default();
        let name = ["distortion_model", "camera_model_distortion"]
            .iter()
            .find_map(|key| doc[*key].as_str())
            // OpenCV's own files name no model: its default is plumb_bob.
            .unwrap_or(if d.is_empty() { "none" } else { "plumb_bob" });
        let distortion = Distortion::from_named(name, &d)?;
        Ok(Self {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
            distortion,
        })
    }

    /// The pinhole model of this camera standing `height_m` above the
    /// floor, tilted `tilt_rad` down, at `mount_forward_m`, `mount_left_m`
    /// from the robot's turning centre.
    pub fn pinhole(
        &self,
        height_m: f64,
        tilt_rad: f64,
        mount_forward_m: f64,
        mount_left_m: f64,
    ) -> PinholeModel {
        PinholeModel {
            width: self.width,
            height: self.height,
            fx: self.fx,
            fy: self.fy,
            cx: self.cx,
            cy: self.cy,
            height_m,
            tilt_rad,
            mount_forward_m,
            mount_left_m,
            distortion: self.distortion,
        }
    }

    /// The calibration of the same camera at `width` × `height` (an image
    /// scaled by the same factor both ways): focal lengths and principal
    /// point scale, pixel centres kept at integer coordinates, the lens
    /// model (on normalised coordinates) unchanged. `None` when the aspect
    /// ratio differs.
    pub fn scaled_to(&self, width: u32, height: u32) -> Option<Self> {
        let sx = f64::from(width) / f64::from(self.width);
        let sy = f64::from(height) / f64::from(self.height);
        if (sx - sy).abs() > 1e-9 * sx.max(sy) {
            return None;
        }
        Some(Self {
            width,
            height,
            fx: self.fx * sx,
            fy: self.fy * sy,
            // A pixel centre at c in the original lies at (c + ½)s − ½.
            cx: (self.cx + 0.5) * sx - 0.5,
            cy: (self.cy + 0.5) * sy - 0.5,
            distortion: self.distortion,
        })
    }
}

fn size(doc: &Yaml, keys: &[&str]) -> Result<u32, String> {
    let (key, v) = keys
        .iter()
        .find_map(|k| doc[*k].as_i64().map(|v| (*k, v)))
        .ok_or_else(|| format!("no {} (the image size)", keys[0]))?;
    if !(1..=MAX_SIDE as i64).contains(&v) {
        return Err(format!("{key} {v} is not a size of 1 to {MAX_SIDE} pixels"));
    }
    Ok(v as u32)
}

/// A matrix's values in row-major order: a ROS or OpenCV node
/// (`{rows, cols, data: [...]}`) or a plain list; `None` when absent.
fn matrix(doc: &Yaml, keys: &[&str]) -> Result<Option<Vec<f64>>, String> {
    let Some((key, node)) = keys
        .iter()
        .map(|k| (*k, &doc[*k]))
        .find(|(_, v)| !v.is_badvalue())
    else {
        return Ok(None);
    };
    let list = match node {
        Yaml::Array(a) => a,
        Yaml::Hash(_) => node["data"]
            .as_vec()
            .ok_or_else(|| format!("{key} has no data list"))?,
        _ => return Err(format!("{key} is neither a matrix nor a list")),
    };
    let values = list
        .iter()
        .map(|v| number(v).ok_or_else(|| format!("{key}: {v:?} is not a number")))
        .collect::<Result<Vec<f64>, String>>()?;
    if let (Some(rows), Some(cols)) = (node["rows"].as_i64(), node["cols"].as_i64()) {
        if rows.checked_mul(cols) != Some(values.len() as i64) {
            return Err(format!("{key}: {rows}x{cols} but {} values", values.len()));
        }
    }
    Ok(Some(values))
}

fn number(v: &Yaml) -> Option<f64> {
    match v {
        Yaml::Integer(i) => Some(*i as f64),
        Yaml::Real(_) => v.as_f64(),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ROS: &str = "image_width: 640
image_height: 480
camera_name: kinect_rgb
camera_matrix:
  rows: 3
  cols: 3
  data: [520.9, 0, 325.1, 0, 521.0, 249.7, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [0.2312, -0.7849, -0.0033, -0.0001, 0.9172]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [520.9, 0, 325.1, 0, 0, 521.0, 249.7, 0, 0, 0, 1, 0]
";

    const OPENCV: &str = "%YAML:1.0
---
image_width: 640
image_height: 480
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 5.2090000000000000e+02, 0., 3.2510000000000002e+02, 0.,
       521., 2.4970000000000000e+02, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ 2.3119999999999999e-01, -7.8490000000000004e-01,
       -3.3000000000000000e-03, -1.0000000000000000e-04,
       9.1720000000000002e-01 ]
";

    fn tum() -> Calibration {
        Calibration {
            width: 640,
            height: 480,
            fx: 520.9,
            fy: 521.0,
            cx: 325.1,
            cy: 249.7,
            distortion: Distortion::RadialTangential {
                k1: 0.2312,
                k2: -0.7849,
                p1: -0.0033,
                p2: -0.0001,
                k3: 0.9172,
            },
        }
    }

    #[test]
    fn ros_camera_info_and_opencv_give_the_same_camera() {
        assert_eq!(Calibration::parse(ROS).unwrap(), tum());
        let cv = Calibration::parse(OPENCV).unwrap();
        assert_eq!((cv.width, cv.height), (640, 480));
        assert!((cv.fx - 520.9).abs() < 1e-12 && (cv.cy - 249.7).abs() < 1e-12);
        assert_eq!(cv.distortion.coefficients().len(), 5);
    }

    #[test]
    fn a_fisheye_camera_info_reads_its_four_coefficients() {
        let text = ROS.replace("plumb_bob", "equidistant").replace(
            "cols: 5\n  data: [0.2312, -0.7849, -0.0033, -0.0001, 0.9172]",
            "cols: 4\n  data: [-0.01, 0.02, -0.01, 0.004]",
        );
        let c = Calibration::parse(&text).unwrap();
        assert_eq!(
            c.distortion,
            Distortion::Equidistant {
                k: [-0.01, 0.02, -0.01, 0.004]
            }
        );
    }

    #[test]
    fn bad_calibrations_say_what_is_wrong() {
        let unknown = ROS.replace("plumb_bob", "rational_polynomial");
        assert!(Calibration::parse(&unknown)
            .unwrap_err()
            .contains("unknown distortion model"));
        let no_k = ROS.replace("camera_matrix", "camera_matrixx");
        assert!(Calibration::parse(&no_k).unwrap_err().contains("camera_matrix"));
        let short = ROS.replace(
            "data: [520.9, 0, 325.1, 0, 521.0, 249.7, 0, 0, 1]",
            "data: [520.9, 0, 325.1]",
        );
        assert!(Calibration::parse(&short)
            .unwrap_err()
            .contains("3x3 but 3 values"));
        let huge = ROS.replace("image_width: 640", "image_width: 6400000");
        assert!(Calibration::parse(&huge).unwrap_err().contains("image_width"));
        assert!(Calibration::parse("just: [text")
            .unwrap_err()
            .contains("not YAML"));
        assert!(Calibration::parse("- a\n- b\n")
            .unwrap_err()
            .contains("not a calibration"));
    }

    #[test]
    fn halving_the_image_halves_k_about_pixel_centres() {
        let half = tum().scaled_to(320, 240).unwrap();
        assert!((half.fx - 260.45).abs() < 1e-12 && (half.fy - 260.5).abs() < 1e-12);
        // A pixel centre at 325.1 covers [324.6, 325.6]: half of that.
        assert!((half.cx - 162.3).abs() < 1e-12 && (half.cy - 124.6).abs() < 1e-12);
        assert_eq!(half.distortion, tum().distortion);
        assert!(tum().scaled_to(320, 200).is_none());
    }
}
