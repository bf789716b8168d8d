//! The scene file format.

use pirouette_camera::PinholeModel;
use pirouette_io::{IoError, World};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Errors of the renderer.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// Reading or writing a file failed.
    #[error(transparent)]
    Io(#[from] IoError),
    /// The scene is not usable.
    #[error("scene: {problem}")]
    Invalid {
        /// What is wrong.
        problem: String,
    },
}

/// The names of the built-in scenes, whose files live in `datasets/scenes/`.
pub const BUILTIN_SCENES: [&str; 5] = [
    "field-pirouette",
    "field-multi",
    "room-multi",
    "field-multi-b",
    "room-multi-b",
];

/// The most waypoints a route may have.
pub const MAX_WAYPOINTS: usize = 10_000;

/// The most frames a sweep may have.
pub const MAX_FRAMES_PER_SWEEP: u32 = 360;

/// The largest light gain (`exposure`, each of `light_rgb`).
pub const MAX_LIGHT_GAIN: f64 = 10.0;

/// The most floor specks a scene may scatter.
pub const MAX_SPECKS: usize = 1_000_000;

/// A scene to render: the world, the camera, how it looks, and the route.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scene {
    /// The dataset name written to the manifest.
    pub name: String,
    /// Floor and obstacles (also written as `truth/world.json`).
    pub world: World,
    /// Colour seen where a ray meets nothing (above the horizon).
    #[serde(default = "default_backdrop")]
    pub backdrop_rgb: [u8; 3],
    /// The camera.
    #[serde(default)]
    pub camera: CameraSetup,
    /// The soft range limit written to the manifest, metres.
    pub max_range: f64,
    /// Light, vignetting, floor variation, specks, noise.
    #[serde(default)]
    pub look: Look,
    /// Where the robot goes.
    pub route: Route,
    /// How far actual motion strays from the command.
    #[serde(default)]
    pub motion_errors: MotionErrors,
}

fn default_backdrop() -> [u8; 3] {
    [120, 120, 125]
}

/// A pinhole camera on the robot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CameraSetup {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Horizontal field of view, degrees (square pixels, principal point
    /// at the image centre).
    pub hfov_deg: f64,
    /// Height of the optical centre, metres.
    pub height_m: f64,
    /// Downward tilt, degrees.
    pub tilt_deg: f64,
    /// Mount offset ahead of the rotation centre, metres.
    pub mount_forward_m: f64,
    /// Mount offset to the left, metres.
    pub mount_left_m: f64,
    /// The lens distortion the images are rendered through; none when
    /// absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lens: Option<pirouette_io::LensSpec>,
}

impl Default for CameraSetup {
    /// The paper's camera: 320 × 240, 60° across, 10 cm up, tilted 25° down,
    /// centred on the robot.
    fn default() -> Self {
        Self {
            width: 320,
            height: 240,
            hfov_deg: 60.0,
            height_m: 0.1,
            tilt_deg: 25.0,
            mount_forward_m: 0.0,
            mount_left_m: 0.0,
            lens: None,
        }
    }
}

impl CameraSetup {
    /// The pinhole model of this camera.
    pub fn pinhole(&self) -> PinholeModel {
        let cx = (self.width as f64 - 1.0) / 2.0;
        let cy = (self.height as f64 - 1.0) / 2.0;
        let f = (self.width as f64 / 2.0) / (self.hfov_deg.to_radians() / 2.0).tan();
        PinholeModel {
            width: self.width,
            height: self.height,
            fx: f,
            fy: f,
            cx,
            cy,
            height_m: self.height_m,
            tilt_rad: self.tilt_deg.to_radians(),
            mount_forward_m: self.mount_forward_m,
            mount_left_m: self.mount_left_m,
            // A lens that does not read is refused by `Scene::validate`.
            distortion: self
                .lens
                .as_ref()
                .and_then(|l| l.distortion().ok())
                .unwrap_or_default(),
        }
    }
}

/// How the images look.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Look {
    /// Direction towards the light (world frame, any length).
    pub light_dir: [f64; 3],
    /// Share of ambient light, 0-1; the rest is diffuse.
    pub ambient: f64,
    /// Overall brightness gain.
    pub exposure: f64,
    /// Colour of the light: a gain per channel (red, green, blue) on top
    /// of `exposure`; white light is `[1, 1, 1]`.
    pub light_rgb: [f64; 3],
    /// Darkening towards the image edges (0 none, 1 black at the corners).
    pub vignetting: f64,
    /// Extra darkening of the bottom corners (the paper's Fig. 1).
    pub corner_darkening: f64,
    /// Relative amplitude of slow floor brightness variation.
    pub floor_variation: f64,
    /// Relative amplitude of fine floor texture (5 mm grain).
    pub floor_texture: f64,
    /// Floor specks (lint, reflections) per square metre.
    pub specks_per_m2: f64,
    /// Standard deviation of sensor noise, 8-bit levels.
    pub noise_sigma: f64,
}

