//! Places: a dataset's sweeps filed in a place index, and a query sweep
//! answered with the place it was taken at and its pose there.
//!
//! [`localise`] takes the index's candidates for a sweep
//! ([`PlaceIndex::query`]: key search, shift search, colour), registers
//! the sweep against each of the best few's stored profile (the
//! registration maps use, started at the shift search's rotation), scores
//! each by how much of the two views the other explains, and answers with
//! the best where its score clears a threshold and no look-alike comes
//! close.

use crate::error::{Result, SlamError};
use crate::frame::DatasetSweep;
use crate::mapping::MapRun;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use pirouette_geom::{Point2, Pose2};
use pirouette_grid::OccupancyGrid;
use pirouette_io::Dataset;
use pirouette_places::{
    relative_chroma, Candidate, PlaceIndex, PlaceMeta, PlacesError, QueryConfig, Signature, StoredProfile,
};
use pirouette_profile::Rop;
use pirouette_register::{register, LikelihoodField, PosePrior, RegisterConfig};

/// How a query is answered.
#[derive(Debug, Clone, PartialEq)]
pub struct LocaliseConfig {
    /// The index search.
    pub query: QueryConfig,
    /// Candidates (a place at one rotation, best first) refined by
    /// registration.
    pub refined: usize,
    /// The registration.
    pub register: RegisterConfig,
    /// Resolution of a stored profile's likelihood field, metres.
    pub field_resolution_m: f64,
    /// Spread of the registration's prior on position, metres: how far
    /// from a stored place a query is looked for (a window of
    /// [`RegisterConfig::window_sigmas`] of it).
    pub sigma_position_m: f64,
    /// Spread of the prior on heading about the shift search's rotation,
    /// radians.
    pub sigma_heading_rad: f64,
    /// The least score of an answer: below it, "unknown place".
    pub min_score: f64,
    /// The least margin of the answer's score over a rival's (another
    /// answer: see [`Answer::rival`]): below it, "ambiguous".
    pub min_margin: f64,
    /// Two matches within this distance of each other (in the map of
    /// their places' dataset) are one answer, metres ...
    pub same_answer_m: f64,
    /// ... and within this heading, radians.
    pub same_answer_rad: f64,
    /// Where no candidate reaches [`Self::min_score`] at the shift search's
    /// rotations, the first this many places are registered again from
    /// headings all round the circle (a view a decimetre or more from the
    /// stored spot can line up best at a wrong rotation of its profile).
    pub fallback_places: usize,
}

impl Default for LocaliseConfig {
    /// The index's defaults; the best 8 candidates refined (so that a
    /// look-alike of the best is among them to be seen); registration as
    /// maps use it, on a 1 cm field; a place looked for within ±45 cm
    /// (σ 15 cm) and ±15° of the shift search (σ 5°); an answer trusted
    /// where it explains at least 60 % of both views, 10 points more than
    /// any rival (matches more than 30 cm or 10° apart are two answers:
    /// twice the position prior's σ and its heading's); failing that, the
    /// 3 first places tried from every 4σ of heading (20°) round the
    /// circle.
    fn default() -> Self {
        Self {
            query: QueryConfig::default(),
            refined: 8,
            register: RegisterConfig::default(),
            field_resolution_m: 0.01,
            sigma_position_m: 0.15,
            sigma_heading_rad: 5f64.to_radians(),
            min_score: 0.6,
            min_margin: 0.1,
            same_answer_m: 0.3,
            same_answer_rad: 10f64.to_radians(),
            fallback_places: 3,
        }
    }
}

/// What became of a query.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// A place was found.
    Known,
    /// No stored place explains the sweep well enough.
    Unknown,
    /// A look-alike place explains it nearly as well.
    Ambiguous,
    /// The sweep saw too little of the circle to be looked up.
    Incomplete,
}

