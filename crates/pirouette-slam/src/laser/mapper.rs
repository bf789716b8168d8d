//! The running state of registration, scan by scan.

use super::config::LaserConfig;
use super::motion::{at_window_edge, blind_priors, moved_by, step_prior, BlindMotion, MotionSoFar};
use super::revisits::{Keyframes, Track};
use super::run::{LoopClosure, RegisteredLog, ScanPose, SkippedScan};
use crate::backend::edge::{information, Edge as MeasuredEdge};
use crate::backend::nodes::Nodes;
use crate::frame::Frame;
use crate::submap::Submap;
use nalgebra::{Matrix3, Vector3};
use pirouette_geom::{Point2, Pose2};
use pirouette_graph::{Edge as GraphEdge, Kernel, OptimiseConfig};
use pirouette_io::LaserScan;
use pirouette_register::{
    endpoints, far_points, thin_points, PosePrior, RegisterConfig, RegisterError, Registration,
};

use crate::error::{Result, SlamError};
use std::collections::VecDeque;

/// The running state of registration: the poses, the path length to
/// each, the pose graph's edges, the thinned endpoints (in their own
/// frame) of the last scans (the local map's and the newest keyframe's),
/// and the keyframes.
pub(super) struct Mapper<'c> {
    config: &'c LaserConfig,
    /// The endpoints of scans `first..first + recent.len()`.
    recent: VecDeque<Vec<Point2>>,
    first: usize,
    /// Every scan's current pose.
    pub(super) poses: Vec<Pose2>,
    /// The pose graph over the node scans.
    nodes: Nodes,
    along_m: Vec<f64>,
    keyframes: Keyframes,
    loops: Vec<(LoopClosure, usize)>,
    /// Whether a step since the last loop closed was not registered.
    lost: bool,
    /// The path length at the last loop closed, metres.
    closed_at_m: f64,
    /// Whether loop edges were added since the graph was last solved ...
    unsolved: bool,
    /// ... and whether one of them disagreed with the poses (see
    /// [`SOLVE_GATE`]).
    disagree: bool,
    /// Times the graph was solved.
    solves: usize,
    /// Skipped scans placed: each relative to the registered scan before.
    placed: Vec<Placed>,
    /// The newest scan's pose relative to the last registered one (the
    /// identity where that is the newest): the next scan's prior starts
    /// there.
    newest: Pose2,
    /// The steps matched so far, for steps without odometry.
    motion: MotionSoFar,
    /// The local map: one or two active submaps, each anchored at a scan;
    /// scans are matched against the older, which holds from
    /// `local_scans` to twice as many scans (fewer after a step not
    /// registered, which begins them anew). A solve of the graph makes
    /// them anew at the poses solved.
    active: VecDeque<Active>,
}

/// An active submap and the scan it is anchored at.
struct Active {
    submap: Submap,
    /// The scan it is anchored at.
    first: usize,
    /// The first scan it holds (it holds every one registered since).
    from: usize,
}

/// A scan's match against the local map.
pub(super) struct Matched {
    /// The scan's thinned endpoints, in its frame.
    pub points: Vec<Point2>,
    /// The match.
    pub registration: Registration,
    /// Whether the match pins no one pose: another pose apart (beyond
    /// the revisit test's tolerances) explains the scan within its gap,
    /// or the match spreads wider than those tolerances. The one kept may
    /// be wrong.
    pub ambiguous: bool,
}

/// A skipped scan placed against the registered scan before it.
struct Placed {
    scan: usize,
    t: f64,
    /// The registered scan before it (its place among those registered).
    anchor: usize,
    /// Its pose in that scan's frame.
    relative: Pose2,
}

/// A loop edge whose squared Mahalanobis residual at the current poses is
/// at most this (three degrees of freedom, 95 %) agrees with them within
/// its noise: solving the graph for it would move the poses by less than
/// the match measures, so the solve waits for a loop that disagrees (or
/// the log's end). Revisits of ground already closed then cost nothing,
/// and the solves grow with the corrections, not with the revisits.
const SOLVE_GATE: f64 = 7.81;

