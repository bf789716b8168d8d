//! The `rop-dataset/1` camera dataset format.

use crate::{atomic_write, atomic_write_with, IoError, World};
use pirouette_camera::{Camera, Distortion, IpmMeasurements, IpmModel, ModelKind, PinholeModel};
use pirouette_geom::Pose2;
use pirouette_profile::Rop;
use serde::{Deserialize, Serialize};
use std::path::{Component, Path, PathBuf};

/// The format version this crate reads and writes.
pub const FORMAT_VERSION: &str = "rop-dataset/1";

/// The manifest, `dataset.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Always [`FORMAT_VERSION`].
    pub format: String,
    /// The dataset's name.
    pub name: String,
    /// The camera.
    pub camera: CameraSpec,
    /// The soft range limit, metres.
    pub max_range: f64,
    /// Frames in capture order.
    pub frames: Vec<FrameSpec>,
}

/// The camera of a dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraSpec {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// The paper's four tape measurements (always present).
    pub ipm: IpmMeasurements,
    /// The exact pinhole model, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pinhole: Option<PinholeSpec>,
    /// Camera offset from the rotation centre; zero when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mount: Option<MountSpec>,
}

/// Pinhole intrinsics and pose, as stored in the manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PinholeSpec {
    /// Focal length along `u`, pixels.
    pub fx: f64,
    /// Focal length along `v`, pixels.
    pub fy: f64,
    /// Principal point column, pixels.
    pub cx: f64,
    /// Principal point row, pixels.
    pub cy: f64,
    /// Camera height, metres.
    pub height: f64,
    /// Downward tilt of the optical axis, degrees.
    pub tilt_deg: f64,
    /// The lens distortion, as ROS `camera_info` names it; none when
    /// absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distortion: Option<LensSpec>,
}

/// A lens model as stored in the manifest: ROS `camera_info`'s
/// `distortion_model` and `D`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LensSpec {
    /// `plumb_bob` (radial-tangential: `k1 k2 p1 p2 k3`) or `equidistant`
    /// (fisheye: `k1 k2 k3 k4`).
    pub model: String,
    /// The coefficients in ROS order.
    pub d: Vec<f64>,
}

impl LensSpec {
    /// The lens model, or what is wrong with it.
    pub fn distortion(&self) -> Result<Distortion, String> {
        Distortion::from_named(&self.model, &self.d)
    }

    /// The spec of a lens model; `None` for the ideal pinhole.
    pub fn of(d: &Distortion) -> Option<Self> {
        (!d.is_none()).then(|| Self {
            model: d.ros_name().to_string(),
            d: d.coefficients(),
        })
    }
}

/// Camera offset from the rotation centre, robot frame, metres.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct MountSpec {
    /// Ahead of the centre.
    #[serde(default)]
    pub forward: f64,
    /// To the left of the centre.
    #[serde(default)]
    pub left: f64,
}

/// One frame of the manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameSpec {
    /// Image path relative to the dataset folder.
    pub image: String,
    /// The sweep this frame belongs to.
    pub sweep: u32,
    /// Commanded motion since the previous frame; `None` for the first.
    pub motion: Option<Motion>,
    /// The actual pose at capture, when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truth: Option<PoseSpec>,
}

/// A commanded motion.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Motion {
    /// A general move, as odometry gives it: the robot's pose at this
    /// frame in the robot frame of the previous one (a turn and a shift
    /// together). A turn of `a` then a straight move of `s` is
    /// `forward = s cos a, left = s sin a, turn_deg = a`.
    Move {
        /// The move itself, in the previous frame.
        #[serde(rename = "move")]
        relative: MoveSpec,
    },
    /// In-place turn, degrees counter-clockwise.
    Turn {
        /// The commanded angle.
        turn_deg: f64,
    },
    /// Straight forward move, metres.
    Forward {
        /// The commanded distance.
        forward: f64,
    },
}

/// The largest shift of a general move that is still a turn in place,
/// metres: a centimetre, what any move errs by however short
/// (odometry's noise on a robot turning on the spot is millimetres).
pub const IN_PLACE_SHIFT_M: f64 = 0.01;

