//! Scores of the engine's results against ground truth.
//!
//! Profiles and sweeps here; trajectories and maps in [`map`].

pub mod laser;
pub mod map;
pub mod relations;
pub mod suite;
pub mod sync;

use pirouette_camera::CameraModel;
use pirouette_geom::Pose2;
use pirouette_io::{TruthRop, World};
use pirouette_profile::Rop;
use serde::Serialize;

/// Relative error within which a range counts as measured well.
pub const WITHIN_REL: f64 = 0.10;

/// Per-bin tallies of measured profiles against true ones.
#[derive(Debug, Clone, Default)]
pub struct ProfileTally {
    /// Relative range errors `(measured − true) / true` over truth bins
    /// that were measured.
    pub rel_errors: Vec<f64>,
    /// Truth bins (a true obstacle within the soft range limit).
    pub truth_bins: usize,
    /// Truth bins measured within [`WITHIN_REL`].
    pub within: usize,
    /// Truth bins with no measured range.
    pub missed: usize,
    /// Bins inside the view with no true obstacle within the limit.
    pub free_bins: usize,
    /// Free bins that were given a range.
    pub false_ranges: usize,
    /// Free bins checked against the scene's geometry (see [`SceneView`]).
    pub scene_checked: usize,
    /// Checked free bins given a range where the scene has no obstacle
    /// within the soft limit anywhere in the bin's view.
    pub scene_false_ranges: usize,
}

/// Rays cast per truth bin when a false range is checked against the
/// scene: about 0.01° apart at 1° bins, finer than a column.
pub const SCENE_RAYS_PER_BIN: usize = 100;

/// The scene behind a frame, for a second look at false ranges.
///
/// A truth profile samples each bin with a few rays, so an obstacle that
/// enters a bin by less than their spacing, or a bin seen only at the
/// image's edge beyond its outermost ray, reads as free there. The scene's
/// geometry, cast densely, tells those from ranges where nothing is.
pub struct SceneView<'a> {
    /// The scene (`truth/world.json`).
    pub world: &'a World,
    /// The camera (what it sees bounds the bins' view).
    pub camera: &'a dyn CameraModel,
    /// The robot's true pose.
    pub world_from_robot: Pose2,
    /// The soft range limit, metres.
    pub max_range_m: f64,
}

impl SceneView<'_> {
    /// Whether some obstacle within the soft limit lies in view at bearings
    /// `[start_rad, start_rad + width_rad)` of the robot.
    pub fn obstacle_in_bin(&self, start_rad: f64, width_rad: f64) -> bool {
        pirouette_sim::nearest_in_view(
            self.world,
            self.camera,
            &self.world_from_robot,
            start_rad,
            width_rad,
            SCENE_RAYS_PER_BIN,
        )
        .is_some_and(|t| t <= self.max_range_m)
    }
}

/// The scores of a [`ProfileTally`].
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ProfileScores {
    /// Median of |relative range error| over measured truth bins.
    pub median_abs_rel_error: f64,
    /// Median of the signed relative range error (negative: ranges short).
    pub median_rel_bias: f64,
    /// Share of truth bins measured within 10 %.
    pub within_10pct: f64,
    /// Share of truth bins missed.
    pub missed: f64,
    /// Share of obstacle-free bins given a false range.
    pub false_range: f64,
    /// Share of obstacle-free bins given a range where the scene, cast
    /// densely, has no obstacle in the bin's view either (null without a
    /// scene).
    pub false_range_scene: Option<f64>,
    /// Truth bins counted.
    pub truth_bins: usize,
    /// Obstacle-free bins counted.
    pub free_bins: usize,
}

fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        (s[n / 2 - 1] + s[n / 2]) / 2.0
    }
}

impl ProfileTally {
    /// Adds one frame: every truth bin against the nearest reliable range
    /// of the measured bins whose centres fall inside it (any bin width).
    pub fn add(&mut self, measured: &Rop, truth: &TruthRop) {
        self.add_with_scene(measured, truth, None);
    }