/// The least spread of a step's or a loop's measured relative pose, one
/// σ: registration's posterior can claim less than a laser's range noise
/// and the local map's own error support.
const EDGE_FLOOR_M: f64 = 0.01;
/// The same for heading, radians.
const EDGE_FLOOR_RAD: f64 = 0.004;

/// The floors' covariance.
fn edge_floor() -> Matrix3<f64> {
    Matrix3::from_diagonal(&Vector3::new(
        EDGE_FLOOR_M.powi(2),
        EDGE_FLOOR_M.powi(2),
        EDGE_FLOOR_RAD.powi(2),
    ))
}

impl<'c> Mapper<'c> {
    /// Nothing registered yet.
    pub(super) fn new(config: &'c LaserConfig) -> Result<Self> {
        Ok(Self {
            config,
            recent: VecDeque::new(),
            first: 0,
            poses: Vec::new(),
            nodes: Nodes::new(),
            along_m: Vec::new(),
            keyframes: Keyframes::new()?,
            loops: Vec::new(),
            lost: false,
            closed_at_m: 0.0,
            unsolved: false,
            disagree: false,
            solves: 0,
            placed: Vec::new(),
            newest: Pose2::IDENTITY,
            motion: MotionSoFar::default(),
            active: VecDeque::new(),
        })
    }

    /// Matches a scan's frame against the local map (the registered scans
    /// before it), from the newest scan's pose moved by the frame's
    /// odometry: its thinned endpoints and the match.
    /// Whether the match is ambiguous: see [`Matched`].
    pub(super) fn matched(&mut self, frame: &Frame, label: &dyn Fn() -> String) -> Result<Matched> {
        let config = self.config;
        let points = self.scan_points(frame);
        let last = self.poses.len() - 1;
        let odometry = frame.odometry();
        let previous = self.poses[last] * self.newest;
        let Some(local) = self.active.front() else {
            return Err(SlamError::Input {
                problem: "a scan matched before any was registered".into(),
            }
            .at(label()));
        };
        let submap = &local.submap;
        let reg = match &odometry {
            Some(step) => self.with_odometry(submap, &points, &previous, step),
            None => self.blind(submap, &points, &previous),
        };
        let step = reg
            .as_ref()
            .ok()
            .filter(|r| r.0.accepted)
            .map(|r| previous.between(&r.0.pose));
        self.motion = self.motion.after(step, config);
        let (registration, ambiguous) = reg.map_err(|e| SlamError::from(e).at(label()))?;
        Ok(Matched {
            points,
            registration,
            ambiguous,
        })
    }

    /// The registration settings of a step's match: rivals counted at the
    /// revisit test's tolerances (a step's rival is a second answer).
    fn step_register(&self) -> RegisterConfig {
        let t = &self.config.loops.revisit;
        RegisterConfig {
            rival_apart_m: t.rival_apart_m,
            rival_apart_rad: t.rival_apart_rad,
            rival_gap_ln: t.min_rival_gap_ln,
            ..self.config.register.clone()
        }
    }

    /// Whether a trusted match does not pin one pose: a rival peak within
    /// the revisit test's gap, or a posterior spread (one σ) beyond its
    /// tolerances (a corridor's length the scan does not tell, where the
    /// prior alone placed it).
    fn pins_no_pose(&self, reg: &Registration) -> bool {
        let t = &self.config.loops.revisit;
        let c = &reg.covariance;
        let spread_m = nalgebra::Matrix2::new(c[(0, 0)], c[(0, 1)], c[(1, 0)], c[(1, 1)])
            .symmetric_eigenvalues()
            .max()
            .max(0.0)
            .sqrt();
        let loose = spread_m > t.rival_apart_m || c[(2, 2)].max(0.0).sqrt() > t.rival_apart_rad;
        reg.accepted && (loose || reg.rival.is_some_and(|r| r.below_best_ln < t.min_rival_gap_ln))
    }