impl Verdict {
    /// The word written in JSON.
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Known => "known",
            Verdict::Unknown => "unknown",
            Verdict::Ambiguous => "ambiguous",
            Verdict::Incomplete => "incomplete",
        }
    }
}

/// A refined candidate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaceMatch {
    /// The place's index.
    pub place: usize,
    /// The query's first frame in the place's first-frame frame.
    pub pose: Pose2,
    /// Share of the two views' obstacle points (each view's points within
    /// two σ of the other's obstacles, averaged over both), 0-1.
    pub score: f64,
    /// The shift search's rotation, radians.
    pub rotation_rad: f64,
}

/// The answer to one query sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct Answer {
    /// What became of it.
    pub verdict: Verdict,
    /// The best refined candidate (an answer only where `verdict` is
    /// [`Verdict::Known`]).
    pub best: Option<PlaceMatch>,
    /// The best score less the best rival's (the best score where there
    /// is no rival).
    pub margin: f64,
    /// The best rival: the best-scoring match that puts the query
    /// elsewhere (see [`LocaliseConfig::same_answer_m`]), or at a place
    /// whose view the best's does not explain where the index cannot
    /// tell; before those, the best moved to its place's look-alike
    /// ([`PlaceMeta::look_alike`], scored as the best). An ambiguous
    /// answer lists it beside the best.
    pub rival: Option<PlaceMatch>,
    /// Candidates the index returned.
    pub candidates: usize,
}

impl Answer {
    /// The trusted match, if any.
    pub fn trusted(&self) -> Option<&PlaceMatch> {
        self.best.as_ref().filter(|_| self.verdict == Verdict::Known)
    }
}

/// Files the sweeps of a dataset's run in the index, as places of the
/// dataset. Where the run's `map` is given, each place keeps its first
/// frame's pose in that map and its look-alike there ([`look_alike`],
/// searched with `config`). A sweep that saw too little of the circle is
/// not filed; returns how many were filed and the ids of those left out.
pub fn file_sweeps(
    index: &mut PlaceIndex,
    ds: &Dataset,
    sweeps: &[DatasetSweep],
    map: Option<&MapRun>,
    config: &LocaliseConfig,
) -> Result<(usize, Vec<u32>)> {
    let name = &ds.manifest.name;
    let dataset = index.dataset_id(name);
    let mut left_out = Vec::new();
    let mut filed = 0;
    let at = |id: u32| format!("{}: sweep {id}", ds.manifest_path().display());
    let walls = map.and_then(|m| LookAlikeMap::of(&m.grid, config));
    for s in sweeps {
        let signature = match index.transforms().signature(&s.sweep.rop) {
            Ok(sig) => sig,
            Err(PlacesError::IncompleteSweep { .. }) => {
                left_out.push(s.id);
                continue;
            }
            Err(e) => return Err(SlamError::from(e).at(at(s.id))),
        };
        let map_pose = map.and_then(|m| m.frame_poses.get(s.frames[0])).copied();
        let truth = ds.manifest.frames[s.frames[0]]
            .truth
            .map(|t| [t.x, t.y, t.theta_deg.to_radians()]);
        let meta = PlaceMeta {
            dataset,
            sweep: s.id,
            truth,
            profile: Some(StoredProfile::from_rop(&s.sweep.rop)),
            map_pose: map_pose.map(|p| [p.x, p.y, p.theta]),
            look_alike: walls
                .as_ref()
                .zip(map_pose)
                .and_then(|(walls, at)| look_alike(&s.sweep.rop, walls, &at, config))
                .map(|p| [p.x, p.y, p.theta]),
        };
        index
            .insert(&signature, s.sweep.rop.max_range_m, meta)
            .map_err(|e| SlamError::from(e).at(at(s.id)))?;
        filed += 1;
    }
    Ok((filed, left_out))
}

