//! Maps of whole datasets: sweeps registered one after another against the
//! map built so far, then fused into one occupancy grid.

use crate::frame::DatasetSweep;
use crate::frame::Frame;
use anyhow::{bail, Result};
use nalgebra::Matrix3;
use pirouette_geom::{Point2, Pose2};
use pirouette_grid::{GridConfig, OccupancyGrid};
use pirouette_io::Motion;
use pirouette_profile::sweep::SweepConfig;
use pirouette_profile::Rop;
use pirouette_register::{
    endpoints, far_points, register, LikelihoodField, MotionNoise, PosePrior, RegisterConfig, Registration,
};

mod adjust;
mod chain;
mod fields;
pub(crate) mod graph;
pub mod revisits;

use crate::localise::LocaliseConfig;
use adjust::adjust_jointly;
use chain::chain_headings;
use fields::{field_in, field_of, frame_fields, seen_by};

/// Settings of mapping.
#[derive(Debug, Clone, PartialEq)]
pub struct MapConfig {
    /// The occupancy grid and its sensor model.
    pub grid: GridConfig,
    /// Sweep registration.
    pub register: RegisterConfig,
    /// Registering one frame alone about its sweep's centre (the anchors of
    /// the heading chain).
    pub turn: RegisterConfig,
    /// Errors of forward moves.
    pub motion: MotionNoise,
    /// Standard deviations of verified and commanded turns (the sweep
    /// assembly's).
    pub sweep: SweepConfig,
    /// Registration also matches ranges beyond the soft limit, up to this
    /// many times it (1: none). They never enter the grid.
    pub far_reach: f64,
    /// A commanded turn errs by this share of its angle where that is more
    /// than [`SweepConfig::commanded_sigma_rad`] (one standard deviation):
    /// odometry's rotation error grows with the rotation.
    pub turn_error_frac: f64,
    /// Revisits recognised by the place index become candidate loop
    /// edges of the joint adjustment ([`revisits`]); `None`: not looked
    /// for.
    pub revisits: Option<LocaliseConfig>,
}

impl MapConfig {
    /// The standard deviation of a commanded turn by `turn_rad` (see
    /// [`MapConfig::turn_error_frac`]).
    pub fn command_sigma(&self, turn_rad: f64) -> f64 {
        self.sweep
            .commanded_sigma_rad
            .max(self.turn_error_frac * turn_rad.abs())
    }
}

impl Default for MapConfig {
    /// Default grid, registration, motion and sweep settings; a frame's
    /// heading about a known centre (one unknown, not three) trusts 6
    /// endpoints on the map (18 cm of edge) instead of 10; registration
    /// matches ranges out to twice the soft limit. A floor boundary's range
    /// error grows with the square of its range (one image row spans more
    /// floor the farther it is): at twice the limit it is four times the
    /// error at the limit, where profiles err by a few millimetres, so
    /// still within the likelihood field's 1.5 cm. A commanded turn errs by
    /// a tenth of its angle, at least the sweep settings' 3°: the 3° of a
    /// pirouette's 30° turns in proportion.
    fn default() -> Self {
        let register = RegisterConfig::default();
        Self {
            grid: GridConfig::default(),
            turn: RegisterConfig {
                min_matched: 6,
                ..register.clone()
            },
            register,
            motion: MotionNoise::default(),
            sweep: SweepConfig::default(),
            far_reach: 2.0,
            turn_error_frac: 0.1,
            revisits: Some(LocaliseConfig::default()),
        }
    }
}

/// Where one sweep ended up.
#[derive(Debug, Clone)]
pub struct SweepPose {
    /// The sweep's id in the manifest.
    pub id: u32,
    /// `map_from_robot` of the sweep's first frame.
    pub pose: Pose2,
    /// The belief from the commanded forward move, before registration
    /// (`None` for the first sweep, which defines the map frame).
    pub prior: Option<PosePrior>,
    /// The last registration of the sweep, against the map of all the
    /// others (`None` when there are no others).
    pub registration: Option<Registration>,
    /// Covariance of `pose` in map `(x, y, θ)`.
    pub covariance: Matrix3<f64>,
}