    /// A match from `previous` moved by the step's odometry. A best pose
    /// on the window's edge may have a better one beyond: the odometry was
    /// wrong by more than its noise (a wheel slipping, a robot pushed).
    /// Searched again, three times as wide; that answer counts where its
    /// best lies inside its own window (one on the edge again is a ridge,
    /// a corridor's length, that a wider window only slides along: the
    /// odometry's pose stands there).
    fn with_odometry(
        &self,
        submap: &Submap,
        points: &[Point2],
        previous: &Pose2,
        step: &Pose2,
    ) -> Result<(Registration, bool), RegisterError> {
        let config = self.config;
        let register_config = self.step_register();
        let prior = moved_by(previous, step, &config.odometry);
        let reg = submap.register(points, &prior, &register_config)?;
        let cell = config.field_resolution_m;
        // The window's edge in the submap's frame, where it was searched.
        let on_edge = |prior: &PosePrior, pose: &Pose2| {
            at_window_edge(
                &submap.local_prior(prior),
                &submap.local_pose(pose),
                &config.register,
                cell,
            )
        };
        if reg.accepted && on_edge(&prior, &reg.pose) {
            let wide = PosePrior {
                sigma_forward_m: 3.0 * prior.sigma_forward_m,
                sigma_left_m: 3.0 * prior.sigma_left_m,
                sigma_theta_rad: 3.0 * prior.sigma_theta_rad,
                ..prior
            };
            let again = submap.register(points, &wide, &register_config)?;
            if again.accepted && !on_edge(&wide, &again.pose) {
                let ambiguous = self.pins_no_pose(&again);
                return Ok((again, ambiguous));
            }
        }
        let ambiguous = self.pins_no_pose(&reg);
        Ok((reg, ambiguous))
    }

    /// A match of a step without odometry: one under each of
    /// [`blind_priors`], the trusted one of highest posterior density
    /// kept (the endpoints' summed log-likelihood at its pose plus its
    /// prior's normalised log density there). A motion that breaks the
    /// robot's course (see [`BlindMotion::keeps_course`]) is taken only
    /// where it beats every trusted one that keeps it by
    /// the revisit test's rival gap
    /// ([`RevisitTest::min_rival_gap_ln`](crate::revisit::RevisitTest::min_rival_gap_ln)): in a corridor, a half turn
    /// explains a scan about as well as a step on, and a robot keeps its
    /// course far more often than it turns round. None trusted, the first
    /// prior's answer. Ambiguous where the match kept has a rival peak, or
    /// another motion's trusted match lies apart from it (beyond the
    /// revisit test's tolerances) with a posterior density within the gap
    /// of its own.
    fn blind(
        &self,
        submap: &Submap,
        points: &[Point2],
        previous: &Pose2,
    ) -> Result<(Registration, bool), RegisterError> {
        let config = self.config;
        let register_config = self.step_register();
        let mut trusted: Vec<(f64, BlindMotion, Registration)> = Vec::new();
        let mut untrusted = None;
        for (motion, prior) in blind_priors(previous, &self.motion, config) {
            let reg = submap.register(points, &prior, &register_config)?;
            if reg.accepted {
                let ln = reg.mean_log_likelihood * reg.points as f64 + prior.ln_density(&reg.pose);
                trusted.push((ln, motion, reg));
            } else if untrusted.is_none() {
                untrusted = Some(reg);
            }
        }
        let most = |keeping: bool| {
            trusted
                .iter()
                .filter(|t| !keeping || t.1.keeps_course())
                .max_by(|a, b| a.0.total_cmp(&b.0))
        };
        let chosen = match (most(false), most(true)) {
            (Some(best), Some(course)) if best.0 - course.0 < config.loops.revisit.min_rival_gap_ln => {
                Some(course)
            }
            (best, _) => best,
        };
        let gap = config.loops.revisit.min_rival_gap_ln;
        let t = &config.loops.revisit;
        match (chosen, untrusted) {
            (Some(c), _) => {
                let apart = |r: &Registration| {
                    let d = c.2.pose.between(&r.pose);
                    d.translation().norm() > t.rival_apart_m || d.theta.abs() > t.rival_apart_rad
                };
                let rival = trusted.iter().any(|o| o.0 > c.0 - gap && apart(&o.2));
                Ok((c.2.clone(), rival || self.pins_no_pose(&c.2)))
            }
            (None, Some(reg)) => Ok((reg, false)),
            (None, None) => Ok((
                submap.register(points, &step_prior(previous, None, config), &register_config)?,
                false,
            )),
        }
    }