/// Answers one query sweep.
pub fn localise(
    index: &PlaceIndex,
    sweep: &DatasetSweep,
    config: &LocaliseConfig,
) -> Result<Answer, PlacesError> {
    let signature = match index.transforms().signature(&sweep.sweep.rop) {
        Ok(s) => s,
        Err(PlacesError::IncompleteSweep { .. }) => {
            return Ok(Answer {
                verdict: Verdict::Incomplete,
                best: None,
                margin: 0.0,
                rival: None,
                candidates: 0,
            })
        }
        Err(e) => return Err(e),
    };
    index.check_signature(&signature, sweep.sweep.rop.max_range_m)?;
    Ok(localise_signature(index, &signature, &sweep.sweep.rop, config))
}

/// Answers a query given its signature and 360° profile.
pub fn localise_signature(
    index: &PlaceIndex,
    signature: &Signature,
    rop: &Rop,
    config: &LocaliseConfig,
) -> Answer {
    let candidates = index.query(signature, &config.query);
    let query = View::of(rop, relative_chroma(rop), config);
    let mut refined: Vec<(PlaceMatch, View)> = Vec::new();
    for c in &candidates {
        if refined.len() == config.refined {
            break;
        }
        let Some(view) = stored_view(index, c.place, config) else {
            continue;
        };
        if let Some(m) = refine(&query, &view, c.place, c.rotation_rad, config) {
            refined.push((m, view));
        }
    }
    if refined.iter().all(|(m, _)| m.score < config.min_score) {
        // Each place tried all round replaces its tries at the shift
        // search's rotations, which the search round the circle covers.
        let again = all_round(index, &candidates, &query, config);
        refined.retain(|(m, _)| again.iter().all(|(a, _)| a.place != m.place));
        refined.extend(again);
    }
    refined.sort_by(|a, b| b.0.score.total_cmp(&a.0.score).then(a.0.place.cmp(&b.0.place)));
    let Some((best, best_view)) = refined.first() else {
        return Answer {
            verdict: Verdict::Unknown,
            best: None,
            margin: 0.0,
            rival: None,
            candidates: candidates.len(),
        };
    };
    // A rival is another answer: a match that puts the query elsewhere in
    // the map of the best's dataset (a look-alike, or the best place's own
    // symmetric image), or, where the map does not tell, a place whose
    // view the best's does not explain. Matches that agree are the same
    // spot filed twice (a revisit).
    let meta = |place: usize| index.contents().meta.get(place);
    let rival = refined[1..].iter().find(|(other, other_view)| {
        match same_map_answer(meta(best.place), best, meta(other.place), other, config) {
            Some(same) => !same,
            None => {
                let best_from_other = best.pose * other.pose.inverse();
                best_view.explains(other_view, &best_from_other, config) < config.min_score
            }
        }
    });
    // Where the best place's view fits elsewhere in its map about as
    // well, the query may stand there, seeing the same: that rival scores
    // as the best.
    let look_alike = meta(best.place).and_then(|m| m.look_alike).map(|l| PlaceMatch {
        pose: Pose2::new(l[0], l[1], l[2]) * best.pose,
        ..*best
    });
    let rival = look_alike.or(rival.map(|r| r.0));
    let margin = best.score - rival.map_or(0.0, |r| r.score);
    let verdict = if best.score < config.min_score {
        Verdict::Unknown
    } else if margin < config.min_margin {
        Verdict::Ambiguous
    } else {
        Verdict::Known
    };
    Answer {
        verdict,
        best: Some(*best),
        margin,
        rival,
        candidates: candidates.len(),
    }
}