/// A mapped dataset.
#[derive(Debug, Clone)]
pub struct MapRun {
    /// The fused grid.
    pub grid: OccupancyGrid,
    /// `map_from_robot` of every frame, in capture order.
    pub frame_poses: Vec<Pose2>,
    /// One per sweep, in capture order.
    pub sweeps: Vec<SweepPose>,
    /// The revisits the place index recognised, and what became of them.
    pub revisits: Vec<revisits::Revisit>,
}

/// Splits a sweep into blocks: frames that verified matches join
/// (consecutive turns, the loop closure, re-matches after the loop), whose
/// headings relative to each other are known to a match's accuracy.
/// Blocks are sorted by their first frame.
fn blocks_of(sweep: &DatasetSweep) -> Vec<Vec<usize>> {
    components(sweep.frames.len(), &sweep.sweep.links)
}

/// The connected components of `n` frames joined by `links`, each sorted,
/// sorted by their first frame.
fn components(n: usize, links: &[(usize, usize)]) -> Vec<Vec<usize>> {
    // Union-find over the links, smallest frame as the root.
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut k: usize) -> usize {
        while parent[k] != k {
            parent[k] = parent[parent[k]];
            k = parent[k];
        }
        k
    }
    for &(a, b) in links {
        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
        parent[ra.max(rb)] = ra.min(rb);
    }
    let mut blocks: Vec<Vec<usize>> = Vec::new();
    let mut index_of_root = vec![usize::MAX; n];
    for k in 0..n {
        let r = root(&mut parent, k);
        if index_of_root[r] == usize::MAX {
            index_of_root[r] = blocks.len();
            blocks.push(Vec::new());
        }
        blocks[index_of_root[r]].push(k);
    }
    blocks
}

/// The state of one sweep while mapping.
#[derive(Debug, Clone)]
struct Placed {
    /// `map_from_robot` of the sweep's first frame.
    pose: Pose2,
    /// Heading of each frame relative to the first, radians.
    heading_rad: Vec<f64>,
    /// Blocks of frames (positions within the sweep).
    blocks: Vec<Vec<usize>>,
    /// The largest block: the next sweep's heading prior counts the
    /// fallback turns from it to the last frame's block.
    reference: usize,
    prior: Option<PosePrior>,
    registration: Option<Registration>,
    covariance: Matrix3<f64>,
    /// The point the robot turns about, in its own frame, metres (see
    /// [`pirouette_profile::sweep::pivot_from_turns`]): a robot a few
    /// millimetres off it moves its centre round a circle in a pirouette.
    pivot: [f64; 2],
}

impl Placed {
    /// A sweep at `pose`, its largest block the reference, its frames
    /// turned about `pivot`.
    fn new(sweep: &DatasetSweep, pose: Pose2, pivot: [f64; 2]) -> Self {
        let blocks = blocks_of(sweep);
        let reference = (0..blocks.len())
            .max_by_key(|&b| (blocks[b].len(), std::cmp::Reverse(b)))
            .expect("a sweep has a frame");
        Self {
            pose,
            heading_rad: sweep.sweep.heading_rad.clone(),
            blocks,
            reference,
            prior: None,
            registration: None,
            covariance: Matrix3::zeros(),
            pivot,
        }
    }

    /// The sweep's `k`-th frame relative to its pose: turned by its heading
    /// about the pivot, which stays where it is.
    fn rel(&self, k: usize) -> Pose2 {
        let at = |h: f64| {
            let (sin, cos) = h.sin_cos();
            [
                cos * self.pivot[0] - sin * self.pivot[1],
                sin * self.pivot[0] + cos * self.pivot[1],
            ]
        };
        let (p0, pk) = (at(self.heading_rad[0]), at(self.heading_rad[k]));
        Pose2::new(p0[0] - pk[0], p0[1] - pk[1], self.heading_rad[k])
    }

    /// `map_from_robot` of the sweep's `k`-th frame.
    fn frame_pose(&self, k: usize) -> Pose2 {
        self.pose * self.rel(k)
    }

    /// The endpoints and far points of some of the sweep's frames, in its
    /// first frame.
    fn points(
        &self,
        sweep: &DatasetSweep,
        members: &[usize],
        input: &[Frame],
        config: &MapConfig,
    ) -> Vec<Point2> {
        members
            .iter()
            .flat_map(|&k| {
                let rel = self.rel(k);
                frame_points(&input[sweep.frames[k]].compared, config)
                    .into_iter()
                    .map(move |p| rel.transform_point(p))
            })
            .collect()
    }