/// A relative pose as stored in a general move: metres and degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MoveSpec {
    /// Ahead of the previous pose, metres.
    pub forward: f64,
    /// To the left of the previous pose, metres.
    pub left: f64,
    /// Counter-clockwise turn, degrees.
    pub turn_deg: f64,
}

impl Motion {
    /// The motion as a relative pose in the previous frame (a turn in
    /// place about the robot centre, a straight move along its heading).
    pub fn relative_pose(&self) -> Pose2 {
        match *self {
            Motion::Move { relative } => Pose2::from_deg(relative.forward, relative.left, relative.turn_deg),
            Motion::Turn { turn_deg } => Pose2::new(0.0, 0.0, turn_deg.to_radians()),
            Motion::Forward { forward } => Pose2::new(forward, 0.0, 0.0),
        }
    }

    /// True for a turn in place: a commanded turn, or a general move whose
    /// shift is within [`IN_PLACE_SHIFT_M`] (odometry of a robot turning
    /// on the spot). Such a frame stays in its sweep, and the turn is
    /// verified by matching profiles.
    pub fn is_in_place_turn(&self) -> bool {
        match *self {
            Motion::Turn { .. } => true,
            Motion::Forward { .. } => false,
            Motion::Move { relative } => relative.forward.hypot(relative.left) <= IN_PLACE_SHIFT_M,
        }
    }

    /// The turn of an in-place turn ([`Motion::is_in_place_turn`]),
    /// radians.
    pub fn in_place_turn_rad(&self) -> Option<f64> {
        match *self {
            // As commanded, not wrapped: a turn of 190° is not one of −170°.
            Motion::Turn { turn_deg } => Some(turn_deg.to_radians()),
            Motion::Move { relative } if self.is_in_place_turn() => Some(relative.turn_deg.to_radians()),
            _ => None,
        }
    }

    /// The general move of a relative pose.
    pub fn from_relative(p: &Pose2) -> Self {
        Motion::Move {
            relative: MoveSpec {
                forward: p.x,
                left: p.y,
                turn_deg: p.theta_deg(),
            },
        }
    }
}

/// A pose as stored in files: metres and degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseSpec {
    /// Position x, metres.
    pub x: f64,
    /// Position y, metres.
    pub y: f64,
    /// Heading, degrees counter-clockwise from +x.
    pub theta_deg: f64,
}

impl From<PoseSpec> for Pose2 {
    fn from(p: PoseSpec) -> Pose2 {
        Pose2::from_deg(p.x, p.y, p.theta_deg)
    }
}

impl From<Pose2> for PoseSpec {
    fn from(p: Pose2) -> PoseSpec {
        PoseSpec {
            x: p.x,
            y: p.y,
            theta_deg: p.theta_deg(),
        }
    }
}

/// A true radial profile, `truth/rop/<sweep>/<k>.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthRop {
    /// Start of bin 0, degrees.
    pub bearing_start_deg: f64,
    /// Bin width, degrees.
    pub bin_deg: f64,
    /// True range per bin, metres; `None` beyond `max_range` or not seen.
    pub range: Vec<Option<f64>>,
}

impl TruthRop {
    /// As a profile: `None` bins become unseen (NaN).
    pub fn to_rop(&self, max_range_m: f32) -> Rop {
        let mut rop = Rop::empty(
            self.bearing_start_deg.to_radians(),
            self.bin_deg.to_radians(),
            self.range.len(),
            max_range_m,
        );
        for (out, r) in rop.range_m.iter_mut().zip(&self.range) {
            *out = r.map_or(f32::NAN, |r| r as f32);
        }
        rop
    }

    /// From a profile: bins without a reliable range become `None`.
    pub fn from_rop(rop: &Rop) -> Self {
        Self {
            bearing_start_deg: rop.bearing_start_deg(),
            bin_deg: rop.bin_width_deg(),
            range: (0..rop.len())
                .map(|i| rop.reliable(i).map(|r| r as f64))
                .collect(),
        }
    }
}

impl CameraSpec {
    /// The camera offset (zero when absent).
    pub fn mount(&self) -> MountSpec {
        self.mount.unwrap_or_default()
    }