    /// Registers scan `k` (`points` its thinned endpoints, `reg` its match,
    /// `None` for the first): the local map and the graph take it.
    /// Whether its registration was trusted.
    pub(super) fn take(&mut self, k: usize, points: Vec<Point2>, reg: Option<&Registration>) -> bool {
        self.remember(k, points);
        self.newest = Pose2::IDENTITY;
        let accepted = self.place(k, reg);
        // A step not registered breaks the local map: the scans after it
        // begin one of their own (placed against what came before by loop
        // closure), as matches against the map before it would take its
        // walls from a prior that is only a guess.
        if !accepted {
            self.active.clear();
        }
        self.insert_local(k);
        accepted
    }

    /// Scan `k`'s pose and the graph's step to it (see [`Mapper::take`]).
    fn place(&mut self, k: usize, reg: Option<&Registration>) -> bool {
        let Some(reg) = reg else {
            self.poses.push(Pose2::IDENTITY);
            self.along_m.push(0.0);
            return true;
        };
        let step = self.poses[k - 1].between(&reg.pose);
        let covariance = self.local_covariance(k - 1, &reg.covariance);
        self.poses.push(reg.pose);
        self.along_m.push(self.along_m[k - 1] + step.translation().norm());
        let node = self.is_node(k);
        self.nodes.step(&step, &covariance, reg.pose, node);
        self.lost |= !reg.accepted;
        reg.accepted
    }

    /// Inserts registered scan `k` into the active submaps; one is begun
    /// (anchored at `k`) when the newest holds `local_scans`, and the
    /// oldest finished when it holds twice as many: the one matched
    /// against always holds the last `local_scans` scans at least.
    fn insert_local(&mut self, k: usize) {
        let half = self.config.local_scans;
        let pose = self.poses[k];
        if self.active.is_empty() {
            self.active.push_back(self.begin(k, k));
        }
        let points = &self.recent[k - self.first];
        for a in self.active.iter_mut() {
            a.submap.insert(&pose, points);
        }
        if self.active.back().is_some_and(|a| a.submap.frames() >= half) {
            self.active.push_back(self.begin(k, k + 1));
        }
        if self.active.len() > 1 && self.active.front().is_some_and(|a| a.submap.frames() >= 2 * half) {
            self.active.pop_front();
        }
    }

    /// An empty submap anchored at scan `k`.
    fn begin(&self, k: usize, from: usize) -> Active {
        Active {
            submap: Submap::new(
                self.poses[k],
                self.config.field_resolution_m,
                &self.config.register,
            ),
            first: k,
            from,
        }
    }

    /// Places a scan the motion filter leaves out at `relative`, its
    /// matched pose in the last registered scan's frame.
    pub(super) fn skip(&mut self, scan: &LaserScan, relative: Pose2) {
        let anchor = self.poses.len() - 1;
        self.placed.push(Placed {
            scan: scan.scan,
            t: scan.t,
            anchor,
            relative,
        });
        self.newest = relative;
    }

    /// A scan's thinned endpoints (those it sees and those beyond the
    /// map's limit within reach), in its frame.
    pub(super) fn scan_points(&self, frame: &Frame) -> Vec<Point2> {
        let config = self.config;
        let mut points = endpoints(&frame.compared);
        points.extend(far_points(&frame.compared, config.reach_m));
        thin_points(&points, config.register.spacing_m.max(config.field_resolution_m))
    }

    /// After scan `k` is placed: a keyframe filed where one is wanted,
    /// and every [`LoopConfig::every_scans`] a search for revisits, the
    /// graph solved where one was found.
    pub(super) fn revisit(&mut self, k: usize) -> Result<()> {
        let every = self.config.loops.every_scans;
        if every > 0 {
            self.file_keyframe(k)?;
            if k > 0 && k % every == 0 && self.close_loops(k)? {
                self.unsolved = true;
                if self.disagree {
                    self.optimise();
                }
            }
        }
        Ok(())
    }

