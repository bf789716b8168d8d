//! A sweep as placed: its blocks of frames that verified turns join,
//! its pose and each frame's about it.

use crate::frame::DatasetSweep;
use crate::frame::Frame;
use nalgebra::Matrix3;
use pirouette_geom::{Point2, Pose2};
use pirouette_profile::Rop;
use pirouette_register::{endpoints, far_points, PosePrior, Registration};

use super::config::MapConfig;

/// Splits a sweep into blocks: frames that verified matches join
/// (consecutive turns, the loop closure, re-matches after the loop), whose
/// headings relative to each other are known to a match's accuracy.
/// Blocks are sorted by their first frame.
pub(super) fn blocks_of(sweep: &DatasetSweep) -> Vec<Vec<usize>> {
    components(sweep.frames.len(), &sweep.sweep.links)
}

/// The connected components of `n` frames joined by `links`, each sorted,
/// sorted by their first frame.
pub(super) fn components(n: usize, links: &[(usize, usize)]) -> Vec<Vec<usize>> {
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
pub(super) struct Placed {
    /// `map_from_robot` of the sweep's first frame.
    pub(super) pose: Pose2,
    /// Heading of each frame relative to the first, radians.
    pub(super) heading_rad: Vec<f64>,
    /// Blocks of frames (positions within the sweep).
    pub(super) blocks: Vec<Vec<usize>>,
    /// The largest block: the next sweep's heading prior counts the
    /// fallback turns from it to the last frame's block.
    pub(super) reference: usize,
    pub(super) prior: Option<PosePrior>,
    pub(super) registration: Option<Registration>,
    pub(super) covariance: Matrix3<f64>,
    /// The point the robot turns about, in its own frame, metres (see
    /// [`pirouette_profile::sweep::pivot_from_turns`]): a robot a few
    /// millimetres off it moves its centre round a circle in a pirouette.
    pub(super) pivot: [f64; 2],
}

impl Placed {
    /// A sweep at `pose`, its largest block the reference, its frames
    /// turned about `pivot`.
    pub(super) fn new(sweep: &DatasetSweep, pose: Pose2, pivot: [f64; 2]) -> Self {
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
    pub(super) fn rel(&self, k: usize) -> Pose2 {
        let pivot = Point2::new(self.pivot[0], self.pivot[1]);
        let at = |h: f64| pivot.rotated(h);
        let (p0, pk) = (at(self.heading_rad[0]), at(self.heading_rad[k]));
        Pose2::new(p0.x - pk.x, p0.y - pk.y, self.heading_rad[k])
    }

    /// `map_from_robot` of the sweep's `k`-th frame.
    pub(super) fn frame_pose(&self, k: usize) -> Pose2 {
        self.pose * self.rel(k)
    }

    /// The endpoints and far points of some of the sweep's frames, in its
    /// first frame.
    pub(super) fn points(
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
    pub(super) fn fallback_var(&self, b: usize, sweep: &DatasetSweep, config: &MapConfig) -> f64 {
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
pub(super) fn frame_points(rop: &Rop, config: &MapConfig) -> Vec<Point2> {
    let mut points = endpoints(rop);
    points.extend(far_points(rop, far_reach_m(rop, config)));
    points
}

/// How far registration matches a profile's ranges, metres.
pub(super) fn far_reach_m(rop: &Rop, config: &MapConfig) -> f64 {
    rop.max_range_m as f64 * config.far_reach
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
}