    /// The paper's model of this camera.
    pub fn ipm_model(&self) -> IpmModel {
        let mount = self.mount();
        IpmModel {
            measurements: self.ipm,
            width: self.width,
            height: self.height,
            mount_forward_m: mount.forward,
            mount_left_m: mount.left,
        }
    }

    /// The pinhole model of this camera, when the manifest gives one.
    pub fn pinhole_model(&self) -> Option<PinholeModel> {
        let p = self.pinhole.as_ref()?;
        let mount = self.mount();
        Some(PinholeModel {
            width: self.width,
            height: self.height,
            fx: p.fx,
            fy: p.fy,
            cx: p.cx,
            cy: p.cy,
            height_m: p.height,
            tilt_rad: p.tilt_deg.to_radians(),
            mount_forward_m: mount.forward,
            mount_left_m: mount.left,
            // A lens that does not read was refused when the manifest was
            // checked.
            distortion: p
                .distortion
                .as_ref()
                .and_then(|l| l.distortion().ok())
                .unwrap_or_default(),
        })
    }

    /// The most accurate model the camera allows: pinhole when given.
    pub fn default_kind(&self) -> ModelKind {
        if self.pinhole.is_some() {
            ModelKind::Pinhole
        } else {
            ModelKind::Paper
        }
    }

    /// What is wrong with the camera, if anything: its size, its model's
    /// measurements, its mount.
    fn problem(&self) -> Option<String> {
        use limits::*;
        if self.width < 2 || self.height < 2 {
            return Some(format!("camera size {}x{} is too small", self.width, self.height));
        }
        if let Some(p) = image_size_problem(self.width, self.height) {
            return Some(format!("camera size {p}"));
        }
        if let Some(p) = self.ipm_problem() {
            return Some(p);
        }
        if let Some(p) = self.pinhole.as_ref().and_then(|p| self.pinhole_problem(p)) {
            return Some(p);
        }
        let m = self.mount();
        if !(m.forward.is_finite() && m.left.is_finite()) {
            return Some("camera.mount: forward and left must be finite".into());
        }
        if m.forward.abs() > MAX_MOUNT_M || m.left.abs() > MAX_MOUNT_M {
            return Some(format!(
                "camera.mount: forward {} and left {} m must be within {MAX_MOUNT_M} m of the turning centre",
                m.forward, m.left
            ));
        }
        None
    }

    /// What is wrong with the IPM measurements, if anything: each must be
    /// a length a real camera has, and together they must describe a real
    /// lens's field of view.
    fn ipm_problem(&self) -> Option<String> {
        use limits::*;
        if !self.ipm.is_valid() {
            return Some("camera.ipm: b, h, d, w must be finite and positive".into());
        }
        let ipm = &self.ipm;
        if [ipm.b, ipm.h, ipm.d, ipm.w].iter().any(|&v| v > MAX_LENGTH_M) {
            return Some(format!(
                "camera.ipm: b {}, h {}, d {}, w {} m: each must be at most {MAX_LENGTH_M} m (metres, not millimetres?)",
                ipm.b, ipm.h, ipm.d, ipm.w
            ));
        }
        // The view the four measurements imply: the bottom and centre rows'
        // depression angles, and the half-width at the centre row.
        let below_bottom = ipm.h.atan2(ipm.b);
        let below_centre = ipm.h.atan2(ipm.b + ipm.d);
        let half_vertical_deg = (below_bottom - below_centre).to_degrees();
        let half_horizontal_deg = ipm.w.atan2(ipm.h.hypot(ipm.b + ipm.d)).to_degrees();
        for (what, deg) in [
            ("vertical", half_vertical_deg),
            ("horizontal", half_horizontal_deg),
        ] {
            if !(MIN_HALF_FOV_DEG..=MAX_HALF_FOV_DEG).contains(&deg) {
                return Some(format!(
                    "camera.ipm: b {}, h {}, d {}, w {} describe a camera whose {what} half field of view is {deg:.2}°, \
                     outside the {MIN_HALF_FOV_DEG}-{MAX_HALF_FOV_DEG}° of a real lens",
                    ipm.b, ipm.h, ipm.d, ipm.w
                ));
            }
        }
        None
    }