    /// The variance a heading in block `b` takes on relative to the
    /// reference block from the fallback turns between them (the turns
    /// into each block's first frame, as `sweep` measured them; at least
    /// one turn's, a command's error, within the reference block).
    fn fallback_var(&self, b: usize, sweep: &DatasetSweep, config: &MapConfig) -> f64 {
        let r = self.reference;
        if b == r {
            return config.sweep.commanded_sigma_rad.powi(2);
        }
        let heading = &sweep.sweep.heading_rad;
        (b.min(r) + 1..=b.max(r))
            .map(|k| {
                let first = self.blocks[k][0];
                let turn = if first > 0 {
                    heading[first] - heading[first - 1]
                } else {
                    0.0
                };
                config.command_sigma(turn).powi(2)
            })
            .sum()
    }
}

/// What registration matches of a profile, robot frame: its endpoints
/// and its far points.
fn frame_points(rop: &Rop, config: &MapConfig) -> Vec<Point2> {
    let mut points = endpoints(rop);
    points.extend(far_points(rop, far_reach_m(rop, config)));
    points
}

/// How far registration matches a profile's ranges, metres.
fn far_reach_m(rop: &Rop, config: &MapConfig) -> f64 {
    rop.max_range_m as f64 * config.far_reach
}

/// Passes of every sweep against the map of the others before the joint
/// adjustment (one more follows it).
const REFINE_PASSES: usize = 2;

/// How many times [`build_map`] reports progress for `sweeps` sweeps.
pub fn progress_steps(sweeps: usize) -> usize {
    sweeps + REFINE_PASSES + 1
}

/// How far a sweep may move against the map of the others in refinement,
/// metres (one standard deviation; its heading as far as one commanded
/// turn errs): the first sweep's frames may have been mapped askew before
/// later sweeps showed better, and later sweeps were placed against that.
const REFINE_SHIFT_M: f64 = 0.05;

/// Places one sweep against `field` by alternating two steps, twice:
/// register the whole sweep (position and heading) from `prior`, then solve
/// its frames' headings about that centre from their turns and their own
/// registrations ([`chain_headings`]).
fn place_sweep(
    placed: &mut Placed,
    sweep: &DatasetSweep,
    input: &[Frame],
    field: &LikelihoodField,
    prior: &PosePrior,
    config: &MapConfig,
) -> Result<()> {
    let all: Vec<usize> = (0..sweep.frames.len()).collect();
    for _ in 0..2 {
        let reg = register(
            field,
            &placed.points(sweep, &all, input, config),
            prior,
            &config.register,
        )?;
        placed.pose = reg.pose;
        placed.covariance = reg.covariance;
        placed.registration = Some(reg);
        chain_headings(placed, sweep, input, |_| field, config)?;
    }
    Ok(())
}

/// Places every sweep again against the map of all the others, which
/// corrects the first sweeps with what later ones saw, and anchors each
/// frame's heading on the map of everything but itself (for a single
/// pirouette, its sweep's other frames). The others are where the pass
/// found them (a Jacobi step, not Gauss-Seidel): a sweep placed early in
/// the pass does not drag the ones after it, and the result does not
/// depend on the sweeps' order.
fn refine_pass(
    placed: &mut [Placed],
    sweeps: &[DatasetSweep],
    input: &[Frame],
    blind_m: f64,
    config: &MapConfig,
) -> Result<()> {
    // Every sweep is placed against where the others were at the pass's
    // start, so that the pass does not depend on the sweeps' order.
    let start: Vec<Placed> = placed.to_vec();
    for (s, sweep) in sweeps.iter().enumerate() {
        let others: Vec<(usize, Pose2)> = sweeps
            .iter()
            .zip(start.iter())
            .enumerate()
            .filter(|&(o, _)| o != s)
            .flat_map(|(_, (other, p))| {
                (0..other.frames.len()).map(move |k| (other.frames[k], p.frame_pose(k)))
            })
            .collect();
        let others = seen_by(&others, input, blind_m, config)?;
        if sweeps.len() > 1 {
            let field = field_in(&others, None, config);
            // Every sweep may move, the first too (the map frame is set at
            // the end), but only locally: the first pass found the basin.
            let prior = PosePrior {
                mean: placed[s].pose,
                sigma_forward_m: REFINE_SHIFT_M,
                sigma_left_m: REFINE_SHIFT_M,
                sigma_theta_rad: config.sweep.commanded_sigma_rad,
            };
            place_sweep(&mut placed[s], sweep, input, &field, &prior, config)?;
        }
        // Each frame against the others and the rest of its own sweep (for
        // a single pirouette, its own sweep alone).
        let fields = frame_fields(&placed[s], sweep, &others, input, blind_m, config);
        chain_headings(&mut placed[s], sweep, input, |k| &fields[k], config)?;
    }
    Ok(())
}

