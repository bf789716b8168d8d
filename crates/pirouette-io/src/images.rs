//! Image folders: a real camera's frames as a user records them, read as
//! a dataset.
//!
//! A folder is described by a rig file (`rig.json`, format
//! `pirouette-images/1`): the calibration file (ROS `camera_info` or
//! OpenCV YAML), where the camera stands on the robot, the soft range
//! limit, a TUM-style stamps file (`stamp path` per line), and optionally
//! an odometry file and a ground-truth file in TUM format. Frames are
//! chosen from the stream (a turn of at least `min_turn_deg` or a move of
//! at least `min_move_m` by odometry since the last chosen frame, or every
//! `every`-th frame without odometry), and each chosen frame's motion is
//! the odometry's relative pose since the previous one (a general move),
//! or unknown (`null`) without odometry. See `docs/image-folders.md`.

use crate::dataset::{CameraSpec, FrameSpec, LensSpec, Manifest, MountSpec, PinholeSpec, PoseSpec};
use crate::relations::{quaternion, rows};
use crate::{IoError, Motion};
use pirouette_camera::{Calibration, CalibrationError};
use pirouette_geom::Pose2;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The rig file's format version.
pub const RIG_FORMAT: &str = "pirouette-images/1";

/// The rig file's usual name in an image folder.
pub const RIG_FILE: &str = "rig.json";

/// A rig file: what turns a folder of images into a dataset. Paths are
/// relative to the rig file's folder (or absolute).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rig {
    /// Always [`RIG_FORMAT`].
    pub format: String,
    /// A name for reports; the folder's name when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The calibration file: ROS `camera_info` or OpenCV YAML, at the
    /// images' size.
    pub calibration: String,
    /// Height of the optical centre above the floor, metres.
    pub height: f64,
    /// Downward tilt of the optical axis from horizontal, degrees.
    pub tilt_deg: f64,
    /// The camera's offset from the robot's turning centre.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mount: Option<MountSpec>,
    /// The soft range limit, metres.
    pub max_range: f64,
    /// The stamps file: `stamp path` per line (TUM's `rgb.txt`). Either
    /// this or `bag`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stamps: Option<String>,
    /// A ROS 1 bag, a ROS 2 bag folder or its storage file, whose
    /// `sensor_msgs/Image` or `CompressedImage` topic gives the frames
    /// (and `nav_msgs/Odometry`, where it has one and `odometry` is not
    /// given, the motion). Either this or `stamps`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bag: Option<String>,
    /// The bag's image topic, where it has several.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_topic: Option<String>,
    /// The bag's odometry topic, where it has several.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub odom_topic: Option<String>,
    /// The folder the stamps' image paths are relative to; the stamps
    /// file's own folder when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub images: Option<String>,
    /// The robot's odometry, TUM format (`t x y z qx qy qz qw`, the base's
    /// pose in the odometry frame).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub odometry: Option<String>,
    /// Ground truth for evaluation, TUM format.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truth: Option<String>,
    /// What the truth file's poses are of.
    #[serde(default)]
    pub truth_frame: TruthFrame,
    /// Whether the truth keeps the stamps' clock, or its clock against
    /// the frames' must be found from the images (stamps made up, or of
    /// another clock).
    #[serde(default)]
    pub truth_clock: TruthClock,
    /// How frames are chosen from the stream.
    #[serde(default)]
    pub select: Selection,
}

/// The frame a ground-truth file's poses belong to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TruthFrame {
    /// The robot's base (x forward, z up): its yaw is the heading.
    #[default]
    Base,
    /// The camera's optical frame (z forward, x right, y down), as motion
    /// capture of a camera gives it: the heading is the optical axis's
    /// direction on the floor, the robot centre lies the mount's offset
    /// behind the camera.
    CameraOptical,
}

/// The truth file's clock against the frames' stamps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TruthClock {
    /// The stamps and the truth share one clock: a frame's truth is the
    /// truth at its stamp.
    #[default]
    Stamps,
    /// Their offset and rate are unknown: the frames carry no truth, and
    /// evaluation finds the clock by matching the images' turning to the
    /// truth's ([`TruthTrack`]).
    FromImages,
}