    /// What is wrong with the pinhole model `p`, if anything.
    fn pinhole_problem(&self, p: &PinholeSpec) -> Option<String> {
        use limits::*;
        let finite = [p.fx, p.fy, p.cx, p.cy, p.height, p.tilt_deg]
            .iter()
            .all(|v| v.is_finite());
        if !finite || p.fx <= 0.0 || p.fy <= 0.0 || p.height <= 0.0 {
            return Some(
                "camera.pinhole: fx, fy, height must be finite and positive, cx, cy, tilt_deg finite".into(),
            );
        }
        if !(-90.0..90.0).contains(&p.tilt_deg) {
            return Some(format!(
                "camera.pinhole.tilt_deg {} is outside (-90, 90)",
                p.tilt_deg
            ));
        }
        let side = f64::from(self.width.max(self.height));
        if p.fx > MAX_FOCAL_SIDES * side || p.fy > MAX_FOCAL_SIDES * side {
            return Some(format!(
                "camera.pinhole: fx {} and fy {} px must be at most {MAX_FOCAL_SIDES} image sides ({} px): no real lens sees less than half a degree",
                shown(p.fx),
                shown(p.fy),
                MAX_FOCAL_SIDES * side
            ));
        }
        if !(0.0..=f64::from(self.width)).contains(&p.cx) || !(0.0..=f64::from(self.height)).contains(&p.cy) {
            return Some(format!(
                "camera.pinhole: the principal point ({}, {}) lies outside the {}x{} image",
                p.cx, p.cy, self.width, self.height
            ));
        }
        if p.height > MAX_LENGTH_M {
            return Some(format!(
                "camera.pinhole.height {} m is above {MAX_LENGTH_M} m",
                p.height
            ));
        }
        if let Some(lens) = &p.distortion {
            if let Err(e) = lens.distortion() {
                return Some(format!("camera.pinhole.distortion: {e}"));
            }
        }
        None
    }
}

/// A number for a message: as written where it is of everyday size, in
/// exponent form where it is huge or tiny.
fn shown(v: f64) -> String {
    if v != 0.0 && !(1e-4..1e6).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// What a manifest may describe: a small robot's camera and its moves
/// between two frames. A manifest beyond these is refused with an error
/// naming the field or frame, before any work (and before any memory is
/// spent on it).
pub mod limits {
    /// The widest or tallest image, pixels.
    pub const MAX_IMAGE_SIDE: u32 = 8192;
    /// The most pixels in an image.
    pub const MAX_IMAGE_PIXELS: u64 = 40_000_000;

    /// What is wrong with an image of `width` × `height` pixels for these
    /// limits, if anything.
    pub fn image_size_problem(width: u32, height: u32) -> Option<String> {
        let too_big = width > MAX_IMAGE_SIDE
            || height > MAX_IMAGE_SIDE
            || u64::from(width) * u64::from(height) > MAX_IMAGE_PIXELS;
        too_big.then(|| {
            format!(
                "{width}x{height} is beyond the {MAX_IMAGE_SIDE} pixels a side and {} megapixels an image may have",
                MAX_IMAGE_PIXELS / 1_000_000
            )
        })
    }
    /// The longest camera measurement (IPM `b`, `h`, `d`, `w`, pinhole
    /// height), metres.
    pub const MAX_LENGTH_M: f64 = 10.0;
    /// The farthest a camera may sit from the turning centre, metres.
    pub const MAX_MOUNT_M: f64 = 1.0;
    /// The narrowest and widest half field of view the IPM may imply,
    /// degrees.
    pub const MIN_HALF_FOV_DEG: f64 = 1.0;
    /// See [`MIN_HALF_FOV_DEG`].
    pub const MAX_HALF_FOV_DEG: f64 = 85.0;
    /// The longest pinhole focal length, in image sides (a field of view
    /// of about half a degree).
    pub const MAX_FOCAL_SIDES: f64 = 100.0;
    /// The longest soft range limit, metres.
    pub const MAX_RANGE_M: f64 = 50.0;
    /// The longest straight move between two frames, metres.
    pub const MAX_FORWARD_M: f64 = 5.0;
    /// The largest turn between two frames, degrees (one full turn).
    pub const MAX_TURN_DEG: f64 = 360.0;
    /// The most frames in a dataset.
    pub const MAX_FRAMES: usize = 1_000_000;
}

/// A dataset opened from disk: its folder and checked manifest.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// The dataset folder: the folder frames' image paths are relative to.
    pub root: PathBuf,
    /// The manifest.
    pub manifest: Manifest,
    /// The file that describes it: `dataset.json`, or an image folder's
    /// rig file.
    pub source: PathBuf,
    /// Each frame's time, seconds, where the input stamps its frames (an
    /// image folder); empty otherwise.
    pub stamps: Vec<f64>,
    /// The frames' images where a bag holds them (the manifest's image
    /// paths are then `topic@stamp` labels); `None` for image files.
    pub bag_frames: Option<std::sync::Arc<crate::bag::camera::BagFrames>>,
    /// Damage read past (a bag cut short, chunks skipped), one line each.
    pub warnings: Vec<String>,
    /// The truth of an image folder whose clock is to be found from the
    /// images (`truth_clock: from_images`); its frames carry no truth.
    pub truth_track: Option<std::sync::Arc<crate::TruthTrack>>,
}