/// Builds the map of a dataset from its frames' profiles and assembled
/// sweeps. `frames` are the manifest's frames (for the commanded forward
/// moves), `blind_m` the camera's blind distance. `progress` is called
/// [`progress_steps`] times: once per sweep placed, once per refinement
/// pass and once for the joint adjustment.
///
/// Each sweep after the first starts from the pose its forward move
/// predicts from the previous sweep's last frame and is registered against
/// what was seen so far: the endpoints the grid holds occupied, the grid's
/// free floor, and the ranges beyond the soft limit, which never enter the
/// grid but pin headings where little is near ([`MapConfig::far_reach`]);
/// then its frames' headings are solved from their turns (verified ones to
/// a match's accuracy, fallbacks to a command's) and their own
/// registrations, each frame turned about the robot's pivot (the sweep
/// settings' [`pirouette_profile::matching::MatchConfig::pivot_m`], which
/// the turns measured). Then every sweep is placed
/// again, twice, against the map of all the others as the pass found them
/// (a Jacobi step), which corrects the
/// first sweeps with what later ones saw, and each frame's heading is
/// anchored on the map of everything but itself (for a single pirouette,
/// its sweep's other frames). One sweep at a time cannot turn a group of
/// sweeps that agree with each other but not with the rest, so then the
/// sweeps are adjusted jointly, each a rigid whole, to agree with every
/// pair's match and the forward moves, and placed once more against the
/// map of the others. The map frame is set last: the first frame is
/// `(0, 0, 0)`.
///
/// Registration compares each frame's `compared` profile; the grid fuses
/// its `rop` ([`Frame`]).
pub fn build_map(
    input: &[Frame],
    sweeps: &[DatasetSweep],
    blind_m: f64,
    config: &MapConfig,
    progress: impl Fn(),
) -> Result<MapRun> {
    let reach = input.iter().map(|f| f.rop.max_range_m as f64).fold(0.0, f64::max);
    let motions: Vec<Option<Motion>> = input.iter().map(Frame::commanded).collect();
    check_extent(&motions, reach, &config.grid)?;
    if let Some(&i) = sweeps.iter().flat_map(|s| &s.frames).find(|&&i| i >= input.len()) {
        bail!("a sweep names frame {i} of {}", input.len());
    }
    // Each sweep in turn against the map of those before it.
    let mut placed = place_in_turn(input, sweeps, blind_m, config, &progress)?;
    // Each sweep against the map of all the others.
    for _pass in 0..REFINE_PASSES {
        refine_pass(&mut placed, sweeps, input, blind_m, config)?;
        progress();
    }
    // The sweeps moved together to agree with every pair's match, then
    // each placed once more against that map.
    let revisits = if sweeps.len() > 1 {
        adjust_jointly(&mut placed, input, sweeps, blind_m, config)?
    } else {
        Vec::new()
    };
    progress();
    // The first frame's heading was refined with the rest; the map frame
    // is where it ended up.
    to_first_frame(&mut placed);
    // Every frame's profile fused at its pose.
    let (grid, frame_poses, out) = fuse(input, sweeps, &placed, blind_m, config)?;
    Ok(MapRun {
        grid,
        frame_poses,
        sweeps: out,
        revisits,
    })
}

