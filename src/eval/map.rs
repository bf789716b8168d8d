//! Trajectories and maps against ground truth.

use anyhow::{Context, Result};
use pirouette_geom::{wrap_angle, Point2, Pose2};
use pirouette_grid::{GridConfig, RosMap, OCCUPIED};
use pirouette_io::{map_names, read_poses, read_ros_map, Dataset, World};
use serde::Serialize;
use std::collections::HashSet;
use std::path::Path;

/// The error of one sweep's first frame (anchored).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SweepError {
    /// The sweep's id.
    pub sweep: u32,
    /// Position error, metres.
    pub position_error_m: f64,
    /// Heading error, degrees.
    pub heading_error_deg: f64,
}

/// Everything `pirouette eval map` measures.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct MapReport {
    /// The dataset's name.
    pub dataset: String,
    /// The map's trajectory against truth.
    pub trajectory: TrajectoryScores,
    /// The commanded motion's trajectory against truth.
    pub commanded: TrajectoryScores,
    /// Per sweep, its first frame's error.
    pub sweeps: Vec<SweepError>,
    /// The trajectory's best-fit rigid alignment onto the true one.
    pub alignment: Alignment,
    /// The point the robot turns about, as mapping took it from the turns
    /// and as the true poses fit it.
    pub pivot: PivotScores,
    /// The map against the scene, where the dataset has one
    /// (`truth/world.json`; a real camera's recording has only its
    /// trajectory's truth). Its fields stand beside the others in JSON.
    #[serde(flatten)]
    pub scene: Option<SceneScores>,
    /// The profiles placed at the true poses: the share of their
    /// obstacle points that another view, from elsewhere, puts in the
    /// same place ([`profile_agreement`]); a figure of the profiles
    /// alone, with or without a scene.
    pub profile_agreement: ProfileAgreement,
    /// The truth's clock as found from the images, where the dataset's
    /// truth keeps another clock than its stamps
    /// ([`crate::eval::sync`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub clock: Option<crate::eval::sync::Clock>,
}

/// A map against its scene ([`MapReport::scene`]).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SceneScores {
    /// The map's occupied cells against the scene, in the map frame (the
    /// true first frame).
    pub map: MapQuality,
    /// The same after the trajectory's best-fit rigid alignment
    /// ([`MapReport::alignment`]).
    pub map_aligned: MapQuality,
    /// The same for a map of the same profiles from the true poses.
    pub true_pose_map: MapQuality,
    /// `map.f1 / true_pose_map.f1`.
    pub f1_ratio: f64,
    /// `map_aligned.f1 / true_pose_map.f1`.
    pub f1_ratio_aligned: f64,
    /// Distance within which an occupied cell matches an outline, metres.
    pub tolerance_m: f64,
}

/// The best-fit rigid alignment of an estimated trajectory onto the true
/// one, map frame: a map whose shape is right but whose first frame erred
/// is turned and moved by about that frame's error.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Alignment {
    /// Rotation, degrees (counter-clockwise).
    pub heading_deg: f64,
    /// Where it moves the map frame's origin, metres.
    pub shift_m: f64,
    /// The scale of the best-fit similarity of the trajectory onto the
    /// truth ([`similarity_scale`]): above 1 where the map came out too
    /// small, below 1 where too large. The profiles' ranges are metric, so
    /// it is an error of mapping, not of units.
    pub scale: f64,
}

/// The point the robot turns about, in its own frame (x forward, y left),
/// millimetres.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct PivotScores {
    /// What mapping used (measured from the verified turns).
    pub estimated_mm: [f64; 2],
    /// The least-squares fit to the true poses (each sweep's frames at
    /// one point minus the pivot turned by their heading); `None` with too
    /// few frames.
    pub true_mm: Option<[f64; 2]>,
}