/// Whether two matches put the query at one pose (within
/// [`LocaliseConfig::same_answer_m`] and [`LocaliseConfig::same_answer_rad`]):
/// of one place, always; of two places of one dataset with map poses, in
/// that map; `None` where the index cannot tell (places of two datasets,
/// or without map poses).
fn same_map_answer(
    a_meta: Option<&PlaceMeta>,
    a: &PlaceMatch,
    b_meta: Option<&PlaceMeta>,
    b: &PlaceMatch,
    config: &LocaliseConfig,
) -> Option<bool> {
    let as_pose = |p: [f64; 3]| Pose2::new(p[0], p[1], p[2]);
    let (pa, pb) = if a.place == b.place {
        (a.pose, b.pose)
    } else {
        let (ma, mb) = (a_meta?, b_meta?);
        if ma.dataset != mb.dataset {
            return None;
        }
        (as_pose(ma.map_pose?) * a.pose, as_pose(mb.map_pose?) * b.pose)
    };
    let apart = pa.between(&pb);
    Some(apart.translation().norm() <= config.same_answer_m && apart.theta.abs() <= config.same_answer_rad)
}

/// Two colours of the same surface differ by less than this in relative
/// log-chromaticity (`|Δ ln R/G| + |Δ ln B/G|`): a channel's ratio off by
/// 65 %, far beyond what the light and the camera's noise do to one
/// surface, and well short of what tells two paints apart.
const SAME_COLOUR: f64 = 0.5;

/// A view's obstacle points with their colours: all of them for
/// registration, and one per registration cell (the first) for scoring,
/// in a k-d tree.
struct View {
    points: Vec<Point2>,
    field: LikelihoodField,
    thinned: Vec<(Point2, Option<[f64; 2]>)>,
    tree: ImmutableKdTree<f64, 2>,
}

impl View {
    fn of(rop: &Rop, chroma: Vec<Option<[f64; 2]>>, config: &LocaliseConfig) -> Self {
        let coloured: Vec<(Point2, Option<[f64; 2]>)> = (0..rop.len())
            .filter_map(|i| {
                let r = rop.reliable(i)?;
                Some((
                    Point2::from_polar(f64::from(r), rop.bin_centre_rad(i)),
                    chroma.get(i).copied().flatten(),
                ))
            })
            .collect();
        let points: Vec<Point2> = coloured.iter().map(|c| c.0).collect();
        let cell = config.register.spacing_m.max(config.field_resolution_m);
        let mut seen = std::collections::HashSet::new();
        let thinned: Vec<(Point2, Option<[f64; 2]>)> = coloured
            .into_iter()
            .filter(|(p, _)| seen.insert(((p.x / cell).floor() as i64, (p.y / cell).floor() as i64)))
            .collect();
        let coords: Vec<[f64; 2]> = thinned.iter().map(|(p, _)| [p.x, p.y]).collect();
        let field = LikelihoodField::from_points(
            &points,
            config.field_resolution_m,
            config.register.sigma_m,
            config.register.epsilon,
        );
        Self {
            points,
            field,
            thinned,
            tree: ImmutableKdTree::new_from_slice(&coords),
        }
    }

    /// Share of `other`'s points (one per cell) that, placed in this
    /// view's frame by `this_from_other`, lie within two σ of one of this
    /// view's points of the same colour (or of any point, where either
    /// has no colour).
    fn explains(&self, other: &View, this_from_other: &Pose2, config: &LocaliseConfig) -> f64 {
        if other.thinned.is_empty() || self.thinned.is_empty() {
            return 0.0;
        }
        let reach2 = (2.0 * config.register.sigma_m).powi(2);
        let hits = other
            .thinned
            .iter()
            .filter(|(p, colour)| {
                let q = this_from_other.transform_point(*p);
                let near = self.tree.nearest_one::<SquaredEuclidean>(&[q.x, q.y]);
                if near.distance > reach2 {
                    return false;
                }
                match (colour, self.thinned[near.item as usize].1) {
                    (Some(a), Some(b)) => (a[0] - b[0]).abs() + (a[1] - b[1]).abs() < SAME_COLOUR,
                    _ => true,
                }
            })
            .count();
        hits as f64 / other.thinned.len() as f64
    }
}

/// The view of a stored place, where the index kept its profile.
fn stored_view(index: &PlaceIndex, place: usize, config: &LocaliseConfig) -> Option<View> {
    let profile = index.contents().meta.get(place)?.profile.as_ref()?;
    let stored = profile.to_rop()?;
    let chroma = (0..stored.len()).map(|i| profile.chroma_of(i)).collect();
    Some(View::of(&stored, chroma, config))
}