/// Each sweep placed in turn: the first at the origin, each later one
/// from the pose its forward move predicts from the previous sweep's last
/// frame, registered against the map of those before it. `progress` is
/// called once per sweep.
fn place_in_turn(
    input: &[Frame],
    sweeps: &[DatasetSweep],
    blind_m: f64,
    config: &MapConfig,
    progress: &impl Fn(),
) -> Result<Vec<Placed>> {
    let mut placed: Vec<Placed> = Vec::with_capacity(sweeps.len());
    let mut inserted: Vec<(usize, Pose2)> = Vec::new();
    for (s, sweep) in sweeps.iter().enumerate() {
        let state = match placed.last() {
            None => Placed::new(sweep, Pose2::IDENTITY, config.sweep.matching.pivot_m),
            Some(prev) => {
                let prior = forward_prior(&sweeps[s - 1], prev, input[sweep.frames[0]].commanded(), config);
                let mut state = Placed::new(sweep, prior.mean, config.sweep.matching.pivot_m);
                state.prior = Some(prior);
                let field = field_of(&inserted, input, blind_m, config)?;
                place_sweep(&mut state, sweep, input, &field, &prior, config)?;
                state
            }
        };
        for k in 0..sweep.frames.len() {
            inserted.push((sweep.frames[k], state.frame_pose(k)));
        }
        placed.push(state);
        progress();
    }
    Ok(placed)
}

/// Moves every sweep (pose, prior, registration and their covariances)
/// into the frame of the first sweep's first frame.
fn to_first_frame(placed: &mut [Placed]) {
    let origin = placed[0].frame_pose(0).inverse();
    let (sin, cos) = origin.theta.sin_cos();
    let rotate = Matrix3::new(cos, -sin, 0.0, sin, cos, 0.0, 0.0, 0.0, 1.0);
    for p in placed {
        p.pose = origin * p.pose;
        p.covariance = rotate * p.covariance * rotate.transpose();
        if let Some(prior) = p.prior.as_mut() {
            prior.mean = origin * prior.mean;
        }
        if let Some(reg) = p.registration.as_mut() {
            reg.pose = origin * reg.pose;
            if let Some(r) = reg.rival.as_mut() {
                r.pose = origin * r.pose;
            }
            reg.covariance = rotate * reg.covariance * rotate.transpose();
        }
    }
}

/// The grid of every frame's profile at its pose, the frames' poses (the
/// first exactly the origin), and each sweep's pose as placed.
fn fuse(
    input: &[Frame],
    sweeps: &[DatasetSweep],
    placed: &[Placed],
    blind_m: f64,
    config: &MapConfig,
) -> Result<(OccupancyGrid, Vec<Pose2>, Vec<SweepPose>)> {
    let mut grid = OccupancyGrid::new(config.grid.clone())?;
    let mut frame_poses = vec![Pose2::IDENTITY; input.len()];
    let mut out = Vec::with_capacity(sweeps.len());
    for (s, (sweep, p)) in sweeps.iter().zip(placed).enumerate() {
        for (k, &i) in sweep.frames.iter().enumerate() {
            // The first frame is the origin exactly, not to rounding.
            frame_poses[i] = if s == 0 && k == 0 {
                Pose2::IDENTITY
            } else {
                p.frame_pose(k)
            };
            grid.insert_profile(&frame_poses[i], &input[i].rop, blind_m);
        }
        if grid.overflowed() {
            bail!(
                "the map grew beyond its budget of {} million cells: registration placed a sweep far from its command",
                config.grid.max_cells / 1_000_000
            );
        }
        out.push(SweepPose {
            id: sweep.id,
            pose: frame_poses[sweep.frames[0]],
            prior: p.prior,
            registration: p.registration.clone(),
            covariance: p.covariance,
        });
    }
    Ok((grid, frame_poses, out))
}

/// The belief in a sweep's first frame after the forward move from the
/// previous sweep's last frame.
fn forward_prior(
    prev_sweep: &DatasetSweep,
    prev: &Placed,
    motion: Option<Motion>,
    config: &MapConfig,
) -> PosePrior {
    let (last, fallback_var) = last_frame(prev_sweep, prev, config);
    let start = prev.frame_pose(last);
    // The last frame's heading: the sweep's registration, a verified
    // turn's error and a command's per fallback turn.
    let start_var = prev.covariance[(2, 2)] + config.sweep.verified_sigma_rad.powi(2) + fallback_var;
    PosePrior::after_forward(&start, forward_distance(motion), start_var.sqrt(), &config.motion)
}

/// A sweep's last frame, and the variance its heading takes on from the
/// fallback turns between its block and the sweep's largest (a command's
/// error each).
fn last_frame(sweep: &DatasetSweep, placed: &Placed, config: &MapConfig) -> (usize, f64) {
    let last = sweep.frames.len() - 1;
    let last_block = placed
        .blocks
        .iter()
        .position(|b| b.contains(&last))
        .expect("in a block");
    (last, placed.fallback_var(last_block, sweep, config))
}