/// The pivot, millimetres, that true poses fit: each frame (of sweep
/// `sweep_of[i]`) at `c_s − R(θ)·p`, a centre `c_s` per sweep and one `p`
/// for the robot, least squares.
pub fn true_pivot(sweep_of: &[u32], truth: &[Pose2]) -> Option<[f64; 2]> {
    assert_eq!(sweep_of.len(), truth.len(), "one sweep per pose");
    let mut sweeps: Vec<u32> = sweep_of.to_vec();
    sweeps.sort_unstable();
    sweeps.dedup();
    let unknowns = 2 * sweeps.len() + 2;
    if 2 * truth.len() <= unknowns {
        return None;
    }
    let mut a = nalgebra::DMatrix::<f64>::zeros(2 * truth.len(), unknowns);
    let mut b = nalgebra::DVector::<f64>::zeros(2 * truth.len());
    for (i, (sweep, t)) in sweep_of.iter().zip(truth).enumerate() {
        let s = sweeps.binary_search(sweep).expect("listed");
        let (sin, cos) = t.theta.sin_cos();
        a[(2 * i, 2 * s)] = 1.0;
        a[(2 * i, unknowns - 2)] = -cos;
        a[(2 * i, unknowns - 1)] = sin;
        b[2 * i] = t.x;
        a[(2 * i + 1, 2 * s + 1)] = 1.0;
        a[(2 * i + 1, unknowns - 2)] = -sin;
        a[(2 * i + 1, unknowns - 1)] = -cos;
        b[2 * i + 1] = t.y;
    }
    let x = a.svd(true, true).solve(&b, 1e-9).ok()?;
    Some([x[unknowns - 2] * 1000.0, x[unknowns - 1] * 1000.0])
}

/// What a map was made of, for the true-pose map beside it.
#[derive(Debug, Clone, Copy)]
pub struct MapInputs<'a> {
    /// One profile per frame.
    pub frames: &'a [crate::frame::Frame],
    /// The camera's blind distance, metres.
    pub blind_m: f64,
    /// The bearings the camera sees, radians.
    pub span_rad: (f64, f64),
    /// The grid settings the map was made with.
    pub grid: &'a GridConfig,
    /// The point the robot turned about, metres (robot frame).
    pub pivot_m: [f64; 2],
}

/// The true poses re-expressed in the map frame (relative to the true first
/// frame), or an error naming the manifest.
pub fn truth_in_map_frame(ds: &Dataset) -> Result<Vec<Pose2>> {
    let truth = ds.truth_poses().with_context(|| {
        format!(
            "{}: frames without truth poses cannot be evaluated",
            ds.manifest_path().display()
        )
    })?;
    let origin_inv = truth[0].inverse();
    Ok(truth.iter().map(|t| origin_inv * *t).collect())
}

/// Evaluates the map folder `dir` that `pirouette map` wrote for `ds`:
/// trajectory against the true poses, map against `truth/world.json`
/// (occupied cells within `tolerance_cells` of an outline), beside the
/// commanded motion and a map of the same profiles from the true poses.
pub fn evaluate_map_dir(
    ds: &Dataset,
    dir: &Path,
    inputs: MapInputs,
    tolerance_cells: f64,
) -> Result<MapReport> {
    let truth = truth_in_map_frame(ds)?;
    let world_truth = ds.truth_poses().expect("checked by truth_in_map_frame");
    let estimated = estimated_poses(ds, dir)?;
    let trajectory = trajectory_scores(&estimated, &truth);
    let commanded = trajectory_scores(
        &crate::mapping::dead_reckoning(&crate::frame::camera_motions(ds)),
        &truth,
    );
    let sweeps = sweep_errors(ds, &estimated, &truth);
    let est: Vec<Point2> = estimated.iter().map(Pose2::translation).collect();
    let tru: Vec<Point2> = truth.iter().map(Pose2::translation).collect();
    let align = align_rigid(&est, &tru);
    let scene = match ds.world()? {
        Some(world) => Some(scene_scores(
            ds,
            dir,
            &inputs,
            &world,
            &world_truth,
            &truth,
            &align,
            tolerance_cells,
        )?),
        None => None,
    };
    Ok(MapReport {
        dataset: ds.label(),
        trajectory,
        commanded,
        sweeps,
        alignment: Alignment {
            heading_deg: align.theta.to_degrees(),
            shift_m: align.translation().norm(),
            scale: similarity_scale(&est, &tru),
        },
        pivot: PivotScores {
            estimated_mm: inputs.pivot_m.map(|v| v * 1000.0),
            true_mm: true_pivot(
                &ds.manifest.frames.iter().map(|f| f.sweep).collect::<Vec<_>>(),
                &world_truth,
            ),
        },
        scene,
        profile_agreement: profile_agreement(
            &inputs.frames.iter().map(|f| &f.rop).collect::<Vec<_>>(),
            &world_truth,
        ),
        clock: None,
    })
}

