//! The folder `pirouette map` writes: the ROS map, a picture, the poses.

use crate::dataset::{read_json, write_json};
use crate::{atomic_write, IoError};
use pirouette_geom::Pose2;
use pirouette_grid::RosMap;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// File names inside a map folder.
pub mod names {
    /// The occupancy grid, trinary P5 PGM.
    pub const PGM: &str = "map.pgm";
    /// The `map_server` YAML.
    pub const YAML: &str = "map.yaml";
    /// The picture for people.
    pub const PNG: &str = "map.png";
    /// The poses as JSON.
    pub const POSES_JSON: &str = "poses.json";
    /// The poses in TUM format.
    pub const POSES_TUM: &str = "poses.tum";
}

/// One pose of `poses.json`, in the map frame. Camera datasets name the
/// frame's `image`; laser logs give the `scan` (its position among the
/// log's laser lines) and its time `t`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseRecord {
    /// The frame's image path, as in the manifest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image: Option<String>,
    /// The scan's position among the log's laser lines (0-based).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scan: Option<usize>,
    /// The scan's timestamp, seconds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t: Option<f64>,
    /// Map-frame x, metres.
    pub x: f64,
    /// Map-frame y, metres.
    pub y: f64,
    /// Heading, degrees counter-clockwise.
    pub theta_deg: f64,
    /// Where the pose is not one trusted match: `"ambiguous"` (another
    /// pose apart explained the scan nearly as well) or `"unmatched"`
    /// (placed by the motion prior alone). Absent where trusted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trust: Option<String>,
}

impl PoseRecord {
    /// The record of a camera frame, to a micrometre and a microdegree
    /// (more digits are noise, and print as 0.30000000000000004).
    pub fn frame(image: &str, pose: &Pose2) -> Self {
        let micro = |v: f64| (v * 1e6).round() / 1e6;
        Self {
            image: Some(image.to_owned()),
            scan: None,
            t: None,
            x: micro(pose.x),
            y: micro(pose.y),
            theta_deg: micro(pose.theta_deg()),
            trust: None,
        }
    }

    /// The record of a laser scan (its position among the log's laser
    /// lines and its timestamp), to a micrometre and a microdegree.
    pub fn scan(scan: usize, t: f64, pose: &Pose2) -> Self {
        Self {
            image: None,
            scan: Some(scan),
            t: Some(t),
            ..Self::frame("", pose)
        }
    }

    /// The record, said not to be one trusted match (see
    /// [`PoseRecord::trust`]).
    pub fn with_trust(self, trust: Option<&str>) -> Self {
        Self {
            trust: trust.map(str::to_owned),
            ..self
        }
    }

    /// The pose.
    pub fn pose(&self) -> Pose2 {
        Pose2::from_deg(self.x, self.y, self.theta_deg)
    }
}

/// Writes the TUM trajectory (`t x y z qx qy qz qw` per line) to `w`: the
/// record's time, or its position in the list for camera frames (which
/// carry no time).
pub fn write_tum(w: &mut impl std::io::Write, records: &[PoseRecord]) -> std::io::Result<()> {
    writeln!(w, "# timestamp tx ty tz qx qy qz qw")?;
    for (k, r) in records.iter().enumerate() {
        let half = r.theta_deg.to_radians() / 2.0;
        writeln!(
            w,
            "{:.6} {:.6} {:.6} 0 0 0 {:.9} {:.9}",
            r.t.unwrap_or(k as f64),
            r.x,
            r.y,
            half.sin(),
            half.cos()
        )?;
    }
    Ok(())
}

/// Writes a map folder: `map.pgm`, `map.yaml`, `map.png` (given as PNG
/// bytes), `poses.json` and `poses.tum`, each replaced atomically.
pub fn write_map_dir(
    dir: &Path,
    map: &RosMap,
    picture_png: &[u8],
    poses: &[PoseRecord],
) -> Result<(), IoError> {
    write_poses(dir, poses)?;
    write_map_files(dir, map, picture_png)
}