    /// The registered log: `meta` with the final poses, the loops, and
    /// the graph without the loop edges its last solve left out.
    pub(super) fn finish(mut self, mut meta: Vec<ScanPose>) -> Result<RegisteredLog> {
        if self.unsolved {
            self.optimise();
        }
        for (s, p) in meta.iter_mut().zip(&self.poses) {
            s.pose = *p;
        }
        let Nodes {
            graph, scans: nodes, ..
        } = self.nodes;
        for (closure, e) in &mut self.loops {
            closure.kept = graph.kept(*e);
        }
        let graph = graph.into_kept();
        let skipped = (self.placed.iter())
            .map(|p| SkippedScan {
                scan: p.scan,
                t: p.t,
                pose: self.poses[p.anchor] * p.relative,
            })
            .collect();
        Ok(RegisteredLog {
            scans: meta,
            skipped,
            info: pirouette_io::LogInfo {
                format: "",
                scan_topic: None,
                motion: None,
                mount: Pose2::IDENTITY,
                skipped: Vec::new(),
                warnings: Vec::new(),
            },
            loops: self.loops.into_iter().map(|(l, _)| l).collect(),
            loop_searches: self.keyframes.searches,
            keyframes: self.keyframes.len(),
            solves: self.solves,
            graph,
            nodes,
        })
    }

    /// The endpoints of scan `k`, in its frame (a recent scan).
    fn points(&self, k: usize) -> &[Point2] {
        &self.recent[k - self.first]
    }

    /// Files scan `k`'s endpoints, forgetting those no local map or
    /// keyframe needs any more.
    fn remember(&mut self, k: usize, points: Vec<Point2>) {
        let c = &self.config;
        // The active submaps' scans, and a keyframe's.
        let keep = (2 * c.local_scans + 1).max(2 * c.loops.anchor_scans + 1);
        self.recent.push_back(points);
        while self.recent.len() > keep {
            self.recent.pop_front();
            self.first += 1;
        }
        debug_assert_eq!(self.first + self.recent.len(), k + 1);
    }