/// The map folder `dir`'s grid against the scene `world`: in the map
/// frame, after the trajectory's alignment `align`, and a map of the
/// same profiles from the true poses beside.
#[allow(clippy::too_many_arguments)]
fn scene_scores(
    ds: &Dataset,
    dir: &Path,
    inputs: &MapInputs,
    world: &World,
    world_truth: &[Pose2],
    truth: &[Pose2],
    align: &Pose2,
    tolerance_cells: f64,
) -> Result<SceneScores> {
    let ros = read_ros_map(&dir.join(map_names::YAML))?;
    // Occupied cells into the world through the true first pose.
    let tolerance_m = tolerance_cells * ros.resolution_m;
    let visible = visible_outline(
        world,
        world_truth,
        inputs.span_rad,
        inputs.blind_m,
        ds.manifest.max_range,
        ros.resolution_m,
    );
    let to_world = |map: &RosMap| -> Vec<Point2> {
        occupied_centres(map)
            .into_iter()
            .map(|p| world_truth[0].transform_point(p))
            .collect()
    };
    let map = map_quality(&to_world(&ros), world, &visible, tolerance_m);
    // The same map moved by the trajectory's best-fit alignment: its shape,
    // whatever the first frame's own error.
    let aligned: Vec<Point2> = occupied_centres(&ros)
        .into_iter()
        .map(|p| world_truth[0].transform_point(align.transform_point(p)))
        .collect();
    let map_aligned = map_quality(&aligned, world, &visible, tolerance_m);
    let true_grid = crate::mapping::map_with_poses(
        inputs.frames.iter().map(|f| &f.rop),
        truth,
        inputs.blind_m,
        inputs.grid,
    )?;
    let true_pose_map = map_quality(
        &to_world(&RosMap::from_grid(&true_grid)),
        world,
        &visible,
        tolerance_m,
    );
    Ok(SceneScores {
        f1_ratio: map.f1 / true_pose_map.f1,
        f1_ratio_aligned: map_aligned.f1 / true_pose_map.f1,
        map,
        map_aligned,
        true_pose_map,
        tolerance_m,
    })
}

/// The pose of every frame of `ds` that the map folder `dir` holds, in
/// manifest order.
fn estimated_poses(ds: &Dataset, dir: &Path) -> Result<Vec<Pose2>> {
    let poses_path = dir.join(map_names::POSES_JSON);
    let records = read_poses(&poses_path)?;
    let by_image: std::collections::HashMap<&str, Pose2> = records
        .iter()
        .filter_map(|r| r.image.as_deref().map(|i| (i, r.pose())))
        .collect();
    ds.manifest
        .frames
        .iter()
        .map(|f| {
            by_image
                .get(f.image.as_str())
                .copied()
                .with_context(|| format!("{}: no pose for frame {}", poses_path.display(), f.image))
        })
        .collect()
}

/// Each sweep's error: its first frame's estimated pose against the true
/// one.
fn sweep_errors(ds: &Dataset, estimated: &[Pose2], truth: &[Pose2]) -> Vec<SweepError> {
    let mut sweeps = Vec::new();
    let mut seen = HashSet::new();
    for (i, f) in ds.manifest.frames.iter().enumerate() {
        if seen.insert(f.sweep) {
            let e = truth[i].between(&estimated[i]);
            sweeps.push(SweepError {
                sweep: f.sweep,
                position_error_m: e.translation().norm(),
                heading_error_deg: e.theta.to_degrees(),
            });
        }
    }
    sweeps
}

/// Errors of an estimated trajectory against the true one, both in the
/// map frame (the true poses re-expressed relative to the true first
/// frame).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct TrajectoryScores {
    /// Poses compared.
    pub poses: usize,
    /// RMSE of positions after the best-fit rigid alignment, metres.
    pub ate_aligned_m: f64,
    /// RMSE of positions as estimated (anchored at the first frame), metres.
    pub ate_anchored_m: f64,
    /// Largest anchored position error, metres.
    pub max_anchored_m: f64,
    /// RMSE of anchored headings, degrees.
    pub heading_rmse_deg: f64,
    /// The turn between consecutive poses against the true turn: median
    /// and 95th percentile of the absolute error, degrees (0 with fewer
    /// than two poses).
    pub turn_error_median_deg: f64,
    /// See `turn_error_median_deg`.
    pub turn_error_p95_deg: f64,
    /// Where the true heading has turned through a full 360° (summed
    /// step by step): the error of the heading turned by then, degrees;
    /// `None` when the truth never turns that far.
    pub heading_after_full_turn_deg: Option<f64>,
}