/// The first [`LocaliseConfig::fallback_places`] distinct candidate places,
/// each registered from headings 4σ apart all round the circle; the best
/// of each.
fn all_round(
    index: &PlaceIndex,
    candidates: &[Candidate],
    query: &View,
    config: &LocaliseConfig,
) -> Vec<(PlaceMatch, View)> {
    let mut places: Vec<usize> = Vec::new();
    for c in candidates {
        if places.len() == config.fallback_places {
            break;
        }
        if !places.contains(&c.place) {
            places.push(c.place);
        }
    }
    let step = (4.0 * config.sigma_heading_rad).max(1f64.to_radians());
    let headings = (std::f64::consts::TAU / step).ceil() as usize;
    places
        .into_iter()
        .filter_map(|place| {
            let view = stored_view(index, place, config)?;
            let best = (0..headings)
                .filter_map(|k| refine(query, &view, place, k as f64 * step, config))
                .max_by(|a, b| a.score.total_cmp(&b.score))?;
            Some((best, view))
        })
        .collect()
}

/// Registers the query's points against a stored place's field, started
/// at the shift search's rotation, and scores the result both ways.
fn refine(
    query: &View,
    stored: &View,
    place: usize,
    rotation_rad: f64,
    config: &LocaliseConfig,
) -> Option<PlaceMatch> {
    let prior = PosePrior {
        mean: Pose2::new(0.0, 0.0, rotation_rad),
        sigma_forward_m: config.sigma_position_m,
        sigma_left_m: config.sigma_position_m,
        sigma_theta_rad: config.sigma_heading_rad,
    };
    let reg = register(&stored.field, &query.points, &prior, &config.register).ok()?;
    let forward = stored.explains(query, &reg.pose, config);
    let backward = query.explains(stored, &reg.pose.inverse(), config);
    Some(PlaceMatch {
        place,
        pose: reg.pose,
        score: 0.5 * (forward + backward),
        rotation_rad,
    })
}

/// A dataset's map as look-alikes are searched in: its walls (cells at
/// least 60 % likely occupied), their fields (coarse for the
/// search, fine for its refinement) and a tree for scoring. Built once
/// for all of a dataset's places.
pub struct LookAlikeMap {
    fine: LikelihoodField,
    coarse: LikelihoodField,
    tree: ImmutableKdTree<f64, 2>,
    centre: Point2,
    half_m: f64,
}

impl LookAlikeMap {
    /// The walls of `map`, with `config`'s registration; `None` where the
    /// map has none.
    pub fn of(map: &OccupancyGrid, config: &LocaliseConfig) -> Option<Self> {
        let s = map.resolution_m();
        let ((lo_x, lo_y), (hi_x, hi_y)) = map.known_extent()?;
        let walls: Vec<Point2> = map
            .cells_above(WALL_PROBABILITY)
            .into_iter()
            .map(|(i, j)| Point2::new((i as f64 + 0.5) * s, (j as f64 + 0.5) * s))
            .collect();
        if walls.is_empty() {
            return None;
        }
        let field_of = |cell: f64, sigma: f64| {
            LikelihoodField::from_points(&walls, cell, sigma, config.register.epsilon)
        };
        let coords: Vec<[f64; 2]> = walls.iter().map(|p| [p.x, p.y]).collect();
        Some(Self {
            fine: field_of(config.field_resolution_m, config.register.sigma_m),
            coarse: field_of(LOOK_ALIKE_CELL_M, LOOK_ALIKE_CELL_M),
            tree: ImmutableKdTree::new_from_slice(&coords),
            centre: Point2::new(0.5 * (lo_x + hi_x) as f64 * s, 0.5 * (lo_y + hi_y) as f64 * s),
            half_m: 0.5 * ((hi_x - lo_x) as f64 * s).max((hi_y - lo_y) as f64 * s),
        })
    }
}

