//! What the frames placed so far saw, and the likelihood fields that
//! registration matches against.

use super::placed::{far_reach_m, Placed};
use super::MapConfig;
use crate::error::Result;
use crate::frame::DatasetSweep;
use crate::frame::Frame;
use pirouette_geom::{Point2, Pose2};
use pirouette_grid::OccupancyGrid;
use pirouette_profile::Rop;
use pirouette_register::{endpoints, far_points, LikelihoodField};
use rayon::prelude::*;

/// What some frames saw, map frame.
#[derive(Debug, Clone)]
pub(super) struct Seen {
    /// Their occupancy grid.
    grid: OccupancyGrid,
    /// Their endpoints within the soft limit.
    near: Vec<Point2>,
    /// Their points beyond it (see [`far_points`]).
    far: Vec<Point2>,
}

impl Seen {
    fn new(config: &MapConfig) -> Result<Self> {
        Ok(Self {
            grid: OccupancyGrid::new(config.grid.clone())?,
            near: Vec::new(),
            far: Vec::new(),
        })
    }

    /// Inserts one frame into the grid and its points into the lists.
    fn add(&mut self, rop: &Rop, pose: Pose2, blind_m: f64, config: &MapConfig) {
        self.grid.insert_profile(&pose, rop, blind_m);
        let placed = |p: Point2| pose.transform_point(p);
        self.near.extend(endpoints(rop).into_iter().map(placed));
        self.far
            .extend(far_points(rop, far_reach_m(rop, config)).into_iter().map(placed));
    }
}

/// What `frames` (manifest index and pose) saw.
pub(super) fn seen_by(
    frames: &[(usize, Pose2)],
    input: &[Frame],
    blind_m: f64,
    config: &MapConfig,
) -> Result<Seen> {
    let mut seen = Seen::new(config)?;
    for &(i, pose) in frames {
        seen.add(&input[i].compared, pose, blind_m, config);
    }
    Ok(seen)
}

/// The likelihood field of what was seen: the endpoints that the grid
/// holds occupied and every far point (the grid knows nothing of them),
/// with the grid's free floor, within `region` (map-frame corners) if
/// given.
pub(super) fn field_in(seen: &Seen, region: Option<(Point2, Point2)>, config: &MapConfig) -> LikelihoodField {
    let r = &config.register;
    let grid = &seen.grid;
    let support: Vec<Point2> = seen
        .near
        .iter()
        .copied()
        .filter(|p| grid.probability_at(p.x, p.y) > r.occupied_threshold)
        .chain(seen.far.iter().copied())
        .collect();
    match region {
        Some((lo, hi)) => LikelihoodField::from_map_within(
            &support,
            grid,
            lo,
            hi,
            r.free_threshold,
            r.sigma_m,
            r.epsilon,
            r.epsilon_free,
        ),
        None => LikelihoodField::from_map(
            &support,
            grid,
            r.free_threshold,
            r.sigma_m,
            r.epsilon,
            r.epsilon_free,
        ),
    }
}

/// The likelihood field of what `frames` saw.
pub(super) fn field_of(
    frames: &[(usize, Pose2)],
    input: &[Frame],
    blind_m: f64,
    config: &MapConfig,
) -> Result<LikelihoodField> {
    Ok(field_in(&seen_by(frames, input, blind_m, config)?, None, config))
}

/// For each frame of sweep `placed`, the field of what `others` saw plus
/// the sweep's other frames, around the sweep's centre: what anchors that
/// frame's heading.
pub(super) fn frame_fields(
    placed: &Placed,
    sweep: &DatasetSweep,
    others: &Seen,
    input: &[Frame],
    blind_m: f64,
    config: &MapConfig,
) -> Vec<LikelihoodField> {
    let n = sweep.frames.len();
    let c = placed.pose.translation();
    // Points lie within the registration's reach; a frame turns about the
    // pivot, within a centimetre of the first frame's position.
    let reach = far_reach_m(&input[sweep.frames[0]].compared, config)
        .max(input[sweep.frames[0]].compared.max_range_m as f64)
        + FRAME_FIELD_MARGIN_M;
    let region = (
        Point2::new(c.x - reach, c.y - reach),
        Point2::new(c.x + reach, c.y + reach),
    );
    // One field per frame, built in parallel (each is independent).
    (0..n)
        .into_par_iter()
        .map(|k| {
            let mut seen = others.clone();
            for j in (0..n).filter(|&j| j != k) {
                seen.add(
                    &input[sweep.frames[j]].compared,
                    placed.frame_pose(j),
                    blind_m,
                    config,
                );
            }
            field_in(&seen, Some(region), config)
        })
        .collect()
}

/// Margin of a frame's field beyond the soft limit around its sweep's
/// centre, metres.
const FRAME_FIELD_MARGIN_M: f64 = 0.2;
