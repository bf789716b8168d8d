//! Revisits of a laser log: places kept as keyframes (a scan with its
//! neighbours' endpoints, at most one per half metre of ground), found again by
//! where the estimate puts the robot and, where that finds nothing, by
//! what the robot sees (the place index of the keyframes' 360° views),
//! and verified by registration.

use super::LaserConfig;
use crate::backend::places::Places;
use crate::error::Result;
use pirouette_geom::{Point2, Pose2};
use pirouette_places::QueryConfig;
use pirouette_profile::Rop;
use pirouette_register::{LikelihoodField, PosePrior, Registration};
use std::f64::consts::{PI, TAU};

/// Bins of a 360° view ([`view`]): 1° each, as the place index samples.
const VIEW_BINS: usize = 360;

/// A place kept for revisits.
struct Keyframe {
    /// The scan.
    scan: usize,
    /// The path length to the last scan of its map, metres.
    last_along_m: f64,
    /// The map's endpoints, thinned, in the scan's frame.
    points: Vec<Point2>,
}

/// The scans placed so far, as a search reads them.
pub(super) struct Track<'a> {
    /// Every scan's current pose.
    pub poses: &'a [Pose2],
    /// The path length to every scan, metres.
    pub along_m: &'a [f64],
}

/// A revisit found and verified: a scan registered on a keyframe's map.
pub(super) struct Found {
    /// The keyframe's scan.
    pub from: usize,
    /// The scan that came back.
    pub to: usize,
    /// The scan's pose on that map.
    pub registration: Registration,
    /// Whether the place index found it (the estimate did not).
    pub recognised: bool,
}

/// The keyframes and the place index of their views (each place's node
/// a keyframe's place among them).
pub(super) struct Keyframes {
    frames: Vec<Keyframe>,
    places: Places,
    /// A revisit the place index found, awaiting confirmation.
    pending: Option<Found>,
    /// Registrations tried.
    pub searches: usize,
}

impl Keyframes {
    /// No keyframes yet.
    pub fn new() -> Result<Self> {
        Ok(Self {
            frames: Vec::new(),
            places: Places::new("log")?,
            pending: None,
            searches: 0,
        })
    }

    /// How many places are kept.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Drops a revisit awaiting confirmation: the poses it was measured
    /// against have moved.
    pub fn forget_pending(&mut self) {
        self.pending = None;
    }

    /// Whether scan `j` lies farther than the keyframe spacing from every
    /// keyframe.
    pub fn wanted(&self, config: &LaserConfig, track: &Track, j: usize) -> bool {
        let here = track.poses[j].translation();
        self.frames.iter().all(|f| {
            let t = track.poses[f.scan].translation();
            t.distance(here) >= config.loops.keyframe_spacing_m
        })
    }

    /// Keeps scan `j` as a keyframe with its map (thinned endpoints in its
    /// frame, the last of them `last_along_m` along the path), filing the
    /// view of the points `seen` about it (the map and more, in its frame)
    /// in the place index where they cover enough of the circle.
    pub fn file(
        &mut self,
        config: &LaserConfig,
        j: usize,
        last_along_m: f64,
        points: Vec<Point2>,
        seen: &[Point2],
    ) -> Result<()> {
        let seen = view(seen, config.max_range_m);
        if let Some(signature) = self.places.signature(&seen)? {
            let id = u32::try_from(j).unwrap_or(u32::MAX);
            self.places
                .file(self.frames.len(), id, &signature, &seen, false)?;
        }
        self.frames.push(Keyframe {
            scan: j,
            last_along_m,
            points,
        });
        Ok(())
    }

    /// Searches the keyframes for the place of scan `k` (its thinned
    /// endpoints `scan`): those near its estimated pose, and where there
    /// are none and the estimate may be lost (`local` given: the local
    /// map's points, in scan `k`'s frame), those whose views the place
    /// index finds like the local map's. The matches found.
    pub fn search(
        &mut self,
        config: &LaserConfig,
        track: &Track,
        k: usize,
        scan: &[Point2],
        local: Option<&[Point2]>,
    ) -> Result<Vec<Found>> {
        let c = &config.loops;
        let candidates = self.near(config, track, k);
        let mut found = Vec::new();
        for &(i, radius) in &candidates {
            let prior = PosePrior {
                mean: track.poses[k],
                sigma_forward_m: radius / 3.0,
                sigma_left_m: radius / 3.0,
                sigma_theta_rad: c.sigma_rad,
            };
            if let Some(registration) = self.verify(config, track, i, scan, &prior)? {
                let from = self.frames[i].scan;
                found.push(Found {
                    from,
                    to: k,
                    registration,
                    recognised: false,
                });
            }
        }
        // The estimate, possibly lost, says new ground: the view may still
        // know it.
        let Some(local) = local.filter(|_| candidates.is_empty() && c.index_candidates > 0) else {
            return Ok(found);
        };
        if self.places.index().is_empty() {
            return Ok(found);
        }
        let Ok(Some(signature)) = self.places.signature(&view(local, config.max_range_m)) else {
            return Ok(found);
        };
        let mut tried: Vec<usize> = candidates.iter().map(|&(i, _)| i).collect();
        for answer in self.places.index().query(&signature, &QueryConfig::default()) {
            if tried.len() >= candidates.len() + c.index_candidates
                || f64::from(answer.profile_rms_m) > c.max_profile_rms_m
            {
                break;
            }
            let i = self.places.node(answer.place);
            let (from, last_along_m) = (self.frames[i].scan, self.frames[i].last_along_m);
            if tried.contains(&i) || track.along_m[k] - last_along_m < c.min_separation_m {
                continue;
            }
            tried.push(i);
            let prior = PosePrior {
                mean: track.poses[from] * Pose2::new(0.0, 0.0, answer.rotation_rad),
                sigma_forward_m: c.index_sigma_m,
                sigma_left_m: c.index_sigma_m,
                sigma_theta_rad: c.sigma_rad,
            };
            if let Some(registration) = self.verify(config, track, i, scan, &prior)? {
                let recognised = Found {
                    from,
                    to: k,
                    registration,
                    recognised: true,
                };
                found.extend(self.confirm(config, track, recognised));
                break;
            }
        }
        Ok(found)
    }