/// A truth to be put on the frames' clock: the truth's planar poses, and
/// every frame of the stream (the chosen ones and the others between,
/// whose images tell the turning).
#[derive(Debug, Clone, PartialEq)]
pub struct TruthTrack {
    /// The truth's planar poses by its own time, seconds.
    pub poses: Vec<(f64, Pose2)>,
    /// Every frame of the stream: its stamp and image file.
    pub frames: Vec<(f64, PathBuf)>,
    /// The chosen frames' places in `frames`, in the dataset's order.
    pub chosen: Vec<usize>,
}

impl TruthTrack {
    /// The truth's pose at its time `t`, between the poses about it;
    /// `None` outside their span.
    pub fn at(&self, t: f64) -> Option<Pose2> {
        planar_at(&self.poses, t)
    }
}

/// How frames are chosen from the stream.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Selection {
    /// With odometry: the least turn since the last chosen frame, degrees.
    pub min_turn_deg: f64,
    /// With odometry: the least move since the last chosen frame, metres.
    pub min_move_m: f64,
    /// Without odometry: every `every`-th frame is chosen.
    pub every: usize,
}

impl Default for Selection {
    /// A frame after every 10° of turn or 10 cm of move (a third of a
    /// 60° camera's view changes, so consecutive frames still overlap
    /// well); every frame without odometry.
    fn default() -> Self {
        Self {
            min_turn_deg: 10.0,
            min_move_m: 0.10,
            every: 1,
        }
    }
}

/// One line of a stamps file.
#[derive(Debug, Clone, PartialEq)]
pub struct Stamped {
    /// Time, seconds.
    pub t: f64,
    /// The image path as written.
    pub path: String,
}

/// The most lines a stamps file may have.
pub const MAX_STAMPS: usize = 1_000_000;

/// Reads a TUM-style stamps file (`stamp path` per line, `#` comments),
/// refusing stamps out of time order.
pub fn read_stamps(path: &Path) -> Result<Vec<Stamped>, IoError> {
    let text = std::fs::read(path).map_err(|e| IoError::io(path, e))?;
    let text = std::str::from_utf8(&text).map_err(|_| IoError::invalid(path, "not text (invalid UTF-8)"))?;
    let mut out: Vec<Stamped> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let bad = |problem: String| IoError::Line {
            path: path.to_owned(),
            line: i + 1,
            problem,
        };
        if out.len() >= MAX_STAMPS {
            return Err(IoError::invalid(path, format!("more than {MAX_STAMPS} stamps")));
        }
        let mut fields = line.split_ascii_whitespace();
        let (Some(t), Some(image)) = (fields.next(), fields.next()) else {
            return Err(bad("a stamps line is `stamp path`".into()));
        };
        let t: f64 = match t.parse() {
            Ok(t) if f64::is_finite(t) => t,
            _ => return Err(bad(format!("`{t}` is not a time in seconds"))),
        };
        if let Some(last) = out.last() {
            if t <= last.t {
                return Err(bad(format!("frames out of time order: {t} s after {} s", last.t)));
            }
        }
        out.push(Stamped {
            t,
            path: image.to_string(),
        });
    }
    if out.is_empty() {
        return Err(IoError::invalid(path, "no stamps"));
    }
    Ok(out)
}

/// A stamped 3D pose of a TUM file: position and rotation matrix.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pose3 {
    t: f64,
    p: [f64; 3],
    r: [[f64; 3]; 3],
}

/// Reads a TUM trajectory as 3D poses, in time order.
fn read_tum3(path: &Path) -> Result<Vec<Pose3>, IoError> {
    let mut out: Vec<Pose3> = Vec::new();
    for (line, v) in rows(path, 8, "TUM")? {
        let [x, y, z, w] = quaternion(path, line, &v)?;
        let n = (x * x + y * y + z * z + w * w).sqrt();
        let (x, y, z, w) = (x / n, y / n, z / n, w / n);
        let r = [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - z * w),
                2.0 * (x * z + y * w),
            ],
            [
                2.0 * (x * y + z * w),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - x * w),
            ],
            [
                2.0 * (x * z - y * w),
                2.0 * (y * z + x * w),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ];
        // Recorders round stamps (motion capture at 100 Hz to 0.1 ms): a
        // pose at the very time of the one before adds nothing.
        if out.last().is_some_and(|p| v[0] == p.t) {
            continue;
        }
        if out.last().is_some_and(|p| v[0] < p.t) {
            return Err(IoError::Line {
                path: path.to_owned(),
                line,
                problem: format!("poses out of time order at {} s", v[0]),
            });
        }
        out.push(Pose3 {
            t: v[0],
            p: [v[1], v[2], v[3]],
            r,
        });
    }
    if out.len() < 2 {
        return Err(IoError::invalid(path, "fewer than two poses"));
    }
    Ok(out)
}