/// The rigid transform `T` minimising `Σ |T·a_i − b_i|²` (2D, no scale):
/// centroids matched, rotation from the cross-covariance.
pub fn align_rigid(a: &[Point2], b: &[Point2]) -> Pose2 {
    assert_eq!(a.len(), b.len(), "paired points");
    if a.is_empty() {
        return Pose2::IDENTITY;
    }
    let n = a.len() as f64;
    let ca = a
        .iter()
        .fold(Point2::new(0.0, 0.0), |s, p| Point2::new(s.x + p.x, s.y + p.y));
    let cb = b
        .iter()
        .fold(Point2::new(0.0, 0.0), |s, p| Point2::new(s.x + p.x, s.y + p.y));
    let (ca, cb) = (Point2::new(ca.x / n, ca.y / n), Point2::new(cb.x / n, cb.y / n));
    let (mut sin, mut cos) = (0.0, 0.0);
    for (p, q) in a.iter().zip(b) {
        let (ax, ay) = (p.x - ca.x, p.y - ca.y);
        let (bx, by) = (q.x - cb.x, q.y - cb.y);
        cos += ax * bx + ay * by;
        sin += ax * by - ay * bx;
    }
    let theta = sin.atan2(cos);
    let rot = Pose2::new(0.0, 0.0, theta);
    let rca = rot.transform_point(ca);
    Pose2::new(cb.x - rca.x, cb.y - rca.y, theta)
}

/// The scale `s` of the similarity `b ≈ s·R·a + t` that fits paired points
/// best in least squares (Umeyama's, in 2D): the length of the centred
/// cross-covariance (its rotation taken out) over the spread of `a`. 1 when
/// `a` has no spread.
pub fn similarity_scale(a: &[Point2], b: &[Point2]) -> f64 {
    assert_eq!(a.len(), b.len(), "paired points");
    let n = a.len().max(1) as f64;
    let centre = |v: &[Point2]| {
        let s = v.iter().fold((0.0, 0.0), |s, p| (s.0 + p.x, s.1 + p.y));
        (s.0 / n, s.1 / n)
    };
    let (ca, cb) = (centre(a), centre(b));
    let (mut sin, mut cos, mut spread) = (0.0, 0.0, 0.0);
    for (p, q) in a.iter().zip(b) {
        let (ax, ay) = (p.x - ca.0, p.y - ca.1);
        let (bx, by) = (q.x - cb.0, q.y - cb.1);
        cos += ax * bx + ay * by;
        sin += ax * by - ay * bx;
        spread += ax * ax + ay * ay;
    }
    if spread > 0.0 {
        sin.hypot(cos) / spread
    } else {
        1.0
    }
}

/// Scores `estimated` against `truth` (paired, map frame).
pub fn trajectory_scores(estimated: &[Pose2], truth: &[Pose2]) -> TrajectoryScores {
    assert_eq!(estimated.len(), truth.len(), "paired poses");
    let n = estimated.len().max(1) as f64;
    let est: Vec<Point2> = estimated.iter().map(Pose2::translation).collect();
    let tru: Vec<Point2> = truth.iter().map(Pose2::translation).collect();
    let anchored: Vec<f64> = est.iter().zip(&tru).map(|(a, b)| a.distance(*b)).collect();
    let align = align_rigid(&est, &tru);
    let aligned_sq: f64 = est
        .iter()
        .zip(&tru)
        .map(|(a, b)| align.transform_point(*a).distance(*b).powi(2))
        .sum();
    let heading_sq: f64 = estimated
        .iter()
        .zip(truth)
        .map(|(a, b)| wrap_angle(a.theta - b.theta).powi(2))
        .sum();
    let step = |p: &[Pose2], k: usize| wrap_angle(p[k + 1].theta - p[k].theta);
    let mut turn_errors: Vec<f64> = (0..estimated.len().saturating_sub(1))
        .map(|k| wrap_angle(step(estimated, k) - step(truth, k)).abs().to_degrees())
        .collect();
    turn_errors.sort_by(f64::total_cmp);
    let quantile = |q: f64| {
        (!turn_errors.is_empty()).then(|| turn_errors[((turn_errors.len() - 1) as f64 * q).round() as usize])
    };
    let (mut turned, mut turned_est) = (0.0f64, 0.0f64);
    let mut heading_after_full_turn_deg = None;
    for k in 0..estimated.len().saturating_sub(1) {
        turned += step(truth, k);
        turned_est += step(estimated, k);
        if turned.abs() >= std::f64::consts::TAU {
            heading_after_full_turn_deg = Some((turned_est - turned).abs().to_degrees());
            break;
        }
    }
    TrajectoryScores {
        poses: estimated.len(),
        ate_aligned_m: (aligned_sq / n).sqrt(),
        ate_anchored_m: (anchored.iter().map(|e| e * e).sum::<f64>() / n).sqrt(),
        max_anchored_m: anchored.iter().copied().fold(0.0, f64::max),
        heading_rmse_deg: (heading_sq / n).sqrt().to_degrees(),
        turn_error_median_deg: quantile(0.5).unwrap_or(0.0),
        turn_error_p95_deg: quantile(0.95).unwrap_or(0.0),
        heading_after_full_turn_deg,
    }
}