impl Dataset {
    /// A name for reports: the folder's name, which tells apart the
    /// renders of one scene (their manifests share the scene's name); the
    /// manifest's name where the folder has none (`.`).
    pub fn label(&self) -> String {
        std::fs::canonicalize(&self.root)
            .ok()
            .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .unwrap_or_else(|| self.manifest.name.clone())
    }
}

pub(crate) fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, IoError> {
    let text = std::fs::read(path).map_err(|e| IoError::io(path, e))?;
    serde_json::from_slice(&text).map_err(|e| IoError::Json {
        path: path.to_owned(),
        source: e,
    })
}

pub(crate) fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), IoError> {
    atomic_write_with(path, |w| {
        serde_json::to_writer_pretty(&mut *w, value).map_err(std::io::Error::other)?;
        std::io::Write::write_all(w, b"\n")
    })
}

/// A relative path that stays inside the dataset folder.
fn is_safe_relative(p: &str) -> bool {
    let path = Path::new(p);
    !p.is_empty()
        && path
            .components()
            .all(|c| matches!(c, Component::Normal(_) | Component::CurDir))
}

impl Dataset {
    /// Opens the dataset in folder `root` (or whose `dataset.json` is
    /// `root`), checking every field of the manifest and that every frame's
    /// image exists. An image folder (a folder with a
    /// [`RIG_FILE`](crate::RIG_FILE) and no `dataset.json`, or the rig
    /// file itself) is read through its rig ([`ImageFolder`](crate::ImageFolder)).
    pub fn open(root: &Path) -> Result<Self, IoError> {
        let rig = if root.is_file() && root.file_name() != Some(std::ffi::OsStr::new("dataset.json")) {
            Some(root.to_owned())
        } else if root.is_dir() && !root.join("dataset.json").exists() && root.join(crate::RIG_FILE).is_file()
        {
            Some(root.join(crate::RIG_FILE))
        } else {
            None
        };
        if let Some(rig) = rig.filter(|r| r.extension().is_some_and(|e| e == "json")) {
            let folder = crate::ImageFolder::open(&rig)?;
            let ds = Dataset {
                root: folder.root,
                manifest: folder.manifest,
                source: rig.clone(),
                stamps: folder.stamps,
                bag_frames: folder.bag_frames.map(std::sync::Arc::new),
                warnings: folder.warnings,
                truth_track: folder.truth_track.map(std::sync::Arc::new),
            };
            ds.check(&rig)?;
            return Ok(ds);
        }
        let root = if root.is_file() {
            // A manifest names its dataset; any other file is no dataset.
            if root.file_name() != Some(std::ffi::OsStr::new("dataset.json")) {
                return Err(IoError::invalid(
                    root,
                    "not a dataset: a dataset is a folder with a dataset.json",
                ));
            }
            root.parent().unwrap_or(Path::new(".")).to_owned()
        } else {
            root.to_owned()
        };
        let path = root.join("dataset.json");
        if !root.is_dir() {
            return Err(IoError::io(
                &root,
                std::io::Error::new(std::io::ErrorKind::NotFound, "no such dataset folder"),
            ));
        }
        // The format is checked before the rest, so that a future version
        // gets a clear message rather than a field error.
        let raw: serde_json::Value = read_json(&path)?;
        match raw.get("format").and_then(|f| f.as_str()) {
            Some(FORMAT_VERSION) => {}
            Some(other) => {
                return Err(IoError::UnknownFormat {
                    path,
                    found: other.to_string(),
                })
            }
            None => return Err(IoError::invalid(&path, "missing field `format`")),
        }
        let manifest: Manifest = serde_json::from_value(raw).map_err(|e| IoError::Json {
            path: path.clone(),
            source: e,
        })?;
        let source = path.clone();
        let ds = Dataset {
            root,
            manifest,
            source,
            stamps: Vec::new(),
            bag_frames: None,
            warnings: Vec::new(),
            truth_track: None,
        };
        ds.check(&path)?;
        Ok(ds)
    }