impl Pose3 {
    /// The planar pose of the robot: for a base frame its yaw and
    /// position, for a camera's optical frame the optical axis's heading
    /// on the floor and the turning centre `mount` behind the camera.
    fn planar(&self, frame: TruthFrame, mount: MountSpec) -> Pose2 {
        match frame {
            TruthFrame::Base => Pose2::new(self.p[0], self.p[1], self.r[1][0].atan2(self.r[0][0])),
            TruthFrame::CameraOptical => {
                // The optical axis is the rotation's third column.
                let heading = self.r[1][2].atan2(self.r[0][2]);
                let world_from_camera = Pose2::new(self.p[0], self.p[1], heading);
                world_from_camera * Pose2::new(-mount.forward, -mount.left, 0.0)
            }
        }
    }
}

/// The planar pose at time `t`, linearly between the two poses about it
/// (the heading along the shorter way); `None` outside the poses' span.
fn planar_at(poses: &[(f64, Pose2)], t: f64) -> Option<Pose2> {
    let k = poses.partition_point(|(s, _)| *s <= t);
    if k == 0 || (k == poses.len() && poses[k - 1].0 < t) {
        return None;
    }
    if k == poses.len() {
        return Some(poses[k - 1].1);
    }
    let ((t0, a), (t1, b)) = (poses[k - 1], poses[k]);
    let f = (t - t0) / (t1 - t0);
    let dtheta = pirouette_geom::wrap_angle(b.theta - a.theta);
    Some(Pose2::new(
        a.x + f * (b.x - a.x),
        a.y + f * (b.y - a.y),
        pirouette_geom::wrap_angle(a.theta + f * dtheta),
    ))
}

/// An image folder read through its rig: the manifest of the chosen
/// frames, the folder their paths are relative to, and every frame's stamp.
#[derive(Debug, Clone)]
pub struct ImageFolder {
    /// The rig file.
    pub rig_path: PathBuf,
    /// The rig.
    pub rig: Rig,
    /// The folder the manifest's image paths are relative to.
    pub root: PathBuf,
    /// The chosen frames as a dataset manifest.
    pub manifest: Manifest,
    /// The stamp of each chosen frame, seconds.
    pub stamps: Vec<f64>,
    /// The chosen frames' images, where they come from a bag (the
    /// manifest's image paths are then labels).
    pub bag_frames: Option<crate::bag::camera::BagFrames>,
    /// Damage read past in a bag (cut short, chunks skipped).
    pub warnings: Vec<String>,
    /// The truth, where its clock is to be found from the images
    /// ([`TruthClock::FromImages`]); the frames then carry none.
    pub truth_track: Option<TruthTrack>,
}

fn relative_to(base: &Path, p: &str) -> PathBuf {
    let p = Path::new(p);
    if p.is_absolute() {
        p.to_owned()
    } else {
        base.join(p)
    }
}

/// Where the frames come from.
enum Source {
    Files(FileSource),
    Bag(crate::bag::camera::CameraBag),
}

/// A stamps file and the folder its paths are relative to.
struct FileSource {
    stamped: Vec<Stamped>,
    root: PathBuf,
}

impl FileSource {
    /// Reads the stamps file `stamps` (relative to `dir`) and checks that
    /// every image it names is there: a stamps file that names a missing
    /// image is broken, whichever frames are chosen.
    fn read(dir: &Path, stamps: &str, images: Option<&str>) -> Result<Self, IoError> {
        let stamps_path = relative_to(dir, stamps);
        let stamped = read_stamps(&stamps_path)?;
        let root = match images {
            Some(p) => relative_to(dir, p),
            None => stamps_path.parent().unwrap_or(Path::new(".")).to_owned(),
        };
        for (k, s) in stamped.iter().enumerate() {
            if !root.join(&s.path).is_file() {
                return Err(IoError::invalid(
                    &stamps_path,
                    format!(
                        "stamp {} (line {} of the stamps) names {}, which does not exist",
                        s.t,
                        k + 1,
                        root.join(&s.path).display()
                    ),
                ));
            }
        }
        Ok(Self { stamped, root })
    }
}