impl Default for Look {
    /// A lamp overhead and to one side, noticeable vignetting, a slowly
    /// varying floor with a faint grain, a few specks per square metre,
    /// and two levels of sensor noise.
    fn default() -> Self {
        Self {
            light_dir: [0.4, 0.3, 1.0],
            ambient: 0.45,
            exposure: 1.0,
            light_rgb: [1.0; 3],
            vignetting: 0.6,
            corner_darkening: 0.6,
            floor_variation: 0.12,
            floor_texture: 0.04,
            specks_per_m2: 12.0,
            noise_sigma: 2.0,
        }
    }
}

/// The route: where the robot starts and the spots it visits; at each spot
/// it makes one pirouette.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Route {
    /// Heading at the first frame, degrees.
    pub start_heading_deg: f64,
    /// Spots visited in order, metres; one sweep at each.
    pub waypoints: Vec<[f64; 2]>,
    /// Frames per sweep (evenly spaced turns over 360°).
    #[serde(default = "default_turns")]
    pub frames_per_sweep: u32,
}

fn default_turns() -> u32 {
    12
}

/// How actual motion strays from the command.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct MotionErrors {
    /// Standard deviation of the turn error, degrees.
    pub turn_sigma_deg: f64,
    /// Systematic turn error, degrees per turn.
    pub turn_bias_deg: f64,
    /// Distance of the true rotation centre from the robot centre, metres.
    pub rotation_centre_offset_m: f64,
    /// Jitter of the rotation centre per turn, metres.
    pub rotation_centre_jitter_m: f64,
    /// Relative standard deviation of forward distance.
    pub forward_sigma_rel: f64,
    /// Standard deviation of the heading change during a forward move, degrees.
    pub heading_sigma_deg: f64,
}

impl Default for MotionErrors {
    /// Errors of the size the paper complains of: turns off by a few
    /// degrees, a rotation centre half a centimetre off, forward moves off
    /// by 5 % and 1.5° of heading.
    fn default() -> Self {
        Self {
            turn_sigma_deg: 3.0,
            turn_bias_deg: 1.0,
            rotation_centre_offset_m: 0.005,
            rotation_centre_jitter_m: 0.001,
            forward_sigma_rel: 0.05,
            heading_sigma_deg: 1.5,
        }
    }
}

impl Scene {
    /// A built-in scene by name (see [`BUILTIN_SCENES`]).
    #[allow(clippy::expect_used, reason = "the built-in scene files are tested")]
    pub fn builtin(name: &str) -> Option<Scene> {
        let text = match name {
            "field-pirouette" => include_str!("../../../datasets/scenes/field-pirouette.json"),
            "field-multi" => include_str!("../../../datasets/scenes/field-multi.json"),
            "room-multi" => include_str!("../../../datasets/scenes/room-multi.json"),
            "field-multi-b" => include_str!("../../../datasets/scenes/field-multi-b.json"),
            "room-multi-b" => include_str!("../../../datasets/scenes/room-multi-b.json"),
            _ => return None,
        };
        Some(serde_json::from_str(text).expect("built-in scene files are valid (tested)"))
    }

    /// A scene from a JSON file.
    pub fn from_file(path: &Path) -> Result<Scene, SimError> {
        let text = std::fs::read(path).map_err(|e| IoError::Io {
            path: path.to_owned(),
            source: e,
        })?;
        let scene: Scene = serde_json::from_slice(&text).map_err(|e| IoError::Json {
            path: path.to_owned(),
            source: e,
        })?;
        scene.validate().map_err(|e| match e {
            SimError::Invalid { problem } => SimError::Io(IoError::Invalid {
                path: path.to_owned(),
                problem,
            }),
            other => other,
        })?;
        Ok(scene)
    }

    /// Checks the scene for values that cannot be rendered.
    pub fn validate(&self) -> Result<(), SimError> {
        let problem = (self.camera_problem())
            .or_else(|| self.route_problem())
            .or_else(|| self.motion_problem())
            .or_else(|| self.look_problem())
            .or_else(|| self.world_problem());
        match problem {
            Some(problem) => Err(SimError::Invalid { problem }),
            None => Ok(()),
        }
    }

