//! The ray caster.

use crate::Scene;
use pirouette_camera::PinholeModel;
use pirouette_geom::{Point2, Pose2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;

/// A small disc of lint or reflection lying on the floor.
#[derive(Debug, Clone, Copy)]
struct Speck {
    centre: [f64; 2],
    radius_m: f64,
    rgb: [f64; 3],
}

/// Renders camera images of a scene from robot poses.
#[derive(Debug, Clone)]
pub struct Renderer {
    scene: Scene,
    camera: PinholeModel,
    light: [f64; 3],
    /// Slow floor variation: (kx, ky, phase) per component, rad/m.
    waves: Vec<[f64; 3]>,
    specks: Vec<Speck>,
    /// Which specks may cover each cell of a lattice of [`SPECK_CELL_M`]
    /// over the floor: indices into `specks`, ascending.
    speck_cells: std::collections::HashMap<(i64, i64), Vec<u32>>,
    /// Each obstacle's [`Obstacle::yaw_sin_cos`](pirouette_io::Obstacle::yaw_sin_cos),
    /// and the centre and squared radius of a circle a little wider than
    /// its footprint: a ray whose line passes outside it cannot hit.
    turned: Vec<((f64, f64), [f64; 2], f64)>,
    seed: u64,
}

/// Side of the cells that index the specks, metres.
const SPECK_CELL_M: f64 = 0.05;

/// Side of the fine floor-texture cells, metres.
const TEXTURE_CELL_M: f64 = 0.005;

fn hash01(ix: i64, iy: i64, seed: u64) -> f64 {
    // SplitMix64 over the cell coordinates: a fixed pseudo-random value per cell.
    let mut z = (ix as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (iy as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ seed.wrapping_mul(0x1656_67B1_9E37_79F9);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

impl Renderer {
    /// A renderer of `scene`; `seed` fixes the floor pattern, the specks
    /// and (with the frame index) the sensor noise.
    pub fn new(scene: &Scene, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xF100_0A5E);
        let l = scene.look.light_dir;
        let n = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt().max(1e-12);
        let waves = (0..3)
            .map(|_| {
                let wavelength = rng.random_range(0.6..2.0);
                let dir: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                let k = std::f64::consts::TAU / wavelength;
                [
                    k * dir.cos(),
                    k * dir.sin(),
                    rng.random_range(0.0..std::f64::consts::TAU),
                ]
            })
            .collect();
        let [x0, y0, x1, y1] = scene.world.bounds;
        let area = ((x1 - x0) * (y1 - y0)).abs();
        let count = (area * scene.look.specks_per_m2).round() as usize;
        let specks: Vec<Speck> = (0..count)
            .map(|_| {
                let bright = rng.random_bool(0.5);
                let level = if bright {
                    rng.random_range(200.0..255.0)
                } else {
                    rng.random_range(140.0..200.0)
                };
                Speck {
                    centre: [
                        rng.random_range(x0.min(x1)..x0.max(x1)),
                        rng.random_range(y0.min(y1)..y0.max(y1)),
                    ],
                    radius_m: rng.random_range(0.002..0.005),
                    rgb: [level, level, level * 0.97],
                }
            })
            .collect();
        let mut speck_cells: std::collections::HashMap<(i64, i64), Vec<u32>> = Default::default();
        for (k, s) in specks.iter().enumerate() {
            let cell = |v: f64| (v / SPECK_CELL_M).floor() as i64;
            let (r, [x, y]) = (s.radius_m, s.centre);
            for i in cell(x - r)..=cell(x + r) {
                for j in cell(y - r)..=cell(y + r) {
                    speck_cells.entry((i, j)).or_default().push(k as u32);
                }
            }
        }
        Self {
            camera: scene.camera.pinhole(),
            turned: scene
                .world
                .obstacles
                .iter()
                .map(|o| {
                    let (centre, r) = o.bounding_circle();
                    // Wider by far more than rounding can move a hit.
                    let r = r * (1.0 + 1e-6) + 1e-9;
                    (o.yaw_sin_cos(), centre, r * r)
                })
                .collect(),
            scene: scene.clone(),
            light: [l[0] / n, l[1] / n, l[2] / n],
            waves,
            specks,
            speck_cells,
            seed,
        }
    }

    fn lit(&self, albedo: [f64; 3], normal: [f64; 3]) -> [f64; 3] {
        let a = self.scene.look.ambient;
        let d = (normal[0] * self.light[0] + normal[1] * self.light[1] + normal[2] * self.light[2]).max(0.0);
        let k = a + (1.0 - a) * d;
        albedo.map(|c| c * k)
    }

    fn floor_albedo(&self, x: f64, y: f64) -> [f64; 3] {
        // The first speck covering the point: its cell lists every speck
        // that reaches into it, in order.
        let cell = (
            (x / SPECK_CELL_M).floor() as i64,
            (y / SPECK_CELL_M).floor() as i64,
        );
        if let Some(s) = self.speck_cells.get(&cell).and_then(|list| {
            list.iter()
                .map(|&k| &self.specks[k as usize])
                .find(|s| (x - s.centre[0]).hypot(y - s.centre[1]) <= s.radius_m)
        }) {
            return s.rgb;
        }
        let look = &self.scene.look;
        let slow: f64 = self
            .waves
            .iter()
            .map(|w| (w[0] * x + w[1] * y + w[2]).sin())
            .sum::<f64>()
            / 3.0;
        let (gx, gy) = (x / TEXTURE_CELL_M, y / TEXTURE_CELL_M);
        let (ix, iy) = (gx.floor() as i64, gy.floor() as i64);
        let (fx, fy) = (gx - gx.floor(), gy - gy.floor());
        let h = |dx, dy| hash01(ix + dx, iy + dy, self.seed) * 2.0 - 1.0;
        let grain =
            (h(0, 0) * (1.0 - fx) + h(1, 0) * fx) * (1.0 - fy) + (h(0, 1) * (1.0 - fx) + h(1, 1) * fx) * fy;
        let k = (1.0 + look.floor_variation * slow) * (1.0 + look.floor_texture * grain);
        self.scene.world.floor_rgb.map(|c| c as f64 * k)
    }

    /// The colour (linear, 8-bit scale) seen along a world ray.
    fn shade(&self, origin: [f64; 3], dir: [f64; 3]) -> [f64; 3] {
        let mut best_t = if dir[2] < 0.0 {
            origin[2] / -dir[2]
        } else {
            f64::INFINITY
        };
        let mut hit: Option<([f64; 3], [f64; 3])> = None;
        let d2 = dir[0] * dir[0] + dir[1] * dir[1];
        for (o, &(turned, centre, r2)) in self.scene.world.obstacles.iter().zip(&self.turned) {
            // The ray's line passes the circle's centre at distance
            // |cross| / |dir|.
            let (ox, oy) = (centre[0] - origin[0], centre[1] - origin[1]);
            let cross = ox * dir[1] - oy * dir[0];
            if cross * cross > r2 * d2 {
                continue;
            }
            // Nor can a hit come before the nearest one so far, where even
            // the circle's near side lies beyond it (a hit at t is t·|dir|
            // from the origin, and at least the centre's distance less the
            // radius).
            if best_t.is_finite() {
                let reach = best_t * d2.sqrt() * (1.0 + 1e-9) + r2.sqrt();
                if ox * ox + oy * oy > reach * reach {
                    continue;
                }
            }
            let Some(h) = o.ray_interval_turned([origin[0], origin[1]], [dir[0], dir[1]], turned) else {
                continue;
            };
            if h.t_enter < 0.0 || h.t_enter >= best_t {
                continue;
            }
            let top = o.height();
            let z = origin[2] + h.t_enter * dir[2];
            let albedo = o.rgb().map(f64::from);
            if (0.0..=top).contains(&z) {
                best_t = h.t_enter;
                hit = Some((albedo, [h.normal[0], h.normal[1], 0.0]));
            } else if z > top && dir[2] < 0.0 {
                let t_top = (top - origin[2]) / dir[2];
                if t_top <= h.t_exit && t_top < best_t {
                    best_t = t_top;
                    hit = Some((albedo, [0.0, 0.0, 1.0]));
                }
            }
        }
        match hit {
            Some((albedo, normal)) => self.lit(albedo, normal),
            None if best_t.is_finite() => {
                let x = origin[0] + best_t * dir[0];
                let y = origin[1] + best_t * dir[1];
                self.lit(self.floor_albedo(x, y), [0.0, 0.0, 1.0])
            }
            None => self.scene.backdrop_rgb.map(f64::from),
        }
    }

    /// Renders the image seen from `world_from_robot`; `frame` seeds the
    /// sensor noise.
    #[allow(clippy::expect_used, reason = "the buffer is made for this image size")]
    pub fn render(&self, world_from_robot: &Pose2, frame: u64) -> image::RgbImage {
        let cam = &self.camera;
        let look = &self.scene.look;
        let centre = world_from_robot.transform_point(Point2::new(cam.mount_forward_m, cam.mount_left_m));
        let origin = [centre.x, centre.y, cam.height_m];
        let (s, c) = world_from_robot.theta.sin_cos();
        #[allow(clippy::expect_used, reason = "Scene::validate bounds noise_sigma")]
        let noise = Normal::new(0.0, look.noise_sigma.max(0.0)).expect("noise sigma is finite");
        const SUB: [(f64, f64); 4] = [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)];
        let row_len = cam.width as usize * 3;
        let mut buf = vec![0u8; row_len * cam.height as usize];
        buf.par_chunks_mut(row_len).enumerate().for_each(|(v, row)| {
            // Noise seeded per frame and row: the same image whatever the thread count.
            let row_seed = self
                .seed
                .wrapping_mul(0x9E37_79B9)
                .wrapping_add(frame)
                .wrapping_mul(0x1_0000_0001)
                .wrapping_add(v as u64);
            let mut rng = ChaCha8Rng::seed_from_u64(row_seed);
            for u in 0..cam.width as usize {
                let mut acc = [0.0; 3];
                for (du, dv) in SUB {
                    // A pixel the lens has no ray for stays black.
                    let Some(r) = cam.ray(u as f64 + du, v as f64 + dv) else {
                        continue;
                    };
                    let dir = [c * r[0] - s * r[1], s * r[0] + c * r[1], r[2]];
                    let col = self.shade(origin, dir);
                    for k in 0..3 {
                        acc[k] += col[k] / SUB.len() as f64;
                    }
                }
                let su = (u as f64 - cam.cx) / cam.cx;
                let sv = (v as f64 - cam.cy) / cam.cy;
                let below = sv.max(0.0);
                let gain = look.exposure
                    * (1.0 - look.vignetting * (su * su + sv * sv) / 2.0).max(0.05)
                    * (1.0 - look.corner_darkening * below * below * su * su).max(0.05);
                for k in 0..3 {
                    row[u * 3 + k] = (acc[k] * gain * look.light_rgb[k] + noise.sample(&mut rng))
                        .round()
                        .clamp(0.0, 255.0) as u8;
                }
            }
        });
        image::RgbImage::from_raw(cam.width, cam.height, buf).expect("buffer matches the image size")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pirouette_camera::CameraModel;
    use pirouette_io::Obstacle;

    /// A noise-free, evenly lit scene: one red box ahead on a dark floor.
    fn plain_scene() -> Scene {
        let mut s = Scene::builtin("field-pirouette").unwrap();
        s.world.obstacles = vec![Obstacle::Box {
            center: [0.6, 0.0],
            size: [0.1, 0.4],
            yaw_deg: 0.0,
            height: 0.1,
            rgb: [200, 40, 40],
        }];
        s.look = crate::Look {
            vignetting: 0.0,
            corner_darkening: 0.0,
            floor_variation: 0.0,
            floor_texture: 0.0,
            specks_per_m2: 0.0,
            noise_sigma: 0.0,
            ..Default::default()
        };
        s
    }

    #[test]
    fn obstacle_base_lands_where_the_camera_model_projects_it() {
        let scene = plain_scene();
        let r = Renderer::new(&scene, 1);
        let pose = Pose2::new(0.0, 0.0, 0.0);
        let img = r.render(&pose, 0);
        let cam = scene.camera.pinhole();
        // The box's near face is at x = 0.55: its base projects to row v_base.
        let (_, v_base) = cam.floor_to_pixel(Point2::new(0.55, 0.0)).unwrap();
        let u = 160;
        let below = img.get_pixel(u, (v_base + 2.0).ceil() as u32).0;
        let above = img.get_pixel(u, (v_base - 2.0).floor() as u32).0;
        assert!(below[0] < 60, "floor expected below the base, got {below:?}");
        // The face looks away from the light: ambient only, but still red.
        assert!(
            above[0] > 3 * above[1] && above[0] > below[0] + 40,
            "red box expected above the base, got {above:?}"
        );
    }

    #[test]
    fn specks_noise_and_vignetting_change_the_image() {
        let scene = Scene::builtin("field-pirouette").unwrap();
        let r = Renderer::new(&scene, 1);
        let pose = Pose2::from_deg(0.75, 0.65, 0.0);
        let a = r.render(&pose, 0);
        let b = r.render(&pose, 1);
        assert_ne!(a, b, "sensor noise differs per frame");
        assert_eq!(a, r.render(&pose, 0), "renders are reproducible");
        // Bottom corners are darker than the bottom centre.
        let lum = |p: &image::Rgb<u8>| p.0.iter().map(|&c| c as u32).sum::<u32>();
        let corner: u32 = (0..8)
            .flat_map(|d| [lum(a.get_pixel(d, 239 - d)), lum(a.get_pixel(319 - d, 239 - d))])
            .sum();
        let centre: u32 = (0..8)
            .flat_map(|d| {
                [
                    lum(a.get_pixel(156 + d, 239 - d)),
                    lum(a.get_pixel(160 + d, 239 - d)),
                ]
            })
            .sum();
        assert!(corner * 2 < centre, "corner {corner} centre {centre}");
    }
}