/// Refuses images (the first is `first`, `w` × `h`) of another size than
/// the calibration's.
fn check_size(calib_path: &Path, calib: &Calibration, first: &Path, w: u32, h: u32) -> Result<(), IoError> {
    if (w, h) != (calib.width, calib.height) {
        return Err(IoError::invalid(
            calib_path,
            format!(
                "the calibration is for {}x{} images, but {} is {w}x{h} (calibrate at the images' size, or scale K with them)",
                calib.width,
                calib.height,
                first.display()
            ),
        ));
    }
    Ok(())
}

/// The ground-truth poses of a rig, planar, with their stamps.
pub fn read_truth(rig_path: &Path, rig: &Rig) -> Result<Option<Vec<(f64, Pose2)>>, IoError> {
    let dir = rig_path.parent().unwrap_or(Path::new("."));
    let mount = rig.mount.unwrap_or_default();
    rig.truth
        .as_ref()
        .map(|t| {
            Ok(read_tum3(&relative_to(dir, t))?
                .iter()
                .map(|p| (p.t, p.planar(rig.truth_frame, mount)))
                .collect())
        })
        .transpose()
}

impl ImageFolder {
    /// Reads the rig at `rig_path` and the files it names, choosing the
    /// frames. Every problem is an error naming its file.
    pub fn open(rig_path: &Path) -> Result<Self, IoError> {
        let raw: serde_json::Value = crate::dataset::read_json(rig_path)?;
        match raw.get("format").and_then(|f| f.as_str()) {
            Some(RIG_FORMAT) => {}
            Some(other) => {
                return Err(IoError::UnknownFormat {
                    path: rig_path.to_owned(),
                    found: other.to_string(),
                })
            }
            None => return Err(IoError::invalid(rig_path, "missing field `format`")),
        }
        let rig: Rig = serde_json::from_value(raw).map_err(|e| IoError::Json {
            path: rig_path.to_owned(),
            source: e,
        })?;
        let dir = rig_path.parent().unwrap_or(Path::new(".")).to_owned();
        let calib_path = relative_to(&dir, &rig.calibration);
        let calib = Calibration::read(&calib_path).map_err(|e| match e {
            CalibrationError::Io { path, source } => IoError::Io { path, source },
            CalibrationError::Invalid { path, problem } => IoError::Invalid { path, problem },
        })?;
        if !(rig.select.min_turn_deg >= 0.0 && rig.select.min_move_m >= 0.0 && rig.select.every >= 1) {
            return Err(IoError::invalid(
                rig_path,
                "select: min_turn_deg and min_move_m must be 0 or more, every at least 1",
            ));
        }
        let mount = rig.mount.unwrap_or_default();
        let source = match (&rig.stamps, &rig.bag) {
            (Some(stamps), None) => Source::Files(FileSource::read(&dir, stamps, rig.images.as_deref())?),
            (None, Some(bag)) => {
                if rig.images.is_some() {
                    return Err(IoError::invalid(
                        rig_path,
                        "`images` is for a stamps file, not a bag",
                    ));
                }
                Source::Bag(crate::bag::camera::CameraBag::scan(
                    &relative_to(&dir, bag),
                    rig.image_topic.as_deref(),
                    rig.odom_topic.as_deref(),
                )?)
            }
            _ => {
                return Err(IoError::invalid(
                    rig_path,
                    "give the frames either as `stamps` (a stamps file) or as `bag`, one of the two",
                ))
            }
        };
        if let Source::Files(f) = &source {
            // The images must be of the calibration's size (read from the
            // first image's header).
            let first = f.root.join(&f.stamped[0].path);
            let (w, h) = image::image_dimensions(&first).map_err(|e| IoError::Image {
                path: first.clone(),
                source: e,
            })?;
            check_size(&calib_path, &calib, &first, w, h)?;
        }
        let stamped: Vec<Stamped> = match &source {
            Source::Files(f) => f.stamped.clone(),
            Source::Bag(b) => (b.stamps.iter())
                .map(|&t| Stamped {
                    t,
                    // A label, not a file: the topic and the stamp in
                    // whole nanoseconds (no dot, so that no extension is
                    // taken off it).
                    path: format!("{}@{}", b.topic, (t * 1e9).round() as i64),
                })
                .collect(),
        };
        let odometry: Option<Vec<(f64, Pose2)>> = rig
            .odometry
            .as_ref()
            .map(|o| -> Result<_, IoError> {
                Ok(read_tum3(&relative_to(&dir, o))?
                    .iter()
                    .map(|p| (p.t, p.planar(TruthFrame::Base, mount)))
                    .collect())
            })
            .transpose()?
            .or_else(|| match &source {
                Source::Bag(b) if !b.odometry.is_empty() => Some(b.odometry.clone()),
                _ => None,
            });
        let truth = read_truth(rig_path, &rig)?;
        let clock_from_images = rig.truth_clock == TruthClock::FromImages;
        if clock_from_images && truth.is_none() {
            return Err(IoError::invalid(
                rig_path,
                "`truth_clock: from_images` needs a `truth` file",
            ));
        }
        if clock_from_images && !matches!(source, Source::Files(_)) {
            return Err(IoError::invalid(
                rig_path,
                "`truth_clock: from_images` reads every frame's image: give the frames as a stamps file",
            ));
        }
        // The chosen frames and their motions.
        let mut chosen: Vec<(usize, Option<Motion>)> = Vec::new();
        match &odometry {
            Some(odo) => {
                let mut last: Option<Pose2> = None;
                for (k, s) in stamped.iter().enumerate() {
                    let Some(pose) = planar_at(odo, s.t) else { continue };
                    match last {
                        None => {
                            chosen.push((k, None));
                            last = Some(pose);
                        }
                        Some(prev) => {
                            let rel = prev.inverse() * pose;
                            let turned = rel.theta.abs().to_degrees() >= rig.select.min_turn_deg;
                            let moved = rel.x.hypot(rel.y) >= rig.select.min_move_m;
                            if turned || moved {
                                chosen.push((k, Some(Motion::from_relative(&rel))));
                                last = Some(pose);
                            }
                        }
                    }
                }
                if chosen.is_empty() {
                    return Err(IoError::invalid(
                        rig_path,
                        "no image stamp lies within the odometry's time span",
                    ));
                }
            }
            None => chosen.extend((0..stamped.len()).step_by(rig.select.every).map(|k| (k, None))),
        }
        let pinhole = calib.pinhole(rig.height, rig.tilt_deg.to_radians(), mount.forward, mount.left);
        // The paper's measurements of this camera (the format always
        // carries them); a camera whose centre row sees no floor has none.
        let ipm = pinhole.ipm_measurements().ok_or_else(|| {
            IoError::invalid(
                rig_path,
                format!(
                    "a camera {} m high tilted {}° down does not see the floor at its centre row: is tilt_deg downward and in degrees?",
                    rig.height, rig.tilt_deg
                ),
            )
        })?;
        let frames = chosen
            .iter()
            .enumerate()
            .scan(0u32, |sweep, (n, &(k, motion))| {
                // A turn in place keeps the sweep; any other move (or an
                // unknown one) starts the next.
                if n > 0 && !motion.is_some_and(|m| m.is_in_place_turn()) {
                    *sweep += 1;
                }
                Some((*sweep, k, motion))
            })
            .map(|(sweep, k, motion)| FrameSpec {
                image: stamped[k].path.clone(),
                sweep,
                motion,
                truth: (truth.as_ref())
                    .filter(|_| !clock_from_images)
                    .and_then(|t| planar_at(t, stamped[k].t))
                    .map(PoseSpec::from),
            })
            .collect();
        let name = rig.name.clone().unwrap_or_else(|| {
            std::fs::canonicalize(&dir)
                .ok()
                .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
                .unwrap_or_else(|| "images".into())
        });
        let manifest = Manifest {
            format: crate::FORMAT_VERSION.into(),
            name,
            camera: CameraSpec {
                width: calib.width,
                height: calib.height,
                ipm,
                pinhole: Some(PinholeSpec {
                    fx: calib.fx,
                    fy: calib.fy,
                    cx: calib.cx,
                    cy: calib.cy,
                    height: rig.height,
                    tilt_deg: rig.tilt_deg,
                    distortion: LensSpec::of(&calib.distortion),
                }),
                mount: rig.mount,
            },
            max_range: rig.max_range,
            frames,
        };
        let stamps = chosen.iter().map(|&(k, _)| stamped[k].t).collect();
        let truth_track = match (&source, truth) {
            (Source::Files(f), Some(poses)) if clock_from_images => Some(TruthTrack {
                poses,
                frames: (stamped.iter()).map(|s| (s.t, f.root.join(&s.path))).collect(),
                chosen: chosen.iter().map(|&(k, _)| k).collect(),
            }),
            _ => None,
        };
        let (root, bag_frames, warnings) = match source {
            Source::Files(f) => (f.root, None, Vec::new()),
            Source::Bag(b) => {
                let positions: Vec<usize> = chosen.iter().map(|&(k, _)| k).collect();
                let frames = b.frames(&positions)?;
                let first = frames.decode(0)?;
                let label = PathBuf::from(format!("{} (topic {})", b.path.display(), b.topic));
                check_size(&calib_path, &calib, &label, first.width(), first.height())?;
                let root = b.path.parent().unwrap_or(Path::new(".")).to_owned();
                (root, Some(frames), b.warnings)
            }
        };
        Ok(Self {
            rig_path: rig_path.to_owned(),
            rig,
            root,
            manifest,
            stamps,
            bag_frames,
            warnings,
            truth_track,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Dataset;

    const CALIBRATION: &str = "image_width: 32
image_height: 24
camera_matrix:
  rows: 3
  cols: 3
  data: [27.7, 0, 15.5, 0, 27.7, 11.5, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.1, 0.01, 0.0, 0.0, 0.0]
";

    /// An image folder of `n` frames 0.1 s apart, with a rig naming the
    /// calibration and stamps, and odometry of a robot turning 4° and
    /// driving 3 cm every 0.1 s when `odometry` is set.
    fn folder(n: usize, odometry: bool) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path();
        std::fs::create_dir(p.join("rgb")).unwrap();
        let mut stamps = String::from("# timestamp filename\n");
        for k in 0..n {
            let img = image::RgbImage::from_pixel(32, 24, image::Rgb([90, 80, 70]));
            img.save(p.join(format!("rgb/{k:03}.png"))).unwrap();
            stamps += &format!("{:.3} rgb/{k:03}.png\n", 100.0 + 0.1 * k as f64);
        }
        std::fs::write(p.join("rgb.txt"), stamps).unwrap();
        std::fs::write(p.join("camera_info.yaml"), CALIBRATION).unwrap();
        let mut odo = String::new();
        let (mut x, mut y, mut th) = (0.0f64, 0.0f64, 0.0f64);
        for k in 0..=(10 * n) {
            let t = 100.0 + 0.01 * k as f64;
            odo += &format!("{t:.3} {x} {y} 0 0 0 {} {}\n", (th / 2.0).sin(), (th / 2.0).cos());
            x += 0.003 * th.cos();
            y += 0.003 * th.sin();
            th += 0.4f64.to_radians();
        }
        std::fs::write(p.join("odometry.txt"), odo).unwrap();
        let rig = format!(
            r#"{{ "format": "pirouette-images/1", "calibration": "camera_info.yaml", "height": 0.3,
                 "tilt_deg": 20.0, "max_range": 2.0, "stamps": "rgb.txt"{} }}"#,
            if odometry {
                r#", "odometry": "odometry.txt", "select": { "min_turn_deg": 10.0, "min_move_m": 1.0 }"#
            } else {
                ""
            }
        );
        std::fs::write(p.join("rig.json"), rig).unwrap();
        dir
    }

