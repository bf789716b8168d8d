//! The scene of `truth/world.json`.

use serde::{Deserialize, Serialize};

/// A scene: a rectangular floor and obstacles standing on it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct World {
    /// `[x_min, y_min, x_max, y_max]` of the floor, metres.
    pub bounds: [f64; 4],
    /// Floor colour, 8-bit RGB.
    pub floor_rgb: [u8; 3],
    /// Obstacles standing on the floor.
    pub obstacles: Vec<Obstacle>,
}

/// An obstacle standing on the floor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Obstacle {
    /// A box with vertical faces.
    Box {
        /// Centre of the footprint, metres.
        center: [f64; 2],
        /// Footprint size along its own x and y, metres.
        size: [f64; 2],
        /// Rotation of the footprint, degrees counter-clockwise.
        #[serde(default)]
        yaw_deg: f64,
        /// Height, metres.
        height: f64,
        /// Colour, 8-bit RGB.
        rgb: [u8; 3],
    },
    /// A vertical cylinder.
    Cylinder {
        /// Centre of the footprint, metres.
        center: [f64; 2],
        /// Radius, metres.
        radius: f64,
        /// Height, metres.
        height: f64,
        /// Colour, 8-bit RGB.
        rgb: [u8; 3],
    },
}

impl Obstacle {
    /// The obstacle's height, metres.
    pub fn height(&self) -> f64 {
        match self {
            Obstacle::Box { height, .. } | Obstacle::Cylinder { height, .. } => *height,
        }
    }

    /// The obstacle's colour.
    pub fn rgb(&self) -> [u8; 3] {
        match self {
            Obstacle::Box { rgb, .. } | Obstacle::Cylinder { rgb, .. } => *rgb,
        }
    }

    /// Distance along the 2D ray `origin + t·dir` (unit `dir`) to where it
    /// first enters the obstacle's footprint, if it does at `t ≥ 0`. A ray
    /// starting inside the footprint hits at `t = 0`.
    pub fn ray_hit(&self, origin: [f64; 2], dir: [f64; 2]) -> Option<f64> {
        match *self {
            Obstacle::Box { center, size, yaw_deg, .. } => {
                let (s, c) = yaw_deg.to_radians().sin_cos();
                // Into the box's own frame.
                let ox = origin[0] - center[0];
                let oy = origin[1] - center[1];
                let lo = [c * ox + s * oy, -s * ox + c * oy];
                let ld = [c * dir[0] + s * dir[1], -s * dir[0] + c * dir[1]];
                let half = [size[0] / 2.0, size[1] / 2.0];
                let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
                for k in 0..2 {
                    if ld[k].abs() < 1e-15 {
                        if lo[k].abs() > half[k] {
                            return None;
                        }
                    } else {
                        let a = (-half[k] - lo[k]) / ld[k];
                        let b = (half[k] - lo[k]) / ld[k];
                        t0 = t0.max(a.min(b));
                        t1 = t1.min(a.max(b));
                    }
                }
                (t1 >= t0.max(0.0)).then_some(t0.max(0.0))
            }
            Obstacle::Cylinder { center, radius, .. } => {
                let ox = origin[0] - center[0];
                let oy = origin[1] - center[1];
                let b = ox * dir[0] + oy * dir[1];
                let c = ox * ox + oy * oy - radius * radius;
                if c <= 0.0 {
                    return Some(0.0);
                }
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let t = -b - disc.sqrt();
                (t >= 0.0).then_some(t)
            }
        }
    }

    /// Every number finite, sizes positive.
    pub fn problem(&self) -> Option<String> {
        let ok = match self {
            Obstacle::Box { center, size, yaw_deg, height, .. } => {
                center.iter().chain(size).chain([yaw_deg, height]).all(|v| v.is_finite())
                    && size.iter().all(|s| *s > 0.0)
                    && *height > 0.0
            }
            Obstacle::Cylinder { center, radius, height, .. } => {
                center.iter().chain([radius, height]).all(|v| v.is_finite()) && *radius > 0.0 && *height > 0.0
            }
        };
        (!ok).then(|| "obstacle with a non-finite or non-positive size".to_string())
    }
}

impl World {
    /// Distance along a 2D ray to the nearest obstacle, if any.
    pub fn ray_cast(&self, origin: [f64; 2], dir: [f64; 2]) -> Option<(f64, usize)> {
        self.obstacles
            .iter()
            .enumerate()
            .filter_map(|(i, o)| o.ray_hit(origin, dir).map(|t| (t, i)))
            .min_by(|a, b| a.0.total_cmp(&b.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_hits_rotated_box_and_cylinder() {
        let b = Obstacle::Box { center: [1.0, 0.0], size: [0.2, 0.2], yaw_deg: 45.0, height: 0.1, rgb: [0; 3] };
        // A 0.2 m square turned 45° reaches √2·0.1 towards the origin.
        let t = b.ray_hit([0.0, 0.0], [1.0, 0.0]).unwrap();
        assert!((t - (1.0 - 0.1 * 2f64.sqrt())).abs() < 1e-12);
        assert!(b.ray_hit([0.0, 0.0], [0.0, 1.0]).is_none());
        let c = Obstacle::Cylinder { center: [0.0, 2.0], radius: 0.5, height: 0.1, rgb: [0; 3] };
        assert!((c.ray_hit([0.0, 0.0], [0.0, 1.0]).unwrap() - 1.5).abs() < 1e-12);
        assert!(c.ray_hit([0.0, 0.0], [0.0, -1.0]).is_none());
        assert_eq!(c.ray_hit([0.0, 2.1], [1.0, 0.0]), Some(0.0));
    }
}