    /// [`ProfileTally::add`], each false range also checked against the
    /// scene where one is given.
    pub fn add_with_scene(&mut self, measured: &Rop, truth: &TruthRop, scene: Option<&SceneView<'_>>) {
        let w_t = truth.bin_deg.to_radians();
        let t0 = truth.bearing_start_deg.to_radians();
        let mut nearest = vec![None::<f32>; truth.range.len()];
        for i in 0..measured.len() {
            let k = ((measured.bin_centre_rad(i) - t0) / w_t).floor();
            if k < 0.0 || k as usize >= nearest.len() {
                continue;
            }
            if let Some(r) = measured.reliable(i) {
                let slot = &mut nearest[k as usize];
                *slot = Some(slot.map_or(r, |s: f32| s.min(r)));
            }
        }
        for (k, (t, m)) in truth.range.iter().zip(&nearest).enumerate() {
            match (t, m) {
                (Some(t), Some(m)) => {
                    self.truth_bins += 1;
                    let e = (*m as f64 - t) / t;
                    self.rel_errors.push(e);
                    if e.abs() <= WITHIN_REL {
                        self.within += 1;
                    }
                }
                (Some(_), None) => {
                    self.truth_bins += 1;
                    self.missed += 1;
                }
                (None, m) => {
                    self.free_bins += 1;
                    if m.is_some() {
                        self.false_ranges += 1;
                    }
                    if let Some(scene) = scene {
                        self.scene_checked += 1;
                        if m.is_some() && !scene.obstacle_in_bin(t0 + k as f64 * w_t, w_t) {
                            self.scene_false_ranges += 1;
                        }
                    }
                }
            }
        }
    }

    /// Adds another tally.
    pub fn merge(&mut self, other: &ProfileTally) {
        self.rel_errors.extend_from_slice(&other.rel_errors);
        self.truth_bins += other.truth_bins;
        self.within += other.within;
        self.missed += other.missed;
        self.free_bins += other.free_bins;
        self.false_ranges += other.false_ranges;
        self.scene_checked += other.scene_checked;
        self.scene_false_ranges += other.scene_false_ranges;
    }