/// How far apart two views must be for their agreement to count:
/// metres ...
pub const AGREEMENT_BASELINE_M: f64 = 0.5;
/// ... or radians of heading (an eighth of a turn).
pub const AGREEMENT_TURN_RAD: f64 = std::f64::consts::FRAC_PI_4;
/// Within this, two views' points agree, metres.
pub const AGREEMENT_TOLERANCE_M: f64 = 0.10;

/// [`profile_agreement`]'s figure.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct ProfileAgreement {
    /// Obstacle points of all the profiles (a range within the limit).
    pub points: usize,
    /// Of those with a view from elsewhere (at least
    /// [`AGREEMENT_BASELINE_M`] away or [`AGREEMENT_TURN_RAD`] turned)
    /// whose point lies within [`AGREEMENT_TOLERANCE_M`], the share.
    pub share: f64,
}

/// Walls in one place: each profile's obstacle points placed at its true
/// pose, and the share of them that a view from elsewhere (another place
/// or heading) also puts within 10 cm. A wall is seen where it is from
/// everywhere; a false obstacle (a stain taken for a wall's foot) lies at
/// a range that moves with the robot, and only chance puts another view's
/// there.
pub fn profile_agreement(rops: &[&pirouette_profile::Rop], poses: &[Pose2]) -> ProfileAgreement {
    use std::collections::HashMap;
    let cell = |p: Point2| {
        (
            (p.x / AGREEMENT_TOLERANCE_M).floor() as i64,
            (p.y / AGREEMENT_TOLERANCE_M).floor() as i64,
        )
    };
    let mut points: Vec<(usize, Point2)> = Vec::new();
    for (i, (rop, pose)) in rops.iter().zip(poses).enumerate() {
        for b in 0..rop.len() {
            if let Some(r) = rop.reliable(b) {
                let (s, c) = rop.bin_centre_rad(b).sin_cos();
                points.push((
                    i,
                    pose.transform_point(Point2::new(f64::from(r) * c, f64::from(r) * s)),
                ));
            }
        }
    }
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (k, &(_, p)) in points.iter().enumerate() {
        grid.entry(cell(p)).or_default().push(k);
    }
    let elsewhere = |i: usize, j: usize| {
        poses[i].translation().distance(poses[j].translation()) >= AGREEMENT_BASELINE_M
            || wrap_angle(poses[i].theta - poses[j].theta).abs() >= AGREEMENT_TURN_RAD
    };
    let agreed = (points.iter())
        .filter(|&&(i, p)| {
            let (cx, cy) = cell(p);
            (cx - 1..=cx + 1).any(|x| {
                (cy - 1..=cy + 1).any(|y| {
                    grid.get(&(x, y)).is_some_and(|ks| {
                        ks.iter().any(|&k| {
                            let (j, q) = points[k];
                            q.distance(p) <= AGREEMENT_TOLERANCE_M && elsewhere(i, j)
                        })
                    })
                })
            })
        })
        .count();
    ProfileAgreement {
        points: points.len(),
        share: if points.is_empty() {
            0.0
        } else {
            agreed as f64 / points.len() as f64
        },
    }
}

/// Quality of a map's occupied cells against the true obstacles.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct MapQuality {
    /// Occupied cells in the map.
    pub occupied_cells: usize,
    /// Share of occupied cells whose centre lies within the tolerance of a
    /// true obstacle outline.
    pub precision: f64,
    /// Cells of true obstacle outline the robot could see from its true
    /// positions.
    pub visible_edge_cells: usize,
    /// Share of those with an occupied map cell within the tolerance.
    pub recall: f64,
    /// Harmonic mean of precision and recall.
    pub f1: f64,
}

/// Centres of a map's occupied cells, map frame.
pub fn occupied_centres(map: &RosMap) -> Vec<Point2> {
    let s = map.resolution_m;
    map.pixels
        .iter()
        .enumerate()
        .filter(|(_, &p)| p == OCCUPIED)
        .map(|(k, _)| {
            let (col, row) = (k % map.width, k / map.width);
            let j = map.height - 1 - row;
            Point2::new(
                map.origin_m[0] + (col as f64 + 0.5) * s,
                map.origin_m[1] + (j as f64 + 0.5) * s,
            )
        })
        .collect()
}