/// Writes a map folder's `poses.json` and `poses.tum`, each replaced
/// atomically (the folder created if missing).
pub fn write_poses(dir: &Path, poses: &[PoseRecord]) -> Result<(), IoError> {
    std::fs::create_dir_all(dir).map_err(|e| IoError::io(dir, e))?;
    write_json(&dir.join(names::POSES_JSON), &poses)?;
    crate::atomic_write_with(&dir.join(names::POSES_TUM), |w| write_tum(w, poses))
}

/// Writes a map folder's `map.pgm`, `map.yaml` and `map.png` (given as
/// PNG bytes), each replaced atomically (the folder created if missing).
pub fn write_map_files(dir: &Path, map: &RosMap, picture_png: &[u8]) -> Result<(), IoError> {
    std::fs::create_dir_all(dir).map_err(|e| IoError::io(dir, e))?;
    atomic_write(&dir.join(names::PGM), &map.pgm())?;
    atomic_write(&dir.join(names::YAML), map.yaml(names::PGM).as_bytes())?;
    atomic_write(&dir.join(names::PNG), picture_png)
}

/// Reads the `map_server` YAML (flat `key: value` lines, `#` comments) and
/// the image it names (relative to the YAML's folder).
pub fn read_ros_map(yaml_path: &Path) -> Result<RosMap, IoError> {
    let text = std::fs::read_to_string(yaml_path).map_err(|e| IoError::io(yaml_path, e))?;
    let bad = |problem: String| IoError::invalid(yaml_path, problem);
    let mut image = None;
    let mut resolution = None;
    let mut origin = None;
    let mut negate = 0i64;
    let mut occupied_thresh = None;
    let mut free_thresh = None;
    for (n, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let (key, value) = line
            .split_once(':')
            .ok_or_else(|| bad(format!("line {}: expected `key: value`", n + 1)))?;
        let value = value.trim();
        let number = |v: &str| {
            v.trim()
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| bad(format!("line {}: `{}` is not a number", n + 1, v.trim())))
        };
        match key.trim() {
            "image" => image = Some(value.trim_matches(|c| c == '"' || c == '\'').to_owned()),
            "resolution" => resolution = Some(number(value)?),
            "origin" => {
                let inner = value
                    .strip_prefix('[')
                    .and_then(|v| v.strip_suffix(']'))
                    .ok_or_else(|| bad(format!("line {}: origin must be [x, y, yaw]", n + 1)))?;
                let v: Vec<f64> = inner.split(',').map(number).collect::<Result<_, _>>()?;
                if v.len() != 3 {
                    return Err(bad(format!("line {}: origin must be [x, y, yaw]", n + 1)));
                }
                if v[2] != 0.0 {
                    return Err(bad(format!("line {}: a rotated origin is not supported", n + 1)));
                }
                origin = Some([v[0], v[1]]);
            }
            "mode" if value.trim() != "trinary" => {
                return Err(bad(format!(
                    "line {}: mode `{}`: only trinary maps (0 occupied, 254 free, 205 unknown) are read",
                    n + 1,
                    value.trim()
                )))
            }
            "negate" => negate = number(value)? as i64,
            "occupied_thresh" => occupied_thresh = Some(number(value)?),
            "free_thresh" => free_thresh = Some(number(value)?),
            _ => {}
        }
    }
    let missing = |what: &str| bad(format!("no `{what}`"));
    let image = image.ok_or_else(|| missing("image"))?;
    let resolution_m = resolution.ok_or_else(|| missing("resolution"))?;
    if resolution_m <= 0.0 {
        return Err(bad(format!("resolution {resolution_m} must be positive")));
    }
    let origin_m = origin.ok_or_else(|| missing("origin"))?;
    let pgm_path = yaml_path.parent().unwrap_or(Path::new(".")).join(&image);
    let bytes = std::fs::read(&pgm_path).map_err(|e| IoError::io(&pgm_path, e))?;
    let grey = image::load_from_memory(&bytes)
        .map_err(|e| IoError::Image {
            path: pgm_path.clone(),
            source: e,
        })?
        .into_luma8();
    let (width, height) = (grey.width() as usize, grey.height() as usize);
    let mut pixels = grey.into_raw();
    if negate != 0 {
        pixels.iter_mut().for_each(|p| *p = 255 - *p);
    }
    Ok(RosMap {
        width,
        height,
        pixels,
        resolution_m,
        origin_m,
        occupied_thresh: occupied_thresh.unwrap_or(pirouette_grid::OCCUPIED_THRESH),
        free_thresh: free_thresh.unwrap_or(pirouette_grid::FREE_THRESH),
    })
}