    fn check(&self, path: &Path) -> Result<(), IoError> {
        let m = &self.manifest;
        if let Some(p) = m.camera.problem() {
            return Err(IoError::invalid(path, p));
        }
        if !(m.max_range.is_finite() && m.max_range > 0.0) {
            return Err(IoError::invalid(
                path,
                format!("max_range {} must be finite and positive", m.max_range),
            ));
        }
        if m.max_range > limits::MAX_RANGE_M {
            return Err(IoError::invalid(
                path,
                format!(
                    "max_range {} m is beyond the {} m this engine maps",
                    m.max_range,
                    limits::MAX_RANGE_M
                ),
            ));
        }
        if m.frames.is_empty() {
            return Err(IoError::invalid(path, "no frames"));
        }
        if m.frames.len() > limits::MAX_FRAMES {
            return Err(IoError::invalid(
                path,
                format!(
                    "{} frames: more than the {} this reader takes",
                    m.frames.len(),
                    limits::MAX_FRAMES
                ),
            ));
        }
        for (i, f) in m.frames.iter().enumerate() {
            let previous = i.checked_sub(1).map(|j| m.frames[j].sweep);
            if let Some(what) = self.frame_problem(f, previous) {
                return Err(IoError::invalid(
                    path,
                    format!("frames[{i}] ({}): {what}", f.image),
                ));
            }
        }
        Ok(())
    }

    /// What is wrong with frame `f` (after a frame of sweep `previous`),
    /// if anything: its image, its motion, its sweep number, its truth.
    fn frame_problem(&self, f: &FrameSpec, previous: Option<u32>) -> Option<String> {
        // A bag's frames are held, their paths only labels.
        if self.bag_frames.is_none() {
            if !is_safe_relative(&f.image) {
                return Some("image must be a relative path inside the dataset".into());
            }
            if !self.root.join(&f.image).is_file() {
                return Some("image file does not exist".into());
            }
        }
        match f.motion {
            Some(Motion::Turn { turn_deg: v }) | Some(Motion::Forward { forward: v })
                if !v.is_finite() =>
            {
                return Some("motion is not finite".into())
            }
            Some(Motion::Move { relative: m })
                if !(m.forward.is_finite() && m.left.is_finite() && m.turn_deg.is_finite()) =>
            {
                return Some("motion is not finite".into())
            }
            Some(Motion::Move { relative: m }) if m.forward.hypot(m.left) > limits::MAX_FORWARD_M => {
                return Some(format!(
                    "a move of {} m between two frames is beyond the {} m limit (metres, not millimetres?)",
                    shown(m.forward.hypot(m.left)),
                    limits::MAX_FORWARD_M
                ))
            }
            Some(Motion::Move { relative: m }) if m.turn_deg.abs() > limits::MAX_TURN_DEG => {
                return Some(format!(
                    "a turn of {}° between two frames is more than a full turn",
                    shown(m.turn_deg)
                ))
            }
            Some(Motion::Forward { forward }) if forward.abs() > limits::MAX_FORWARD_M => {
                return Some(format!(
                    "a straight move of {} m between two frames is beyond the {} m limit (metres, not millimetres?)",
                    shown(forward),
                    limits::MAX_FORWARD_M
                ))
            }
            Some(Motion::Turn { turn_deg }) if turn_deg.abs() > limits::MAX_TURN_DEG => {
                return Some(format!(
                    "a turn of {}° between two frames is more than a full turn",
                    shown(turn_deg)
                ))
            }
            _ => {}
        }
        // Sweep numbers follow the motions: a turn stays in the sweep,
        // a straight move starts a later one.
        if let Some(before) = previous {
            match f.motion {
                Some(m) if m.is_in_place_turn() && f.sweep != before => {
                    return Some(format!(
                        "a turn keeps the robot in sweep {before}, but the frame says sweep {}",
                        f.sweep
                    ))
                }
                Some(m) if !m.is_in_place_turn() && f.sweep <= before => {
                    return Some(format!(
                        "a move starts a new sweep after sweep {before}, but the frame says sweep {}",
                        f.sweep
                    ))
                }
                _ => {}
            }
        }
        if let Some(t) = f.truth {
            if !(t.x.is_finite() && t.y.is_finite() && t.theta_deg.is_finite()) {
                return Some("truth pose is not finite".into());
            }
        }
        None
    }

