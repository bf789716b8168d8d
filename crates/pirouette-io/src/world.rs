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

/// Where a 2D ray crosses an obstacle's footprint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FootprintHit {
    /// Ray parameter where the ray enters the footprint.
    pub t_enter: f64,
    /// Ray parameter where it leaves.
    pub t_exit: f64,
    /// Outward unit normal of the face entered.
    pub normal: [f64; 2],
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

    /// Where the 2D ray `origin + t·dir` (any non-zero `dir`) crosses the
    /// obstacle's footprint: the entry and exit parameters and the outward
    /// normal at the entry. A ray starting inside has `t_enter < 0`.
    pub fn ray_interval(&self, origin: [f64; 2], dir: [f64; 2]) -> Option<FootprintHit> {
        self.ray_interval_turned(origin, dir, self.yaw_sin_cos())
    }

    /// A circle holding the footprint: its centre and radius, metres.
    pub fn bounding_circle(&self) -> ([f64; 2], f64) {
        match *self {
            Obstacle::Box { center, size, .. } => (center, (size[0] / 2.0).hypot(size[1] / 2.0)),
            Obstacle::Cylinder { center, radius, .. } => (center, radius),
        }
    }

    /// The `(sin, cos)` of a box's yaw (`(0, 1)` for a cylinder), for
    /// [`Obstacle::ray_interval_turned`].
    pub fn yaw_sin_cos(&self) -> (f64, f64) {
        match *self {
            Obstacle::Box { yaw_deg, .. } => yaw_deg.to_radians().sin_cos(),
            Obstacle::Cylinder { .. } => (0.0, 1.0),
        }
    }

    /// [`Obstacle::ray_interval`] given the obstacle's
    /// [`Obstacle::yaw_sin_cos`], for callers that cast many rays.
    pub fn ray_interval_turned(
        &self,
        origin: [f64; 2],
        dir: [f64; 2],
        (s, c): (f64, f64),
    ) -> Option<FootprintHit> {
        match *self {
            Obstacle::Box { center, size, .. } => {
                // Into the box's own frame.
                let lo = box_local(center, (s, c), origin);
                let ld = [c * dir[0] + s * dir[1], -s * dir[0] + c * dir[1]];
                let half = [size[0] / 2.0, size[1] / 2.0];
                let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
                let mut local_normal = [0.0, 0.0];
                for k in 0..2 {
                    if ld[k] == 0.0 {
                        if lo[k].abs() > half[k] {
                            return None;
                        }
                        continue;
                    }
                    let a = (-half[k] - lo[k]) / ld[k];
                    let b = (half[k] - lo[k]) / ld[k];
                    let near = a.min(b);
                    if near > t0 {
                        t0 = near;
                        local_normal = [0.0, 0.0];
                        local_normal[k] = -ld[k].signum();
                    }
                    t1 = t1.min(a.max(b));
                }
                if t1 < t0 || t1 < 0.0 {
                    return None;
                }
                let normal = [
                    c * local_normal[0] - s * local_normal[1],
                    s * local_normal[0] + c * local_normal[1],
                ];
                Some(FootprintHit {
                    t_enter: t0,
                    t_exit: t1,
                    normal,
                })
            }
            Obstacle::Cylinder { center, radius, .. } => {
                let ox = origin[0] - center[0];
                let oy = origin[1] - center[1];
                let a = dir[0] * dir[0] + dir[1] * dir[1];
                let b = ox * dir[0] + oy * dir[1];
                let c = ox * ox + oy * oy - radius * radius;
                let disc = b * b - a * c;
                if a == 0.0 || disc < 0.0 {
                    return None;
                }
                let root = disc.sqrt();
                let (t0, t1) = ((-b - root) / a, (-b + root) / a);
                if t1 < 0.0 {
                    return None;
                }
                let px = ox + t0 * dir[0];
                let py = oy + t0 * dir[1];
                let n = px.hypot(py).max(1e-300);
                Some(FootprintHit {
                    t_enter: t0,
                    t_exit: t1,
                    normal: [px / n, py / n],
                })
            }
        }
    }

    /// Distance along the 2D ray `origin + t·dir` (unit `dir`) to where it
    /// first meets the obstacle's footprint at `t ≥ 0`. A ray starting
    /// inside the footprint hits at `t = 0`.
    pub fn ray_hit(&self, origin: [f64; 2], dir: [f64; 2]) -> Option<f64> {
        self.ray_interval(origin, dir).map(|h| h.t_enter.max(0.0))
    }

    /// Distance from a floor point to the outline of the footprint (inside
    /// or outside), metres.
    pub fn outline_distance(&self, p: [f64; 2]) -> f64 {
        match *self {
            Obstacle::Box {
                center,
                size,
                yaw_deg,
                ..
            } => {
                let local = box_local(center, yaw_deg.to_radians().sin_cos(), p);
                let dx = local[0].abs() - size[0] / 2.0;
                let dy = local[1].abs() - size[1] / 2.0;
                if dx > 0.0 || dy > 0.0 {
                    dx.max(0.0).hypot(dy.max(0.0))
                } else {
                    -dx.max(dy)
                }
            }
            Obstacle::Cylinder { center, radius, .. } => {
                ((p[0] - center[0]).hypot(p[1] - center[1]) - radius).abs()
            }
        }
    }

    /// Every number finite, sizes positive.
    pub fn problem(&self) -> Option<String> {
        let ok = match self {
            Obstacle::Box {
                center,
                size,
                yaw_deg,
                height,
                ..
            } => {
                center
                    .iter()
                    .chain(size)
                    .chain([yaw_deg, height])
                    .all(|v| v.is_finite())
                    && size.iter().all(|s| *s > 0.0)
                    && *height > 0.0
            }
            Obstacle::Cylinder {
                center,
                radius,
                height,
                ..
            } => {
                center.iter().chain([radius, height]).all(|v| v.is_finite()) && *radius > 0.0 && *height > 0.0
            }
        };
        (!ok).then(|| "obstacle with a non-finite or non-positive size".to_string())
    }
}

