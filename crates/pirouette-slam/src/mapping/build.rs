//! A dataset's map: each sweep placed in turn against the map before it,
//! every sweep refined against the others, the sweeps adjusted jointly,
//! then every frame fused into the grid.

use crate::frame::DatasetSweep;
use crate::frame::{Frame, Step};
use nalgebra::Matrix3;
use pirouette_geom::Pose2;
use pirouette_grid::OccupancyGrid;
use pirouette_io::Motion;
use pirouette_register::{register, LikelihoodField, PosePrior, Registration};

use super::adjust::adjust_jointly;
use super::chain::chain_headings;
use super::config::MapConfig;
use super::fields::{field_in, field_of, frame_fields, seen_by};
use super::placed::Placed;
use super::revisits;
use super::route::check_extent;

use crate::error::{Result, SlamError};
use crate::final_grid::FinalGrid;

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
pub(super) fn place_sweep(
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
pub(super) fn refine_pass(
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
        return Err(SlamError::Input {
            problem: format!("a sweep names frame {i} of {}", input.len()),
        });
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
                let prior = forward_prior(&sweeps[s - 1], prev, input[sweep.frames[0]].motion, config);
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
    for p in placed {
        p.pose = origin * p.pose;
        p.covariance = origin.rotate_covariance(&p.covariance);
        if let Some(prior) = p.prior.as_mut() {
            prior.mean = origin * prior.mean;
        }
        if let Some(reg) = p.registration.as_mut() {
            reg.pose = origin * reg.pose;
            if let Some(r) = reg.rival.as_mut() {
                r.pose = origin * r.pose;
            }
            reg.covariance = origin.rotate_covariance(&reg.covariance);
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
    let mut grid = FinalGrid::new(
        &config.grid,
        blind_m,
        "registration placed a sweep far from its command",
    )?;
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
            grid.insert(&frame_poses[i], &input[i].rop)?;
        }
        out.push(SweepPose {
            id: sweep.id,
            pose: frame_poses[sweep.frames[0]],
            prior: p.prior,
            registration: p.registration.clone(),
            covariance: p.covariance,
        });
    }
    Ok((grid.finish(), frame_poses, out))
}

/// The belief in a sweep's first frame after the forward move from the
/// previous sweep's last frame.
pub(super) fn forward_prior(
    prev_sweep: &DatasetSweep,
    prev: &Placed,
    motion: Option<Step>,
    config: &MapConfig,
) -> PosePrior {
    let (last, fallback_var) = last_frame(prev_sweep, prev, config);
    let start = prev.frame_pose(last);
    // The last frame's heading: the sweep's registration, a verified
    // turn's error and a command's per fallback turn.
    let start_var = prev.covariance[(2, 2)] + config.sweep.verified_sigma_rad.powi(2) + fallback_var;
    motion_prior(&start, start_var.sqrt(), motion, config)
}

/// The belief in a sweep's first frame after `motion` from `start`
/// (whose heading is known to `start_sigma_theta_rad`): a commanded
/// straight move, or a general move (odometry's turn and shift), whose
/// turn errs as a commanded turn of that size; with no motion (an image
/// stream without odometry) the turn the visual compass saw
/// ([`COMPASS_SIGMA_RAD`]) or, where it saw none, anything the frames'
/// overlap allows ([`UNKNOWN_TURN_SIGMA_RAD`]), the shift unknown
/// ([`UNKNOWN_SHIFT_SIGMA_M`]).
pub(super) fn motion_prior(
    start: &Pose2,
    start_sigma_theta_rad: f64,
    step: Option<Step>,
    config: &MapConfig,
) -> PosePrior {
    let motion = match step {
        Some(Step::Commanded(m)) => Some(m),
        Some(Step::SeenTurn(turn)) => {
            return PosePrior {
                mean: *start * Pose2::new(0.0, 0.0, turn),
                sigma_forward_m: UNKNOWN_SHIFT_SIGMA_M,
                sigma_left_m: UNKNOWN_SHIFT_SIGMA_M,
                sigma_theta_rad: start_sigma_theta_rad.hypot(COMPASS_SIGMA_RAD),
            }
        }
        // Camera frames carry no odometry.
        None | Some(Step::Odometry(_)) => None,
    };
    match motion {
        None => PosePrior {
            mean: *start,
            sigma_forward_m: UNKNOWN_SHIFT_SIGMA_M,
            sigma_left_m: UNKNOWN_SHIFT_SIGMA_M,
            sigma_theta_rad: start_sigma_theta_rad.hypot(UNKNOWN_TURN_SIGMA_RAD),
        },
        Some(m @ Motion::Move { .. }) => {
            let relative = m.relative_pose();
            let turn_sigma = config.command_sigma(relative.theta);
            PosePrior::after_move(
                start,
                &relative,
                start_sigma_theta_rad,
                turn_sigma,
                &config.motion,
            )
        }
        _ => PosePrior::after_forward(
            start,
            forward_distance(motion),
            start_sigma_theta_rad,
            &config.motion,
        ),
    }
}

/// A sweep's last frame, and the variance its heading takes on from the
/// fallback turns between its block and the sweep's largest (a command's
/// error each).
pub(super) fn last_frame(sweep: &DatasetSweep, placed: &Placed, config: &MapConfig) -> (usize, f64) {
    let last = sweep.frames.len() - 1;
    let last_block = placed
        .blocks
        .iter()
        .position(|b| b.contains(&last))
        .expect("in a block");
    (last, placed.fallback_var(last_block, sweep, config))
}

/// How far a frame of unknown motion may have turned since the last, one
/// standard deviation: frames must share a good part of a camera's view
/// for the images to tell the turn, so within three of these (45°) of a
/// 60° camera.
pub const UNKNOWN_TURN_SIGMA_RAD: f64 = 15.0 * std::f64::consts::PI / 180.0;

/// How far the visual compass's turn may err, one standard deviation: a
/// wall 3 m away seen after a sideways move of 10 cm shifts by 1.9°.
pub const COMPASS_SIGMA_RAD: f64 = 2.0 * std::f64::consts::PI / 180.0;

/// How far a frame of unknown motion may have moved since the last, one
/// standard deviation, metres (a slow robot between two frames).
pub const UNKNOWN_SHIFT_SIGMA_M: f64 = 0.15;

/// The commanded forward move before a sweep, metres (0 without one).
pub(super) fn forward_distance(motion: Option<Motion>) -> f64 {
    match motion {
        Some(Motion::Forward { forward }) => forward,
        _ => 0.0,
    }
}