    /// The file that describes the dataset: its `dataset.json`, or an
    /// image folder's rig file.
    pub fn manifest_path(&self) -> PathBuf {
        self.source.clone()
    }

    /// Path of frame `i`'s image.
    ///
    /// # Panics
    /// When `i` is not a frame index.
    pub fn image_path(&self, i: usize) -> PathBuf {
        match &self.bag_frames {
            Some(b) => PathBuf::from(format!("{}:{}", b.path.display(), self.manifest.frames[i].image)),
            None => self.root.join(&self.manifest.frames[i].image),
        }
    }

    /// Loads frame `i`'s image as 8-bit RGB (grey, alpha and 16-bit images
    /// are converted), checking its size against the camera.
    ///
    /// # Panics
    /// When `i` is not a frame index.
    pub fn load_image(&self, i: usize) -> Result<image::RgbImage, IoError> {
        if let Some(b) = &self.bag_frames {
            let img = b.decode(i)?;
            let (width, height) = (self.manifest.camera.width, self.manifest.camera.height);
            if img.dimensions() != (width, height) {
                return Err(IoError::ImageSize {
                    path: self.image_path(i),
                    width,
                    height,
                    found_width: img.width(),
                    found_height: img.height(),
                });
            }
            return Ok(img);
        }
        load_rgb(
            &self.image_path(i),
            self.manifest.camera.width,
            self.manifest.camera.height,
        )
    }

    /// The camera model of the given kind, or the most accurate one.
    pub fn camera(&self, kind: Option<ModelKind>) -> Result<Camera, IoError> {
        let cam = &self.manifest.camera;
        match kind.unwrap_or_else(|| cam.default_kind()) {
            ModelKind::Paper if cam.pinhole.as_ref().is_some_and(|p| p.distortion.is_some()) => Err(IoError::invalid(
                self.manifest_path(),
                "the camera's lens distortion (camera.pinhole.distortion) is beyond the paper's model: use the pinhole model",
            )),
            ModelKind::Paper => Ok(Camera::Paper(cam.ipm_model())),
            ModelKind::Pinhole => cam.pinhole_model().map(Camera::Pinhole).ok_or_else(|| {
                IoError::invalid(
                    self.manifest_path(),
                    "the pinhole model was asked for, but camera.pinhole is absent",
                )
            }),
        }
    }

    /// The truth pose of every frame, when all frames have one.
    pub fn truth_poses(&self) -> Option<Vec<Pose2>> {
        self.manifest
            .frames
            .iter()
            .map(|f| f.truth.map(Pose2::from))
            .collect()
    }

    /// Path of `truth/world.json`.
    pub fn world_path(&self) -> PathBuf {
        self.root.join("truth").join("world.json")
    }