    /// A revisit the place index found counts once a second one, a few
    /// scans on, moves the estimate the same way (a look-alike place
    /// pulls each scan its own way): both, where `found` confirms the one
    /// pending, else none (and `found` waits for its confirmation).
    fn confirm(&mut self, config: &LaserConfig, track: &Track, found: Found) -> Vec<Found> {
        let c = &config.loops;
        // The move from the estimate to the registered pose, as it applies
        // at scan `to`.
        let correction = |f: &Found| f.registration.pose * track.poses[f.to].inverse();
        let agree = self.pending.as_ref().is_some_and(|p| {
            let recent = found.to - p.to <= 2 * c.every_scans;
            let at = track.poses[found.to];
            let (a, b) = (correction(p) * at, correction(&found) * at);
            let shift = a.translation().distance(b.translation());
            let turn = pirouette_geom::wrap_angle(a.theta - b.theta).abs();
            recent && shift <= c.revisit.rival_apart_m && turn <= c.revisit.rival_apart_rad
        });
        match self.pending.take() {
            Some(p) if agree => vec![p, found],
            _ => {
                self.pending = Some(found);
                Vec::new()
            }
        }
    }

    /// The keyframes that scan `k` may be revisiting by its estimated
    /// pose, nearest first, with the search radius of each.
    fn near(&self, config: &LaserConfig, track: &Track, k: usize) -> Vec<(usize, f64)> {
        let c = &config.loops;
        let here = track.poses[k].translation();
        let along = |i: usize| track.along_m[self.frames[i].scan];
        let mut near: Vec<(usize, f64, f64)> = (self.frames.iter().enumerate())
            .filter(|(_, f)| track.along_m[k] - f.last_along_m >= c.min_separation_m)
            .filter_map(|(i, f)| {
                let d = track.poses[f.scan].translation();
                let dist = d.distance(here);
                let since = track.along_m[k] - along(i);
                let radius = (c.radius_m + c.radius_per_m * since).min(c.max_radius_m);
                (dist <= radius).then_some((i, dist, radius))
            })
            .collect();
        near.sort_by(|a, b| a.1.total_cmp(&b.1));
        let mut chosen: Vec<(usize, f64)> = Vec::new();
        for (i, _, radius) in near {
            if chosen.len() == c.max_candidates {
                break;
            }
            if chosen
                .iter()
                .all(|&(o, _)| (along(o) - along(i)).abs() >= c.min_separation_m)
            {
                chosen.push((i, radius));
            }
        }
        chosen
    }

    /// Registers `scan` on keyframe `i`'s map from `prior` (searched
    /// within its ±3σ): the registration where it is a revisit (see
    /// [`crate::revisit`]).
    fn verify(
        &mut self,
        config: &LaserConfig,
        track: &Track,
        i: usize,
        scan: &[Point2],
        prior: &PosePrior,
    ) -> Result<Option<Registration>> {
        let c = &config.loops;
        let r = &config.register;
        self.searches += 1;
        let f = &self.frames[i];
        let map: Vec<Point2> = f
            .points
            .iter()
            .map(|p| track.poses[f.scan].transform_point(*p))
            .collect();
        let field = LikelihoodField::from_points(&map, config.field_resolution_m, r.sigma_m, r.epsilon);
        let window_m = 3.0 * prior.sigma_forward_m.max(prior.sigma_left_m);
        c.revisit.register(&field, scan, prior, window_m, r)
    }
}

/// The 360° view of obstacle points around a spot (the points in its
/// frame): each 1° bin the nearest point's range, bins no point falls in
/// unseen.
pub(super) fn view(points: &[Point2], max_range_m: f32) -> Rop {
    let mut rop = Rop::empty(-PI, TAU / VIEW_BINS as f64, VIEW_BINS, max_range_m);
    for p in points {
        let r = p.norm() as f32;
        if r.is_finite() && r > 0.0 {
            rop.insert(p.bearing(), r, None);
        }
    }
    rop
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_view_holds_the_nearest_point_of_each_bearing() {
        let points = [
            Point2::new(2.0, 0.0005),
            Point2::new(3.0, 0.001),
            Point2::new(0.0, -1.5),
            Point2::new(-4.0, -0.0001),
        ];
        let rop = view(&points, 20.0);
        let bin = |deg: f64| ((deg + 180.0).floor() as usize).min(359);
        assert_eq!(rop.range_m[bin(0.0)], 2.0);
        assert_eq!(rop.range_m[bin(-90.0)], 1.5);
        // Just past −180°: the first bin.
        assert_eq!(rop.range_m[0], 4.0);
        assert_eq!(rop.range_m.iter().filter(|r| !r.is_nan()).count(), 3);
    }
}