/// Reads `poses.json` of a map folder, checking every value is finite.
pub fn read_poses(path: &Path) -> Result<Vec<PoseRecord>, IoError> {
    let records: Vec<PoseRecord> = read_json(path)?;
    for (k, r) in records.iter().enumerate() {
        if !(r.x.is_finite() && r.y.is_finite() && r.theta_deg.is_finite()) {
            return Err(IoError::invalid(path, format!("pose {k} is not finite")));
        }
    }
    Ok(records)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small_map() -> RosMap {
        RosMap {
            width: 3,
            height: 2,
            pixels: vec![0, 254, 205, 205, 254, 0],
            resolution_m: 0.05,
            origin_m: [-1.0, 0.5],
            occupied_thresh: 0.65,
            free_thresh: 0.196,
        }
    }

    #[test]
    fn a_written_map_folder_reads_back() {
        let dir = tempfile::tempdir().unwrap();
        let poses = vec![
            PoseRecord::frame("frames/s00/000.png", &Pose2::IDENTITY),
            PoseRecord::frame("frames/s00/001.png", &Pose2::from_deg(0.1, -0.2, 30.0)),
        ];
        write_map_dir(dir.path(), &small_map(), b"png", &poses).unwrap();
        assert_eq!(read_ros_map(&dir.path().join(names::YAML)).unwrap(), small_map());
        assert_eq!(read_poses(&dir.path().join(names::POSES_JSON)).unwrap(), poses);
        let tum = std::fs::read_to_string(dir.path().join(names::POSES_TUM)).unwrap();
        let line: Vec<f64> = tum
            .lines()
            .nth(2)
            .unwrap()
            .split(' ')
            .map(|v| v.parse().unwrap())
            .collect();
        // 30° about z: qz = sin 15°, qw = cos 15°.
        assert_eq!(line.len(), 8);
        assert_eq!(&line[..3], &[1.0, 0.1, -0.2]);
        assert!((line[6] - 15f64.to_radians().sin()).abs() < 1e-9);
        assert!((line[7] - 15f64.to_radians().cos()).abs() < 1e-9);
        // Rewriting replaces and leaves no temporary files.
        write_map_dir(dir.path(), &small_map(), b"png", &poses[..1]).unwrap();
        assert_eq!(read_poses(&dir.path().join(names::POSES_JSON)).unwrap().len(), 1);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 5);
    }

    #[test]
    fn bad_map_files_name_the_file_and_the_problem() {
        let dir = tempfile::tempdir().unwrap();
        let yaml = dir.path().join("map.yaml");
        let cases = [
            ("resolution: 0.05\norigin: [0, 0, 0]\n", "no `image`"),
            (
                "image: map.pgm\nresolution: fine\norigin: [0, 0, 0]\n",
                "is not a number",
            ),
            (
                "image: map.pgm\nresolution: 0.05\norigin: [0, 0]\n",
                "origin must be",
            ),
            ("image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n", "map.pgm"),
            (
                "image: map.pgm\nmode: scale\nresolution: 0.05\norigin: [0, 0, 0]\n",
                "only trinary maps",
            ),
        ];
        for (text, expected) in cases {
            std::fs::write(&yaml, text).unwrap();
            let err = read_ros_map(&yaml).unwrap_err().to_string();
            assert!(err.contains(expected), "{err}");
        }
        let poses = dir.path().join("poses.json");
        std::fs::write(&poses, "[{\"image\": \"a.png\", \"x\": 0.0}]").unwrap();
        let err = read_poses(&poses).unwrap_err().to_string();
        assert!(
            err.contains("poses.json") && err.contains("missing field `y`"),
            "{err}"
        );
    }
}