/// A place's look-alike: where else in its dataset's map its view fits
/// about as well as where it was taken. The view (the stored profile's
/// points) is registered on the whole map in each of eight sectors of
/// heading (on a 5 cm field, then refined with `config`'s registration
/// and field, as queries are on a place), and each sector's best is
/// scored as answers are: the share of the view's points (one per
/// registration cell) within 2σ of a wall of the map. The look-alike is
/// the best-scoring pose apart from the place's map pose `at` (two
/// answers: see [`LocaliseConfig::same_answer_m`]) that scores within
/// [`LocaliseConfig::min_margin`] of the view at `at`, or better;
/// returned in the place's own frame. `None` where the view fits its own
/// pose alone, or has no points.
pub fn look_alike(rop: &Rop, map: &LookAlikeMap, at: &Pose2, config: &LocaliseConfig) -> Option<Pose2> {
    let view = View::of(rop, vec![None; rop.len()], config);
    if view.thinned.is_empty() {
        return None;
    }
    // A sector where the view fits nowhere in particular spreads over
    // many poses: given up early (no look-alike there).
    let coarse_config = RegisterConfig {
        sigma_m: LOOK_ALIKE_CELL_M,
        spacing_m: LOOK_ALIKE_CELL_M,
        max_window_m: map.half_m + LOOK_ALIKE_CELL_M,
        max_spread_poses: LOOK_ALIKE_SPREAD_POSES,
        ..config.register.clone()
    };
    let reach2 = (2.0 * config.register.sigma_m).powi(2);
    // The share of the view's points on a wall, the view at `pose`.
    let share = |pose: &Pose2| {
        let on = (view.thinned.iter())
            .filter(|(p, _)| {
                let q = pose.transform_point(*p);
                map.tree.nearest_one::<SquaredEuclidean>(&[q.x, q.y]).distance <= reach2
            })
            .count();
        on as f64 / view.thinned.len() as f64
    };
    let apart = |pose: &Pose2| {
        let d = at.between(pose);
        d.translation().norm() > config.same_answer_m || d.theta.abs() > config.same_answer_rad
    };
    // Each sector's best pose, flat over the map, refined on the fine
    // field.
    let sector = std::f64::consts::TAU / LOOK_ALIKE_SECTORS as f64;
    let found: Vec<Pose2> = (0..LOOK_ALIKE_SECTORS)
        .filter_map(|k| {
            let prior = PosePrior {
                mean: Pose2::new(map.centre.x, map.centre.y, at.theta + k as f64 * sector),
                sigma_forward_m: 1e3,
                sigma_left_m: 1e3,
                sigma_theta_rad: 0.5 * sector / coarse_config.window_sigmas,
            };
            let reg = register(&map.coarse, &view.points, &prior, &coarse_config).ok()?;
            if !reg.accepted {
                return None;
            }
            let near = PosePrior {
                mean: reg.pose,
                sigma_forward_m: LOOK_ALIKE_CELL_M,
                sigma_left_m: LOOK_ALIKE_CELL_M,
                sigma_theta_rad: 1f64.to_radians(),
            };
            let refined = register(&map.fine, &view.points, &near, &config.register).ok()?;
            Some(if refined.accepted { refined.pose } else { reg.pose })
        })
        .collect();
    // The view where it was taken: at its map pose, or the search's best
    // near it (the map pose may sit a cell or a degree off the best fit).
    let own = found
        .iter()
        .filter(|p| !apart(p))
        .map(&share)
        .fold(share(at), f64::max);
    found
        .iter()
        .filter(|p| apart(p))
        .map(|p| (share(p), p))
        .filter(|(score, _)| *score >= own - config.min_margin)
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, p)| at.between(p))
}

/// The cell and σ of the coarse field a place's look-alike is first
/// searched on, metres.
const LOOK_ALIKE_CELL_M: f64 = 0.05;