    #[test]
    fn a_folder_without_odometry_takes_every_frame_with_unknown_motion() {
        let dir = folder(6, false);
        let ds = Dataset::open(dir.path()).unwrap();
        assert_eq!(ds.manifest.frames.len(), 6);
        assert!(ds.manifest.frames.iter().all(|f| f.motion.is_none()));
        assert_eq!(ds.stamps[5], 100.5);
        assert_eq!(ds.manifest_path(), dir.path().join("rig.json"));
        let lens = ds
            .manifest
            .camera
            .pinhole
            .as_ref()
            .unwrap()
            .distortion
            .clone()
            .unwrap();
        assert_eq!((lens.model.as_str(), lens.d[0]), ("plumb_bob", -0.1));
        assert_eq!(ds.load_image(3).unwrap().dimensions(), (32, 24));
    }

    #[test]
    fn odometry_chooses_a_frame_every_ten_degrees_with_its_move() {
        let dir = folder(12, true);
        let ds = Dataset::open(&dir.path().join("rig.json")).unwrap();
        // 4° a frame: frames 0, 3, 6, 9 (12° each), every one a new sweep.
        let images: Vec<&str> = ds.manifest.frames.iter().map(|f| f.image.as_str()).collect();
        assert_eq!(
            images,
            ["rgb/000.png", "rgb/003.png", "rgb/006.png", "rgb/009.png"]
        );
        assert_eq!(
            ds.manifest.frames.iter().map(|f| f.sweep).collect::<Vec<_>>(),
            [0, 1, 2, 3]
        );
        // The move from frame 3 to 6: 30 steps of 3 mm, each turned 0.4°
        // further, expressed in frame 3's pose.
        let Some(Motion::Move { relative }) = ds.manifest.frames[2].motion else {
            panic!("a general move")
        };
        let (mut x, mut y, mut th) = (0.0f64, 0.0f64, 0.0f64);
        for _ in 0..30 {
            x += 0.003 * th.cos();
            y += 0.003 * th.sin();
            th += 0.4f64.to_radians();
        }
        assert!((relative.turn_deg - 12.0).abs() < 1e-9, "{relative:?}");
        assert!(
            (relative.forward - x).abs() < 1e-9 && (relative.left - y).abs() < 1e-9,
            "{relative:?} vs {x} {y}"
        );
    }