/// The true obstacle outline a robot could see: from each pose (world
/// frame, robot centre), rays over the view's bearings `span_rad` at steps
/// that leave no cell of `cell_m` unvisited at `max_range_m`; hits between
/// `blind_m` and `max_range_m`, one point per cell (world frame, sorted).
pub fn visible_outline(
    world: &World,
    poses: &[Pose2],
    span_rad: (f64, f64),
    blind_m: f64,
    max_range_m: f64,
    cell_m: f64,
) -> Vec<Point2> {
    let step = 0.5 * cell_m / max_range_m;
    let rays = ((span_rad.1 - span_rad.0) / step).ceil().max(1.0) as usize;
    let mut cells: HashSet<(i64, i64)> = HashSet::new();
    let mut out = Vec::new();
    for pose in poses {
        for k in 0..=rays {
            let bearing = span_rad.0 + (span_rad.1 - span_rad.0) * k as f64 / rays as f64;
            let dir = pose.rotate_vector(Point2::from_polar(1.0, bearing));
            let Some((t, _)) = world.ray_cast([pose.x, pose.y], [dir.x, dir.y]) else {
                continue;
            };
            if t < blind_m || t > max_range_m {
                continue;
            }
            let p = Point2::new(pose.x + t * dir.x, pose.y + t * dir.y);
            if cells.insert(((p.x / cell_m).floor() as i64, (p.y / cell_m).floor() as i64)) {
                out.push(p);
            }
        }
    }
    out.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    out
}