    /// What is wrong with the camera or the range limit, if anything.
    fn camera_problem(&self) -> Option<String> {
        use pirouette_io::limits::{image_size_problem, MAX_LENGTH_M, MAX_RANGE_M};
        let c = &self.camera;
        if c.width < 2
            || c.height < 2
            || !(c.hfov_deg > 1.0 && c.hfov_deg < 170.0)
            || c.height_m.is_nan()
            || c.height_m <= 0.0
        {
            return Some("camera: width and height ≥ 2, hfov_deg in (1, 170), height_m > 0".into());
        }
        if !(c.tilt_deg > 0.0 && c.tilt_deg < 90.0) {
            return Some("camera: tilt_deg must be in (0, 90)".into());
        }
        if let Some(p) = image_size_problem(c.width, c.height) {
            return Some(format!("camera: {p}"));
        }
        if let Some(Err(e)) = c.lens.as_ref().map(|l| l.distortion()) {
            return Some(format!("camera.lens: {e}"));
        }
        if c.height_m > MAX_LENGTH_M || self.max_range > MAX_RANGE_M {
            return Some(format!(
                "camera height {} m and max_range {} m must be at most {MAX_LENGTH_M} m and {MAX_RANGE_M} m",
                c.height_m, self.max_range
            ));
        }
        if !(self.max_range.is_finite() && self.max_range > 0.0) {
            return Some("max_range must be finite and positive".into());
        }
        None
    }

    /// What is wrong with the route's size, if anything.
    fn route_problem(&self) -> Option<String> {
        if self.route.waypoints.is_empty() || self.route.frames_per_sweep == 0 {
            return Some("route: at least one waypoint and one frame per sweep".into());
        }
        if self.route.waypoints.len() > MAX_WAYPOINTS || self.route.frames_per_sweep > MAX_FRAMES_PER_SWEEP {
            return Some(format!(
                "route: at most {MAX_WAYPOINTS} waypoints and {MAX_FRAMES_PER_SWEEP} frames per sweep"
            ));
        }
        None
    }

    /// What is wrong with the motion errors, if anything.
    fn motion_problem(&self) -> Option<String> {
        let m = &self.motion_errors;
        let spreads = [
            m.turn_sigma_deg,
            m.turn_bias_deg.abs(),
            m.heading_sigma_deg,
            m.forward_sigma_rel * 90.0,
            (m.rotation_centre_offset_m.abs() + m.rotation_centre_jitter_m) * 90.0,
        ];
        (spreads.iter())
            .any(|v| !(v.is_finite() && (0.0..=90.0).contains(v)))
            .then(|| {
                "motion_errors: turn and heading errors within 0-90°, forward_sigma_rel within 0-1, \
             rotation centre offset and jitter within 1 m"
                    .into()
            })
    }

    /// What is wrong with the look, if anything.
    fn look_problem(&self) -> Option<String> {
        let l = &self.look;
        let [x0, y0, x1, y1] = self.world.bounds;
        let specks = ((x1 - x0) * (y1 - y0)).abs() * l.specks_per_m2;
        let noise_ok = (0.0..=255.0).contains(&l.noise_sigma);
        if !(l
            .light_rgb
            .iter()
            .chain([&l.exposure])
            .all(|g| (0.0..=MAX_LIGHT_GAIN).contains(g)))
        {
            return Some(format!(
                "look: exposure and light_rgb gains within 0-{MAX_LIGHT_GAIN}"
            ));
        }
        let specks_ok = (0.0..=MAX_SPECKS as f64).contains(&specks);
        (!(noise_ok && specks_ok)).then(|| {
            format!("look: noise_sigma within 0-255 levels and at most {MAX_SPECKS} specks over the world's bounds")
        })
    }

    /// What is wrong with the world's obstacles and the route among them,
    /// if anything.
    fn world_problem(&self) -> Option<String> {
        let route = &self.route;
        if (route.waypoints.iter().flatten())
            .chain([&route.start_heading_deg])
            .any(|v| !v.is_finite())
        {
            return Some("route: waypoints and heading must be finite".into());
        }
        let obstacles = &self.world.obstacles;
        if let Some((i, p)) = (obstacles.iter().enumerate()).find_map(|(i, o)| o.problem().map(|p| (i, p))) {
            return Some(format!("world.obstacles[{i}]: {p}"));
        }
        let inside = |w: &[f64; 2]| {
            (obstacles.iter()).any(|o| o.ray_interval(*w, [1.0, 0.0]).is_some_and(|h| h.t_enter <= 0.0))
        };
        let i = route.waypoints.iter().position(inside)?;
        Some(format!("route.waypoints[{i}] lies inside an obstacle"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_scenes_parse_and_validate() {
        for name in BUILTIN_SCENES {
            let s = Scene::builtin(name).unwrap();
            s.validate().unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        assert!(Scene::builtin("nope").is_none());
    }

    #[test]
    fn default_camera_has_sixty_degree_view() {
        let p = CameraSetup::default().pinhole();
        assert!((p.fx - 160.0 / 30f64.to_radians().tan()).abs() < 1e-9);
        assert_eq!((p.cx, p.cy), (159.5, 119.5));
    }
}