/// A floor point in the frame of a box centred at `center`, turned by
/// `yaw_deg`.
fn box_local(center: [f64; 2], (s, c): (f64, f64), p: [f64; 2]) -> [f64; 2] {
    let (ox, oy) = (p[0] - center[0], p[1] - center[1]);
    [c * ox + s * oy, -s * ox + c * oy]
}

impl World {
    /// Distance from a floor point to the nearest obstacle outline, metres
    /// (infinite in a world without obstacles).
    pub fn outline_distance(&self, p: [f64; 2]) -> f64 {
        self.obstacles
            .iter()
            .map(|o| o.outline_distance(p))
            .fold(f64::INFINITY, f64::min)
    }

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
        let b = Obstacle::Box {
            center: [1.0, 0.0],
            size: [0.2, 0.2],
            yaw_deg: 45.0,
            height: 0.1,
            rgb: [0; 3],
        };
        // A 0.2 m square turned 45° reaches √2·0.1 towards the origin.
        let t = b.ray_hit([0.0, 0.0], [1.0, 0.0]).unwrap();
        assert!((t - (1.0 - 0.1 * 2f64.sqrt())).abs() < 1e-12);
        assert!(b.ray_hit([0.0, 0.0], [0.0, 1.0]).is_none());
        let c = Obstacle::Cylinder {
            center: [0.0, 2.0],
            radius: 0.5,
            height: 0.1,
            rgb: [0; 3],
        };
        assert!((c.ray_hit([0.0, 0.0], [0.0, 1.0]).unwrap() - 1.5).abs() < 1e-12);
        assert!(c.ray_hit([0.0, 0.0], [0.0, -1.0]).is_none());
        assert_eq!(c.ray_hit([0.0, 2.1], [1.0, 0.0]), Some(0.0));
        let h = b.ray_interval([0.0, 0.0], [2.0, 0.0]).unwrap();
        assert!((h.t_enter * 2.0 - (1.0 - 0.1 * 2f64.sqrt())).abs() < 1e-12);
        assert!((h.normal[0] + 0.5f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn outline_distance_inside_and_outside() {
        let b = Obstacle::Box {
            center: [1.0, 0.0],
            size: [0.4, 0.2],
            yaw_deg: 90.0,
            height: 0.1,
            rgb: [0; 3],
        };
        // Turned 90°: 0.2 wide along x, 0.4 along y.
        assert!((b.outline_distance([0.5, 0.0]) - 0.4).abs() < 1e-12);
        assert!((b.outline_distance([1.0, 0.5]) - 0.3).abs() < 1e-12);
        assert!((b.outline_distance([1.4, 0.5]) - 0.3f64.hypot(0.3)).abs() < 1e-12);
        assert!((b.outline_distance([1.05, 0.0]) - 0.05).abs() < 1e-12, "inside");
        let c = Obstacle::Cylinder {
            center: [0.0, 0.0],
            radius: 0.5,
            height: 0.1,
            rgb: [0; 3],
        };
        assert!((c.outline_distance([0.2, 0.0]) - 0.3).abs() < 1e-12);
        assert!((c.outline_distance([0.0, -0.8]) - 0.3).abs() < 1e-12);
        let w = World {
            bounds: [0.0, 0.0, 2.0, 2.0],
            floor_rgb: [0; 3],
            obstacles: vec![b, c],
        };
        assert!((w.outline_distance([0.7, 0.0]) - 0.2).abs() < 1e-12);
    }
}