    /// The scores.
    pub fn scores(&self) -> ProfileScores {
        let share = |a: usize, b: usize| if b == 0 { f64::NAN } else { a as f64 / b as f64 };
        let abs: Vec<f64> = self.rel_errors.iter().map(|e| e.abs()).collect();
        ProfileScores {
            median_abs_rel_error: median(&abs),
            median_rel_bias: median(&self.rel_errors),
            within_10pct: share(self.within, self.truth_bins),
            missed: share(self.missed, self.truth_bins),
            false_range: share(self.false_ranges, self.free_bins),
            // Only when every free bin was checked.
            false_range_scene: (self.scene_checked == self.free_bins && self.free_bins > 0)
                .then(|| share(self.scene_false_ranges, self.free_bins)),
            truth_bins: self.truth_bins,
            free_bins: self.free_bins,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tally_counts_each_case() {
        let truth = TruthRop {
            bearing_start_deg: -2.0,
            bin_deg: 1.0,
            range: vec![Some(0.5), Some(0.5), None, None],
        };
        let mut m = Rop::empty(-2f64.to_radians(), 0.5f64.to_radians(), 8, 0.9);
        m.range_m = vec![0.52, 0.6, f32::NAN, f32::NAN, 0.3, f32::INFINITY, 1.5, f32::NAN];
        let mut t = ProfileTally::default();
        t.add(&m, &truth);
        // Bin 0: nearest of 0.52 and 0.6 → +4 %. Bin 1: missed. Bin 2: false
        // range 0.3. Bin 3: 1.5 is beyond the soft limit, not a range.
        assert_eq!(
            (t.truth_bins, t.within, t.missed, t.free_bins, t.false_ranges),
            (2, 1, 1, 2, 1)
        );
        let s = t.scores();
        assert!((s.median_abs_rel_error - 0.04).abs() < 1e-6);
        assert_eq!(s.missed, 0.5);
        assert_eq!(s.false_range_scene, None, "no scene, no second look");
    }

    /// A wall whose end enters bin [0°, 1°) by 0.03°, between the first of
    /// nine sampling rays (at 0.056°) and the bin's edge: a truth profile
    /// of nine rays calls the bin free, the scene does not. Bin [2°, 3°)
    /// has nothing at all.
    #[test]
    fn false_ranges_are_checked_against_the_scene() {
        let (x, y_max, y_min) = (
            0.5,
            0.5 * 0.03f64.to_radians().tan(),
            -0.5 * 5f64.to_radians().tan(),
        );
        let world = World {
            bounds: [-2.0, -2.0, 2.0, 2.0],
            floor_rgb: [30, 30, 30],
            obstacles: vec![pirouette_io::Obstacle::Box {
                center: [x + 0.05, (y_max + y_min) / 2.0],
                size: [0.1, y_max - y_min],
                yaw_deg: 0.0,
                height: 0.1,
                rgb: [200, 200, 200],
            }],
        };
        // The paper's camera: 320 × 240, 60° across, 10 cm up, 25° down.
        let camera = pirouette_sim::CameraSetup::default().pinhole();
        let scene = SceneView {
            world: &world,
            camera: &camera,
            world_from_robot: Pose2::new(0.0, 0.0, 0.0),
            max_range_m: 0.9,
        };
        let nine_rays_hit = (0..9).any(|k| {
            let b = ((k as f64 + 0.5) / 9.0).to_radians();
            world.ray_cast([0.0, 0.0], [b.cos(), b.sin()]).is_some()
        });
        assert!(!nine_rays_hit, "the sliver lies between the sampling rays");
        let truth = TruthRop {
            bearing_start_deg: 0.0,
            bin_deg: 1.0,
            range: vec![None, None, None],
        };
        let mut m = Rop::empty(0.0, 1f64.to_radians(), 3, 0.9);
        m.range_m = vec![0.5, f32::INFINITY, 0.4];
        let mut t = ProfileTally::default();
        t.add_with_scene(&m, &truth, Some(&scene));
        assert_eq!((t.free_bins, t.false_ranges, t.scene_false_ranges), (3, 2, 1));
        assert_eq!(t.scores().false_range_scene, Some(1.0 / 3.0));
    }
}

/// Turn errors of one dataset's sweeps against true headings.
#[derive(Debug, Clone, Default)]
pub struct SweepTally {
    /// |estimated − true| over verified turns, radians.
    pub verified_errors: Vec<f64>,
    /// |estimated − true| over every turn (fallbacks use the command), radians.
    pub all_errors: Vec<f64>,
    /// |commanded − true| over every turn, radians.
    pub commanded_errors: Vec<f64>,
    /// Turns that fell back to the command.
    pub fallbacks: usize,
    /// Verified turns that the loop closure fixed rather than a match of
    /// their own (see [`pirouette_profile::matching::Evidence::Loop`]).
    pub loop_fixed: usize,
    /// Verified turns with an error above 3°.
    pub wrong_verified: usize,
    /// |heading error| accumulated from each sweep's first to last frame,
    /// estimated and commanded, radians.
    pub sweep_heading_errors: Vec<(f64, f64)>,
}

/// The scores of a [`SweepTally`].
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SweepScores {
    /// Turns evaluated.
    pub turns: usize,
    /// Share of turns verified (not a fallback).
    pub verified: f64,
    /// Verified turns that the loop closure fixed (no match of their own).
    pub loop_fixed: usize,
    /// Median |error| of verified turns, degrees.
    pub median_verified_error_deg: f64,
    /// 95th percentile |error| of verified turns, degrees.
    pub p95_verified_error_deg: f64,
    /// Largest |error| of a verified turn, degrees.
    pub max_verified_error_deg: f64,
    /// Verified turns with an error above 3°.
    pub wrong_verified: usize,
    /// Median |error| of all turns (fallbacks at the command), degrees.
    pub median_error_deg: f64,
    /// Median |error| of the commanded turns, degrees.
    pub median_commanded_error_deg: f64,
    /// Median |heading error| accumulated over a sweep, estimated, degrees.
    pub median_sweep_heading_error_deg: f64,
    /// Median |heading error| accumulated over a sweep, commanded, degrees.
    pub median_sweep_commanded_heading_error_deg: f64,
}

fn percentile(v: &[f64], p: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let idx = ((s.len() - 1) as f64 * p).round() as usize;
    s[idx]
}

impl SweepTally {
    /// Adds one sweep: `truth_theta_rad[k]` is the true heading of its
    /// frame `k`, `commanded_rad[k]` the commanded turn before it.
    pub fn add(
        &mut self,
        sweep: &pirouette_profile::sweep::Sweep,
        truth_theta_rad: &[f64],
        commanded_rad: &[Option<f64>],
    ) {
        use pirouette_geom::wrap_angle;
        let mut cmd_heading = 0.0;
        for k in 1..truth_theta_rad.len() {
            let (Some(t), Some(cmd)) = (sweep.turns[k], commanded_rad[k]) else {
                continue;
            };
            let true_turn = wrap_angle(truth_theta_rad[k] - truth_theta_rad[k - 1]);
            let err = wrap_angle(t.turn_rad - true_turn).abs();
            self.all_errors.push(err);
            self.commanded_errors.push(wrap_angle(cmd - true_turn).abs());
            cmd_heading += cmd;
            if t.fallback {
                self.fallbacks += 1;
            } else {
                self.loop_fixed += (t.evidence == pirouette_profile::matching::Evidence::Loop) as usize;
                self.verified_errors.push(err);
                if err > 3f64.to_radians() {
                    self.wrong_verified += 1;
                }
            }
        }
        if let (Some(&first), Some(&last), Some(&est)) = (
            truth_theta_rad.first(),
            truth_theta_rad.last(),
            sweep.heading_rad.last(),
        ) {
            let true_heading = wrap_angle(last - first);
            self.sweep_heading_errors.push((
                wrap_angle(est - true_heading).abs(),
                wrap_angle(cmd_heading - true_heading).abs(),
            ));
        }
    }

    /// Adds another tally.
    pub fn merge(&mut self, o: &SweepTally) {
        self.verified_errors.extend_from_slice(&o.verified_errors);
        self.all_errors.extend_from_slice(&o.all_errors);
        self.commanded_errors.extend_from_slice(&o.commanded_errors);
        self.fallbacks += o.fallbacks;
        self.loop_fixed += o.loop_fixed;
        self.wrong_verified += o.wrong_verified;
        self.sweep_heading_errors
            .extend_from_slice(&o.sweep_heading_errors);
    }

    /// The scores.
    pub fn scores(&self) -> SweepScores {
        let deg = |x: f64| x.to_degrees();
        let turns = self.all_errors.len();
        let est: Vec<f64> = self.sweep_heading_errors.iter().map(|e| e.0).collect();
        let cmd: Vec<f64> = self.sweep_heading_errors.iter().map(|e| e.1).collect();
        SweepScores {
            turns,
            verified: if turns == 0 {
                f64::NAN
            } else {
                self.verified_errors.len() as f64 / turns as f64
            },
            loop_fixed: self.loop_fixed,
            median_verified_error_deg: deg(median(&self.verified_errors)),
            p95_verified_error_deg: deg(percentile(&self.verified_errors, 0.95)),
            max_verified_error_deg: deg(self.verified_errors.iter().copied().fold(0.0, f64::max)),
            wrong_verified: self.wrong_verified,
            median_error_deg: deg(median(&self.all_errors)),
            median_commanded_error_deg: deg(median(&self.commanded_errors)),
            median_sweep_heading_error_deg: deg(median(&est)),
            median_sweep_commanded_heading_error_deg: deg(median(&cmd)),
        }
    }
}

/// Tallies the sweeps of a dataset against its true headings; `None` when
/// some frame has no true pose.
pub fn tally_sweeps(ds: &pirouette_io::Dataset, sweeps: &[crate::frame::DatasetSweep]) -> Option<SweepTally> {
    let truth = ds.truth_poses()?;
    let mut tally = SweepTally::default();
    for s in sweeps {
        let theta: Vec<f64> = s.frames.iter().map(|&i| truth[i].theta).collect();
        let commanded = crate::pipeline::commanded_turns(|i| ds.manifest.frames[i].motion, &s.frames);
        tally.add(&s.sweep, &theta, &commanded);
    }
    Some(tally)
}