    /// The scene, if the dataset has `truth/world.json`.
    pub fn world(&self) -> Result<Option<World>, IoError> {
        let path = self.world_path();
        if !path.exists() {
            return Ok(None);
        }
        let w: World = read_json(&path)?;
        if !w.bounds.iter().all(|v| v.is_finite()) {
            return Err(IoError::invalid(&path, "bounds are not finite"));
        }
        if let Some((i, p)) = w
            .obstacles
            .iter()
            .enumerate()
            .find_map(|(i, o)| o.problem().map(|p| (i, p)))
        {
            return Err(IoError::invalid(&path, format!("obstacles[{i}]: {p}")));
        }
        Ok(Some(w))
    }

    /// Path of frame `i`'s true profile: the image path with `frames/`
    /// replaced by `truth/rop/` and the extension by `.json`.
    ///
    /// # Panics
    /// When `i` is not a frame index.
    pub fn truth_rop_path(&self, i: usize) -> PathBuf {
        let image = Path::new(&self.manifest.frames[i].image);
        let rel = image.strip_prefix("frames").unwrap_or(image);
        self.root
            .join("truth")
            .join("rop")
            .join(rel)
            .with_extension("json")
    }

    /// Frame `i`'s true profile, if the dataset has one.
    ///
    /// # Panics
    /// When `i` is not a frame index.
    pub fn truth_rop(&self, i: usize) -> Result<Option<TruthRop>, IoError> {
        let path = self.truth_rop_path(i);
        if !path.exists() {
            return Ok(None);
        }
        let t: TruthRop = read_json(&path)?;
        if !(t.bin_deg.is_finite() && t.bin_deg > 0.0 && t.bearing_start_deg.is_finite()) {
            return Err(IoError::invalid(
                &path,
                "bin_deg must be positive and bearing_start_deg finite",
            ));
        }
        if t.range.iter().flatten().any(|r| !r.is_finite() || *r < 0.0) {
            return Err(IoError::invalid(&path, "a range is negative or not finite"));
        }
        Ok(Some(t))
    }

    /// Writes the manifest (atomically).
    pub fn write_manifest(root: &Path, manifest: &Manifest) -> Result<(), IoError> {
        write_json(&root.join("dataset.json"), manifest)
    }

    /// Writes the scene to `truth/world.json` (atomically).
    pub fn write_world(root: &Path, world: &World) -> Result<(), IoError> {
        write_json(&root.join("truth").join("world.json"), world)
    }

    /// Writes a true profile for the frame whose image is `image` (atomically).
    pub fn write_truth_rop(root: &Path, image: &str, rop: &TruthRop) -> Result<(), IoError> {
        let rel = Path::new(image);
        let rel = rel.strip_prefix("frames").unwrap_or(rel);
        write_json(
            &root.join("truth").join("rop").join(rel).with_extension("json"),
            rop,
        )
    }

    /// Writes an 8-bit RGB image as PNG at `root/image` (atomically).
    pub fn write_image(root: &Path, image: &str, rgb: &image::RgbImage) -> Result<(), IoError> {
        let path = root.join(image);
        let mut bytes = Vec::new();
        rgb.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png)
            .map_err(|e| IoError::Image {
                path: path.clone(),
                source: e,
            })?;
        atomic_write(&path, &bytes)
    }
}

/// Loads an image as 8-bit RGB and checks its size.
pub(crate) fn load_rgb(path: &Path, width: u32, height: u32) -> Result<image::RgbImage, IoError> {
    let reader = image::ImageReader::open(path)
        .map_err(|e| IoError::io(path, e))?
        .with_guessed_format()
        .map_err(|e| IoError::io(path, e))?;
    let img = reader.decode().map_err(|e| IoError::Image {
        path: path.to_owned(),
        source: e,
    })?;
    if img.width() != width || img.height() != height {
        return Err(IoError::ImageSize {
            path: path.to_owned(),
            width,
            height,
            found_width: img.width(),
            found_height: img.height(),
        });
    }
    Ok(img.into_rgb8())
}

#[cfg(test)]
mod tests;