/// The most lattice poses a sector's posterior may spread over: a fit
/// that pins a pose keeps a few hundred.
const LOOK_ALIKE_SPREAD_POSES: usize = 1 << 14;

/// Sectors of heading a place's look-alike is searched in, one search
/// each (a search's best is one pose: a look-alike turned half round
/// lies in another sector than the place).
const LOOK_ALIKE_SECTORS: usize = 8;

/// Map cells at least this likely occupied are the walls a look-alike is
/// searched among (the grid's free threshold's counterpart).
const WALL_PROBABILITY: f64 = 0.6;

#[cfg(test)]
mod tests {
    use super::*;
    use pirouette_places::SignatureConfig;
    use std::f64::consts::{PI, TAU};

    /// The sweep of a bare 4 × 3 m room of one colour from `(x, y)` (the
    /// room from its corner at the origin), heading 0, 1° bins.
    fn bare_room_from(x: f64, y: f64) -> Rop {
        let (w, h) = (4.0, 3.0);
        let mut rop = Rop::empty(-PI, TAU / 360.0, 360, 4.0);
        for i in 0..360 {
            let (s, c) = rop.bin_centre_rad(i).sin_cos();
            let t = [(w - x) / c, -x / c, (h - y) / s, -y / s]
                .into_iter()
                .filter(|t| *t > 0.0)
                .fold(f64::INFINITY, f64::min);
            rop.range_m[i] = t as f32;
        }
        rop
    }

    fn answer(stored: &Rop, query: &Rop) -> Answer {
        let mut index = PlaceIndex::new(SignatureConfig::default()).unwrap();
        let signature = index.transforms().signature(stored).unwrap();
        let meta = PlaceMeta {
            dataset: index.dataset_id("room"),
            sweep: 0,
            truth: None,
            profile: Some(StoredProfile::from_rop(stored)),
            map_pose: Some([0.0, 0.0, 0.0]),
            look_alike: None,
        };
        index.insert(&signature, stored.max_range_m, meta).unwrap();
        let query_signature = index.transforms().signature(query).unwrap();
        localise_signature(&index, &query_signature, query, &LocaliseConfig::default())
    }

    /// From the centre of a bare rectangular room, the view turned half
    /// round is the same view: the answer is ambiguous between the two
    /// headings, never a confident one of them.
    #[test]
    fn a_place_and_its_own_symmetric_image_are_two_answers() {
        let centre = bare_room_from(2.0, 1.5);
        let a = answer(&centre, &centre);
        assert_eq!(a.verdict, Verdict::Ambiguous, "{a:?}");
        let (best, rival) = (a.best.unwrap(), a.rival.unwrap());
        let apart = best.pose.between(&rival.pose);
        assert!((apart.theta.abs() - PI).abs() < 5f64.to_radians(), "{a:?}");
        assert!(a.margin < LocaliseConfig::default().min_margin);

        // Off the room's centre lines the view has no such image.
        let off = bare_room_from(1.2, 1.0);
        let b = answer(&off, &off);
        assert_eq!(b.verdict, Verdict::Known, "{b:?}");
        let pose = b.best.unwrap().pose;
        assert!(
            pose.translation().norm() < 0.02 && pose.theta.abs() < 1f64.to_radians(),
            "{b:?}"
        );
    }

    /// The view from `at` (1° bins, 4 m soft limit) of `walls`.
    fn view_of(walls: &pirouette_sim::Walls, at: &Pose2) -> Rop {
        view_in_bins(walls, at, 360)
    }

    /// The view from `at` of `walls` in `bins` bins round the circle.
    fn view_in_bins(walls: &pirouette_sim::Walls, at: &Pose2, bins: usize) -> Rop {
        let mut rop = Rop::empty(-PI, TAU / bins as f64, bins, 4.0);
        for i in 0..bins {
            let (s, c) = (rop.bin_centre_rad(i) + at.theta).sin_cos();
            if let Some(r) = walls.cast([at.x, at.y], [c, s]) {
                rop.range_m[i] = r as f32;
            }
        }
        rop
    }