    #[test]
    fn broken_folders_are_refused_naming_the_file_and_problem() {
        let dir = folder(4, false);
        let p = dir.path();
        let err = |what: &str| Dataset::open(p).unwrap_err().to_string() + " <" + what + ">";
        // A stamps file naming a missing image.
        std::fs::remove_file(p.join("rgb/002.png")).unwrap();
        let e = err("missing");
        assert!(
            e.contains("rgb.txt") && e.contains("002.png") && e.contains("does not exist"),
            "{e}"
        );
        std::fs::copy(p.join("rgb/001.png"), p.join("rgb/002.png")).unwrap();
        // Frames out of time order.
        std::fs::write(p.join("rgb.txt"), "1.0 rgb/000.png\n0.5 rgb/001.png\n").unwrap();
        let e = err("order");
        assert!(e.contains("rgb.txt:2") && e.contains("out of time order"), "{e}");
        std::fs::write(p.join("rgb.txt"), "1.0 rgb/000.png\n").unwrap();
        // A calibration of another size than the images.
        std::fs::write(
            p.join("camera_info.yaml"),
            CALIBRATION.replace("image_width: 32", "image_width: 64"),
        )
        .unwrap();
        let e = err("size");
        assert!(
            e.contains("camera_info.yaml") && e.contains("64x24") && e.contains("32x24"),
            "{e}"
        );
        // An unknown distortion model.
        std::fs::write(
            p.join("camera_info.yaml"),
            CALIBRATION.replace("plumb_bob", "rational_polynomial"),
        )
        .unwrap();
        let e = err("model");
        assert!(
            e.contains("camera_info.yaml") && e.contains("unknown distortion model"),
            "{e}"
        );
        std::fs::write(p.join("camera_info.yaml"), CALIBRATION).unwrap();
        assert!(Dataset::open(p).is_ok());
        // A rig of another format, or with a field it does not know.
        let rig = std::fs::read_to_string(p.join("rig.json")).unwrap();
        std::fs::write(
            p.join("rig.json"),
            rig.replace("pirouette-images/1", "pirouette-images/9"),
        )
        .unwrap();
        assert!(err("format").contains("pirouette-images/9"));
        std::fs::write(p.join("rig.json"), rig.replace("\"height\"", "\"hieght\"")).unwrap();
        assert!(err("field").contains("hieght"));
    }

    #[test]
    fn camera_mocap_becomes_the_robot_pose_behind_the_camera() {
        // A camera whose optical axis (z) points along world +y, x right
        // (world +x... turned: right is -x), y down: its heading is 90°.
        let r = [[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]];
        let cam = Pose3 {
            t: 0.0,
            p: [1.0, 2.0, 0.5],
            r,
        };
        let robot = cam.planar(
            TruthFrame::CameraOptical,
            MountSpec {
                forward: 0.1,
                left: 0.0,
            },
        );
        assert!((robot.theta - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!(
            (robot.x - 1.0).abs() < 1e-12 && (robot.y - 1.9).abs() < 1e-12,
            "{robot:?}"
        );
    }
}