    /// The poses and path lengths so far.
    fn track(&self) -> Track<'_> {
        Track {
            poses: &self.poses,
            along_m: &self.along_m,
        }
    }

    /// Makes scan `k − anchor_scans` a keyframe (its neighbours now all
    /// placed) where no keyframe lies near it.
    fn file_keyframe(&mut self, k: usize) -> Result<()> {
        let c = &self.config.loops;
        let Some(j) = k.checked_sub(c.anchor_scans) else {
            return Ok(());
        };
        // A keyframe is a loop's earlier end: a node of the graph.
        if self.nodes.node_of(j).is_none() || !self.keyframes.wanted(self.config, &self.track(), j) {
            return Ok(());
        }
        let points = self.points_in_frame(j, j.saturating_sub(c.anchor_scans)..k + 1);
        // Its view: every scan remembered, the 180° scanners' blind backs
        // filled by the scans before.
        let seen = self.points_in_frame(j, self.first..k + 1);
        let spacing = self.config.register.spacing_m.max(self.config.field_resolution_m);
        let along = self.along_m[k];
        self.keyframes
            .file(self.config, j, along, thin_points(&points, spacing), &seen)
    }

    /// The endpoints of recent scans `range` in scan `j`'s frame.
    fn points_in_frame(&self, j: usize, range: std::ops::Range<usize>) -> Vec<Point2> {
        let to_j = self.poses[j].inverse();
        range
            .flat_map(|m| {
                let rel = to_j * self.poses[m];
                self.points(m).iter().map(move |p| rel.transform_point(*p))
            })
            .collect()
    }

    /// A registered pose's covariance (in the world frame) in the frame of
    /// scan `i`'s current pose, with the floors added.
    fn local_covariance(&self, i: usize, covariance: &Matrix3<f64>) -> Matrix3<f64> {
        self.poses[i].unrotate_covariance(covariance) + edge_floor()
    }

    /// A loop edge `i → j` measuring `j`'s registered pose `pose_j` (with
    /// its world covariance) in the frame of `i`'s current pose, between
    /// scans `i` and `j`.
    fn loop_edge(&self, i: usize, j: usize, pose_j: &Pose2, covariance: &Matrix3<f64>) -> GraphEdge {
        let mut e = MeasuredEdge {
            i,
            j,
            z: self.poses[i].between(pose_j),
            info: information(&self.local_covariance(i, covariance)),
        }
        .to_graph();
        e.kernel = Kernel::Cauchy { c: 1.0 };
        e
    }

    /// Whether scan `k` (placed) is to be a node of the graph: every scan
    /// searched for revisits (a loop's later end) and every scan that may
    /// become a keyframe (a loop's earlier end); every scan where loops
    /// are not closed.
    fn is_node(&self, k: usize) -> bool {
        let every = self.config.loops.every_scans;
        every == 0 || k % every == 0 || self.keyframes.wanted(self.config, &self.track(), k)
    }

    /// Searches the keyframes for the place of scan `k`; each match found
    /// becomes a loop edge. Whether any did.
    fn close_loops(&mut self, k: usize) -> Result<bool> {
        let c = &self.config.loops;
        // The estimate may be out of the search near it when a step since
        // the last loop was not registered, or when the path since has
        // grown drift beyond its radius: then the view is asked as well.
        let drift_reach_m = (c.max_radius_m - c.radius_m) / c.radius_per_m.max(1e-9);
        let lost = self.lost || self.along_m[k] - self.closed_at_m > drift_reach_m;
        let local = if lost {
            self.points_in_frame(k, k.saturating_sub(self.config.local_scans)..k + 1)
        } else {
            Vec::new()
        };
        let track = Track {
            poses: &self.poses,
            along_m: &self.along_m,
        };
        let scan = &self.recent[k - self.first];
        let found = self
            .keyframes
            .search(self.config, &track, k, scan, lost.then_some(&local[..]))?;
        if !found.is_empty() {
            self.lost = false;
            self.closed_at_m = self.along_m[k];
        }
        for f in &found {
            let reg = &f.registration;
            let edge = self.loop_edge(f.from, f.to, &reg.pose, &reg.covariance);
            let chi2 = edge.chi2(&self.poses[f.from], &self.poses[f.to]);
            // Both ends are nodes: a keyframe and a searched scan.
            let Some(e) = self.nodes.add(edge) else {
                continue;
            };
            self.disagree |= chi2 > SOLVE_GATE;
            let closure = LoopClosure {
                from: f.from,
                to: f.to,
                recognised: f.recognised,
                kept: true,
            };
            self.loops.push((closure, e));
        }
        Ok(!found.is_empty())
    }

    /// Solves the pose graph of the scans so far ([`Graph::solve`]:
    /// the loops checked against each other first, those the solution
    /// contradicts dropped); the poses follow.
    ///
    /// [`Graph::solve`]: crate::backend::solve::Graph::solve
    fn optimise(&mut self) {
        let config = OptimiseConfig {
            max_iterations: 20,
            ..OptimiseConfig::default()
        };
        self.solves += 1;
        // A graph that cannot be solved keeps its poses.
        if !self.nodes.graph.solve(&config) {
            return;
        }
        for (p, q) in self.poses.iter_mut().zip(self.nodes.poses()) {
            *p = q;
        }
        self.unsolved = false;
        self.disagree = false;
        // The active submaps made anew of their scans at the poses solved
        // (a submap moved whole with its anchor would keep the drift the
        // solve took out of it).
        // (Each dropped before its successor is made: memory holds two.)
        let held: Vec<(usize, usize)> = self.active.drain(..).map(|a| (a.first, a.from)).collect();
        for (first, from) in held {
            let mut again = self.begin(first, from);
            for k in from..self.poses.len() {
                again.submap.insert(&self.poses[k], self.points(k));
            }
            self.active.push_back(again);
        }
        self.keyframes.forget_pending();
    }
}