    /// The map of `walls` seen from a lattice of spots 0.5 m apart, as
    /// look-alikes are searched in.
    fn map_of(walls: &pirouette_sim::Walls, w: f64, h: f64, config: &LocaliseConfig) -> LookAlikeMap {
        let grid_config = pirouette_grid::GridConfig {
            resolution_m: 0.02,
            ..Default::default()
        };
        let mut grid = OccupancyGrid::new(grid_config).unwrap();
        for i in 1..(2.0 * w) as usize {
            for j in 1..(2.0 * h) as usize {
                let at = Pose2::new(0.5 * i as f64, 0.5 * j as f64, 0.3 * (i + j) as f64);
                grid.insert_profile(&at, &view_of(walls, &at), 0.0);
            }
        }
        LookAlikeMap::of(&grid, config).expect("walls")
    }

    /// In a bare rectangular room a spot looks like its image half round
    /// about the centre: that is its look-alike, in its own frame. A room
    /// that one corner's recess makes an L tells the two apart.
    #[test]
    fn a_place_in_a_symmetric_room_has_its_image_as_look_alike() {
        let mut walls = pirouette_sim::Walls::default();
        walls.rectangle(0.0, 0.0, 4.0, 3.0);
        let at = Pose2::new(1.2, 1.0, 0.4);
        let image = Pose2::new(2.8, 2.0, 0.4 + PI);
        let config = LocaliseConfig::default();
        let found = look_alike(
            &view_of(&walls, &at),
            &map_of(&walls, 4.0, 3.0, &config),
            &at,
            &config,
        )
        .expect("a look-alike");
        let off = found.between(&at.between(&image));
        assert!(
            off.translation().norm() < 0.1 && off.theta.abs() < 2f64.to_radians(),
            "{found:?}"
        );

        let l_room = pirouette_sim::Walls::new(vec![
            [0.0, 0.0, 4.0, 0.0],
            [4.0, 0.0, 4.0, 1.6],
            [4.0, 1.6, 2.4, 1.6],
            [2.4, 1.6, 2.4, 3.0],
            [2.4, 3.0, 0.0, 3.0],
            [0.0, 3.0, 0.0, 0.0],
        ]);
        let found = look_alike(
            &view_of(&l_room, &at),
            &map_of(&l_room, 4.0, 3.0, &config),
            &at,
            &config,
        );
        assert_eq!(found, None);
    }

    /// Profiles are metric: a place filed from 1° bins is found by a
    /// query of 0.25° bins (another camera's, or another build's), and
    /// the other way round, at the query's pose.
    #[test]
    fn a_query_of_other_bin_widths_than_the_index_is_answered_at_its_pose() {
        let mut walls = pirouette_sim::Walls::default();
        walls.rectangle(0.0, 0.0, 4.0, 3.0);
        walls.rectangle(3.2, 2.2, 4.0, 3.0);
        walls.rectangle(0.0, 0.0, 0.5, 0.8);
        let place = Pose2::new(1.5, 1.2, 0.3);
        let query = Pose2::new(1.65, 1.1, 0.3 + 25f64.to_radians());
        let truth = place.between(&query);
        for (stored_bins, query_bins) in [(360, 1440), (1440, 360)] {
            let a = answer(
                &view_in_bins(&walls, &place, stored_bins),
                &view_in_bins(&walls, &query, query_bins),
            );
            assert_eq!(a.verdict, Verdict::Known, "{stored_bins} / {query_bins}: {a:?}");
            let off = truth.between(&a.best.unwrap().pose);
            assert!(
                off.translation().norm() < 0.02 && off.theta.abs() < 0.5f64.to_radians(),
                "{stored_bins} / {query_bins}: {off:?}"
            );
        }
    }
}