/// Precision, recall and F1 of occupied cell centres `occupied` against
/// the true `world` and its `visible` outline (all in the world frame),
/// within `tolerance_m`.
pub fn map_quality(occupied: &[Point2], world: &World, visible: &[Point2], tolerance_m: f64) -> MapQuality {
    let true_cells = occupied
        .iter()
        .filter(|p| world.outline_distance([p.x, p.y]) <= tolerance_m)
        .count();
    let precision = if occupied.is_empty() {
        0.0
    } else {
        true_cells as f64 / occupied.len() as f64
    };
    // Occupied centres bucketed by the tolerance, so each query looks at
    // the 3 × 3 buckets around it.
    let key = |p: &Point2| {
        (
            (p.x / tolerance_m).floor() as i64,
            (p.y / tolerance_m).floor() as i64,
        )
    };
    let mut buckets: std::collections::HashMap<(i64, i64), Vec<Point2>> = Default::default();
    for p in occupied {
        buckets.entry(key(p)).or_default().push(*p);
    }
    let found = visible
        .iter()
        .filter(|v| {
            let (i, j) = key(v);
            (-1..=1).any(|di| {
                (-1..=1).any(|dj| {
                    buckets
                        .get(&(i + di, j + dj))
                        .is_some_and(|b| b.iter().any(|p| p.distance(**v) <= tolerance_m))
                })
            })
        })
        .count();
    let recall = if visible.is_empty() {
        0.0
    } else {
        found as f64 / visible.len() as f64
    };
    let f1 = if precision + recall > 0.0 {
        2.0 * precision * recall / (precision + recall)
    } else {
        0.0
    };
    MapQuality {
        occupied_cells: occupied.len(),
        precision,
        visible_edge_cells: visible.len(),
        recall,
        f1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pirouette_io::Obstacle;

    #[test]
    fn rigid_alignment_undoes_a_known_transform() {
        let a: Vec<Point2> = (0..10)
            .map(|k| Point2::new(k as f64 * 0.1, (k * k) as f64 * 0.01))
            .collect();
        let t = Pose2::new(0.3, -1.2, 0.7);
        let b: Vec<Point2> = a.iter().map(|p| t.transform_point(*p)).collect();
        let found = align_rigid(&a, &b);
        assert!((found.x - t.x).abs() < 1e-12 && (found.y - t.y).abs() < 1e-12);
        assert!((found.theta - t.theta).abs() < 1e-12);
        // Scores: a rotated copy is perfect once aligned, not anchored.
        let est: Vec<Pose2> = a.iter().map(|p| Pose2::new(p.x, p.y, 0.0)).collect();
        let tru: Vec<Pose2> = b.iter().map(|p| Pose2::new(p.x, p.y, 0.0)).collect();
        let s = trajectory_scores(&est, &tru);
        assert!(s.ate_aligned_m < 1e-12 && s.ate_anchored_m > 0.5);
        // A rigid copy has scale 1; one scaled up by 1 % about any point,
        // 1.01 (the truth is larger than the estimate by that much).
        assert!((similarity_scale(&a, &b) - 1.0).abs() < 1e-12);
        let grown: Vec<Point2> = b
            .iter()
            .map(|p| Point2::new(2.0 + 1.01 * (p.x - 2.0), -1.0 + 1.01 * (p.y + 1.0)))
            .collect();
        assert!((similarity_scale(&a, &grown) - 1.01).abs() < 1e-12);
        assert_eq!(
            similarity_scale(&[Point2::new(1.0, 1.0)], &[Point2::new(3.0, 0.0)]),
            1.0
        );
    }

    #[test]
    fn anchored_error_is_the_rms_of_distances() {
        let est = [Pose2::IDENTITY, Pose2::new(1.0, 0.0, 0.0)];
        let tru = [Pose2::IDENTITY, Pose2::new(1.0, 0.02, 0.01)];
        let s = trajectory_scores(&est, &tru);
        assert!((s.ate_anchored_m - (0.02f64 * 0.02 / 2.0).sqrt()).abs() < 1e-12);
        assert!((s.max_anchored_m - 0.02).abs() < 1e-12);
        assert!((s.heading_rmse_deg - (0.01f64.powi(2) / 2.0).sqrt().to_degrees()).abs() < 1e-9);
    }

    /// 40 steps of 10.5° (a turn and a sixth): every estimated step 0.2°
    /// short but the fifth, 2° long.
    #[test]
    fn turn_errors_and_the_heading_after_a_full_turn() {
        let deg = f64::to_radians;
        let truth: Vec<Pose2> = (0..41)
            .map(|k| Pose2::new(0.1 * k as f64, 0.0, deg(10.5 * k as f64)))
            .collect();
        let mut est = vec![Pose2::IDENTITY];
        for k in 0..40 {
            let step = if k == 4 { 12.5 } else { 10.3 };
            let last = est[k];
            est.push(Pose2::new(0.1 * (k + 1) as f64, 0.0, last.theta + deg(step)));
        }
        let s = trajectory_scores(&est, &truth);
        assert!((s.turn_error_median_deg - 0.2).abs() < 1e-9, "{s:?}");
        // The 95th percentile of 40 errors: the 38th smallest (0.2°); the
        // one 2° error is the largest.
        assert!((s.turn_error_p95_deg - 0.2).abs() < 1e-9, "{s:?}");
        // 35 steps make the full turn (367.5°): 34 short by 0.2°, one long
        // by 2°.
        let after = s.heading_after_full_turn_deg.unwrap();
        assert!((after - (34.0 * 0.2 - 2.0)).abs() < 1e-9, "{after}");
        // Half a turn is never a full one.
        assert_eq!(
            trajectory_scores(&est[..19], &truth[..19]).heading_after_full_turn_deg,
            None
        );
    }

    /// A wall's foot seen from two places a metre apart agrees; a false
    /// obstacle 1.2 m ahead of each view does not; one place twice is no
    /// second view.
    #[test]
    fn walls_agree_across_views_and_false_obstacles_do_not() {
        use pirouette_profile::Rop;
        // One bin straight ahead.
        let ahead = |range: f32| {
            let mut rop = Rop::empty(-0.01, 0.02, 1, 4.0);
            rop.range_m[0] = range;
            rop
        };
        let poses = [Pose2::IDENTITY, Pose2::new(1.0, 0.0, 0.0)];
        // The wall at x = 2: 2 m from the first, 1 m from the second.
        let wall = profile_agreement(&[&ahead(2.0), &ahead(1.0)], &poses);
        assert_eq!((wall.points, wall.share), (2, 1.0));
        // 5 cm off still agrees; 15 cm does not.
        assert_eq!(profile_agreement(&[&ahead(2.0), &ahead(1.05)], &poses).share, 1.0);
        assert_eq!(profile_agreement(&[&ahead(2.0), &ahead(1.15)], &poses).share, 0.0);
        // A stain 1.2 m ahead of each: 1 m apart on the floor.
        assert_eq!(profile_agreement(&[&ahead(1.2), &ahead(1.2)], &poses).share, 0.0);
        // The same point from one place turned by 45° (seen 45° right) is
        // from elsewhere; turned by 10°, not.
        let turned = |deg: f64| {
            let mut rop = Rop::empty(-deg.to_radians() - 0.01, 0.02, 1, 4.0);
            rop.range_m[0] = 2.0;
            let poses = [Pose2::IDENTITY, Pose2::new(0.0, 0.0, deg.to_radians())];
            profile_agreement(&[&ahead(2.0), &rop], &poses).share
        };
        assert_eq!((turned(45.0), turned(10.0)), (1.0, 0.0));
        // Beyond the range limit is no obstacle.
        assert_eq!(
            profile_agreement(&[&ahead(f32::INFINITY), &ahead(5.0)], &poses).points,
            0
        );
    }

    fn wall_world() -> World {
        World {
            bounds: [0.0, 0.0, 2.0, 2.0],
            floor_rgb: [0; 3],
            obstacles: vec![Obstacle::Box {
                center: [1.0, 0.0],
                size: [0.03, 2.0],
                yaw_deg: 0.0,
                height: 0.1,
                rgb: [255; 3],
            }],
        }
    }

    #[test]
    fn visible_outline_is_the_near_face_within_range() {
        let w = wall_world();
        let pts = visible_outline(&w, &[Pose2::IDENTITY], (-0.5, 0.5), 0.1, 1.2, 0.01);
        assert!(!pts.is_empty());
        // The near face x = 0.985 (mid-cell), seen within 1.2 m and ±0.5 rad.
        let face = 0.985;
        let reach = (1.2f64.powi(2) - face * face).sqrt();
        assert!(pts
            .iter()
            .all(|p| (p.x - face).abs() < 1e-9 && p.y.abs() <= reach + 1e-9));
        // One point per 1 cm cell along the visible stretch, none missing.
        let expected = (2.0 * (0.5f64.tan() * face).min(reach) / 0.01).round() as i64;
        assert!(
            (pts.len() as i64 - expected).abs() <= 2,
            "{} vs {expected}",
            pts.len()
        );
        let none = visible_outline(&w, &[Pose2::IDENTITY], (-0.5, 0.5), 0.1, 0.9, 0.01);
        assert!(none.is_empty(), "the wall is beyond the limit");
    }

    #[test]
    fn map_quality_counts_true_false_and_missed_cells() {
        let w = wall_world();
        let visible: Vec<Point2> = (0..10).map(|k| Point2::new(0.985, k as f64 * 0.01)).collect();
        // Eight cells on the wall, y from -0.05 to 0.02; two more 4 cm and
        // 50 cm off it.
        let mut occupied: Vec<Point2> = (0..8)
            .map(|k| Point2::new(0.99, -0.05 + k as f64 * 0.01))
            .collect();
        occupied.push(Point2::new(0.5, 0.5));
        occupied.push(Point2::new(0.95, 0.0));
        let q = map_quality(&occupied, &w, &visible, 0.02);
        assert_eq!(q.occupied_cells, 10);
        assert!((q.precision - 0.8).abs() < 1e-12);
        // Visible (0.985, y) lies within 2 cm of (0.99, 0.02) for
        // |y − 0.02| ≤ √(0.02² − 0.005²) = 0.0194: y = 0.00 to 0.03, four of ten.
        assert!((q.recall - 0.4).abs() < 1e-12, "{q:?}");
        assert!((q.f1 - 2.0 * 0.8 * 0.4 / 1.2).abs() < 1e-12);
    }

    /// Poses of two sweeps, each turning exactly about one robot-frame
    /// point: the fit gives that point back.
    #[test]
    fn true_pivot_is_the_point_turned_about() {
        let pivot = [0.004, -0.0025];
        let (mut sweep_of, mut poses) = (Vec::new(), Vec::new());
        for (s, centre) in [(0u32, [0.3, -0.2]), (1, [1.4, 0.6])] {
            for k in 0..12 {
                let theta = 0.3 + k as f64 * 0.52 + s as f64;
                let (sin, cos) = f64::sin_cos(theta);
                let x = centre[0] - (cos * pivot[0] - sin * pivot[1]);
                let y = centre[1] - (sin * pivot[0] + cos * pivot[1]);
                sweep_of.push(s);
                poses.push(Pose2::new(x, y, theta));
            }
        }
        let p = true_pivot(&sweep_of, &poses).expect("enough frames");
        assert!((p[0] - 4.0).abs() < 1e-9 && (p[1] + 2.5).abs() < 1e-9, "{p:?}");
        assert!(true_pivot(&sweep_of[..2], &poses[..2]).is_none());
    }
}