/// The commanded forward move before a sweep, metres (0 without one).
fn forward_distance(motion: Option<Motion>) -> f64 {
    match motion {
        Some(Motion::Forward { forward }) => forward,
        _ => 0.0,
    }
}

/// Refuses, before any work, a dataset whose commanded moves alone span a
/// grid beyond [`GridConfig::max_cells`] (each sweep may still move by up
/// to the registration window, which the final grid's own check catches).
/// `reach_m` is how far a profile reaches (the soft range limit).
pub fn check_extent(motions: &[Option<Motion>], reach_m: f64, grid: &GridConfig) -> Result<()> {
    let reach = reach_m;
    let poses = dead_reckoning(motions);
    let (lo, hi) = poses
        .iter()
        .fold(((f64::MAX, f64::MAX), (f64::MIN, f64::MIN)), |(lo, hi), p| {
            ((lo.0.min(p.x), lo.1.min(p.y)), (hi.0.max(p.x), hi.1.max(p.y)))
        });
    let s = grid.resolution_m;
    let (w, h) = ((hi.0 - lo.0 + 2.0 * reach) / s, (hi.1 - lo.1 + 2.0 * reach) / s);
    if w.is_nan() || h.is_nan() || w * h > grid.max_cells as f64 {
        bail!(
            "the commanded moves span {:.1} × {:.1} m: a map of {:.0} × {:.0} cells of {} cm is beyond the budget of {} million cells \
             (is a forward move given in millimetres?)",
            hi.0 - lo.0,
            hi.1 - lo.1,
            w,
            h,
            s * 100.0,
            grid.max_cells / 1_000_000
        );
    }
    Ok(())
}

/// A grid of the profiles seen from given poses (the map a perfect
/// registration would make).
pub fn map_with_poses<'r>(
    rops: impl IntoIterator<Item = &'r Rop>,
    poses: &[Pose2],
    blind_m: f64,
    config: &GridConfig,
) -> Result<OccupancyGrid> {
    let mut grid = OccupancyGrid::new(config.clone())?;
    for (rop, pose) in rops.into_iter().zip(poses) {
        grid.insert_profile(pose, rop, blind_m);
    }
    if grid.overflowed() {
        bail!(
            "the map of the given poses is beyond the budget of {} million cells",
            config.max_cells / 1_000_000
        );
    }
    Ok(grid)
}

/// The trajectory the commands alone predict, from `(0, 0, 0)`: one pose
/// per frame, from each frame's motion.
pub fn dead_reckoning(motions: &[Option<Motion>]) -> Vec<Pose2> {
    let mut pose = Pose2::IDENTITY;
    motions
        .iter()
        .map(|&motion| {
            match motion {
                Some(Motion::Turn { turn_deg }) => pose = pose * Pose2::new(0.0, 0.0, turn_deg.to_radians()),
                Some(Motion::Forward { forward }) => pose = pose * Pose2::new(forward, 0.0, 0.0),
                None => {}
            }
            pose
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_are_the_frames_verified_matches_join() {
        // Turns 1, 3, 4 verified; the loop closed 5 → 0; frame 6 re-matched
        // against 3.
        let links = [(0, 1), (2, 3), (3, 4), (0, 5), (3, 6)];
        assert_eq!(
            components(8, &links),
            vec![vec![0, 1, 5], vec![2, 3, 4, 6], vec![7]]
        );
        assert_eq!(components(3, &[]), vec![vec![0], vec![1], vec![2]]);
    }

    #[test]
    fn dead_reckoning_follows_the_commands() {
        let motions = [
            None,
            Some(Motion::Turn { turn_deg: 90.0 }),
            Some(Motion::Forward { forward: 0.5 }),
            Some(Motion::Turn { turn_deg: -45.0 }),
        ];
        let poses = dead_reckoning(&motions);
        assert_eq!(poses[0], Pose2::IDENTITY);
        assert!((poses[2].x).abs() < 1e-12 && (poses[2].y - 0.5).abs() < 1e-12);
        assert!((poses[3].theta - 45f64.to_radians()).abs() < 1e-12);
    }
}
