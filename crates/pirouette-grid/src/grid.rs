//! The log-odds occupancy grid.

use crate::traverse;
use pirouette_geom::{Point2, Pose2};
use pirouette_profile::Rop;

/// Probability above which a cell counts as occupied (ROS `map_server`'s
/// customary `occupied_thresh`).
pub const OCCUPIED_THRESH: f64 = 0.65;
/// Probability below which a cell counts as free (`map_server`'s customary
/// `free_thresh`).
pub const FREE_THRESH: f64 = 0.196;

/// Errors of the grid.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GridError {
    /// A setting is out of range.
    #[error("grid settings: {problem}")]
    BadConfig {
        /// What is wrong.
        problem: String,
    },
}

/// Settings of the grid and of the vision sensor model.
#[derive(Debug, Clone, PartialEq)]
pub struct GridConfig {
    /// Side of a cell, metres.
    pub resolution_m: f64,
    /// Prior probability that a cell is occupied.
    pub prior: f64,
    /// Probability that a cell is occupied given one profile saw its
    /// obstacle there.
    pub hit_probability: f64,
    /// Probability that a cell is occupied given one profile saw through it.
    pub miss_probability: f64,
    /// Log-odds are kept within ± this (so the map can still change its mind).
    pub clamp_log_odds: f32,
    /// The most cells the grid may hold (nine bytes each): a profile that
    /// would grow it beyond is not inserted, and
    /// [`OccupancyGrid::overflowed`] says so.
    pub max_cells: usize,
}

impl Default for GridConfig {
    /// 1 cm cells (a profile resolves about that at its soft limit); prior
    /// 0.5; one sighting of an obstacle 0.7, one look through a cell 0.4
    /// (a camera's misses are cheaper than its hits: lint and shading make
    /// false obstacles, not false floor); log-odds clamped at ±4 (0.018 to
    /// 0.982); at most 50 million cells (450 MB; 70 × 70 m at 1 cm).
    fn default() -> Self {
        Self {
            resolution_m: 0.01,
            prior: 0.5,
            hit_probability: 0.7,
            miss_probability: 0.4,
            clamp_log_odds: 4.0,
            max_cells: 50_000_000,
        }
    }
}

fn logit(p: f64) -> f32 {
    (p / (1.0 - p)).ln() as f32
}

/// Bytes a cell of the grid holds (log-odds, a per-profile stamp and mark).
pub const BYTES_PER_CELL: usize = 9;

/// Storage cells the grid adds around what it must hold, each side.
const EDGE_CELLS: f64 = 16.0;

/// The most times [`GridConfig::fitted`] doubles a cell's side.
const MAX_DOUBLINGS: u32 = 12;

impl GridConfig {
    /// The cells a grid of these settings stores to hold every profile
    /// reaching `reach_m` from a sensor within the box `lo..=hi` (metres);
    /// infinite for a box that is not finite.
    pub fn cells_for(&self, lo: Point2, hi: Point2, reach_m: f64) -> f64 {
        if ![lo.x, lo.y, hi.x, hi.y, reach_m].iter().all(|v| v.is_finite()) {
            return f64::INFINITY;
        }
        let s = self.resolution_m;
        let side =
            |a: f64, b: f64| ((b - a).max(0.0) + 2.0 * (reach_m + 2.0 * s)) / s + 2.0 * EDGE_CELLS + 2.0;
        side(lo.x, hi.x) * side(lo.y, hi.y)
    }

    /// These settings where the grid of the box (see
    /// [`GridConfig::cells_for`]) fits [`GridConfig::max_cells`]; else
    /// with cells 2, 4, 8, … times as wide, the first that fits. `None`
    /// where not even cells 4096 times as wide fit (or the box is not
    /// finite).
    pub fn fitted(&self, lo: Point2, hi: Point2, reach_m: f64) -> Option<GridConfig> {
        let mut config = self.clone();
        for _ in 0..=MAX_DOUBLINGS {
            if config.cells_for(lo, hi, reach_m) <= self.max_cells as f64 {
                return Some(config);
            }
            config.resolution_m *= 2.0;
        }
        None
    }

    fn check(&self) -> Result<(), GridError> {
        let prob = |p: f64| p > 0.0 && p < 1.0;
        if !(self.resolution_m.is_finite() && self.resolution_m > 0.0) {
            return Err(GridError::BadConfig {
                problem: format!("resolution {} m", self.resolution_m),
            });
        }
        if !(prob(self.prior) && prob(self.hit_probability) && prob(self.miss_probability)) {
            return Err(GridError::BadConfig {
                problem: "probabilities must lie in (0, 1)".into(),
            });
        }
        if self.hit_probability <= self.prior || self.miss_probability >= self.prior {
            return Err(GridError::BadConfig {
                problem: "a hit must raise and a miss lower the prior".into(),
            });
        }
        if self.clamp_log_odds.is_nan() || self.clamp_log_odds <= 0.0 {
            return Err(GridError::BadConfig {
                problem: "clamp must be positive".into(),
            });
        }
        Ok(())
    }
}

/// What a profile said of a cell (occupied wins over free within one profile).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Seen {
    Free,
    Occupied,
}

/// A growing occupancy grid of log-odds (relative to the prior).
///
/// Cell `(i, j)` covers `[i·s, (i+1)·s) × [j·s, (j+1)·s)` of the map frame.
///
/// # Memory
/// Nine bytes per cell (log-odds, a per-profile stamp and mark): 9 MB for a
/// 10 × 10 m map at 1 cm; never more than [`GridConfig::max_cells`] cells.
#[derive(Debug, Clone)]
pub struct OccupancyGrid {
    config: GridConfig,
    /// Cell index of storage element 0.
    min_cell: (i64, i64),
    width: usize,
    height: usize,
    log_odds: Vec<f32>,
    /// Which profile last touched each cell, and what it said.
    stamp: Vec<u32>,
    mark: Vec<Seen>,
    profiles: u32,
    /// Scratch: the cells the profile being inserted touches.
    touched: Vec<usize>,
    l_hit: f32,
    l_miss: f32,
    /// Whether a profile was left out because the grid would have grown
    /// beyond its budget.
    overflow: bool,
}

impl OccupancyGrid {
    /// An empty grid.
    pub fn new(config: GridConfig) -> Result<Self, GridError> {
        config.check()?;
        let l0 = logit(config.prior);
        Ok(Self {
            l_hit: logit(config.hit_probability) - l0,
            l_miss: logit(config.miss_probability) - l0,
            config,
            min_cell: (0, 0),
            width: 0,
            height: 0,
            log_odds: Vec::new(),
            stamp: Vec::new(),
            mark: Vec::new(),
            profiles: 0,
            touched: Vec::new(),
            overflow: false,
        })
    }

    /// The settings.
    pub fn config(&self) -> &GridConfig {
        &self.config
    }

    /// Cell side, metres.
    pub fn resolution_m(&self) -> f64 {
        self.config.resolution_m
    }

    /// The cell holding a point.
    pub fn cell_of(&self, p: Point2) -> (i64, i64) {
        let s = self.config.resolution_m;
        ((p.x / s).floor() as i64, (p.y / s).floor() as i64)
    }

    /// The cells stored: `(min_i, min_j, width, height)`.
    pub fn extent(&self) -> (i64, i64, usize, usize) {
        (self.min_cell.0, self.min_cell.1, self.width, self.height)
    }

    fn index(&self, i: i64, j: i64) -> Option<usize> {
        let (x, y) = (i - self.min_cell.0, j - self.min_cell.1);
        (x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height)
            .then(|| y as usize * self.width + x as usize)
    }

    /// Log-odds of cell `(i, j)` relative to the prior (0: unknown).
    pub fn log_odds(&self, i: i64, j: i64) -> f32 {
        self.index(i, j).map_or(0.0, |k| self.log_odds[k])
    }

    /// Probability that cell `(i, j)` is occupied.
    pub fn probability(&self, i: i64, j: i64) -> f64 {
        self.probability_of(self.log_odds(i, j))
    }

    /// The probability of a cell holding log-odds `l`.
    fn probability_of(&self, l: f32) -> f64 {
        let l = l as f64 + logit(self.config.prior) as f64;
        1.0 / (1.0 + (-l).exp())
    }

    /// The least log-odds (as [`OccupancyGrid::log_odds`] holds them) whose
    /// probability is at least `p`, `+∞` where none is: a cell is below `p`
    /// exactly when its log-odds are below this, so a scan of many cells
    /// compares numbers instead of taking each one's exponential.
    pub fn log_odds_reaching(&self, p: f64) -> f32 {
        // Bisection over the finite f32 values in their order (the bit
        // patterns of the non-negative ones count up, of the negative ones
        // down): the probability never falls as the log-odds rise.
        let key = |v: f32| {
            let b = v.to_bits() as i32 as i64;
            if b < 0 {
                i32::MIN as i64 - b
            } else {
                b
            }
        };
        let value = |k: i64| {
            f32::from_bits(if k < 0 {
                (i32::MIN as i64 - k) as u32
            } else {
                k as u32
            })
        };
        let (mut lo, mut hi) = (key(f32::MIN), key(f32::MAX));
        if self.probability_of(f32::MAX) < p {
            return f32::INFINITY;
        }
        if self.probability_of(f32::MIN) >= p {
            return f32::MIN;
        }
        // probability(value(lo)) < p <= probability(value(hi)).
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if self.probability_of(value(mid)) >= p {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        value(hi)
    }

    /// Probability that the cell holding `(x, y)` is occupied.
    pub fn probability_at(&self, x: f64, y: f64) -> f64 {
        let (i, j) = self.cell_of(Point2::new(x, y));
        self.probability(i, j)
    }

    /// The smallest box of cells holding every cell some profile touched:
    /// `(min, max)` cell indices, inclusive; `None` for an untouched grid.
    pub fn known_extent(&self) -> Option<((i64, i64), (i64, i64))> {
        let mut out: Option<((i64, i64), (i64, i64))> = None;
        for (k, _) in self.log_odds.iter().enumerate().filter(|(_, &v)| v != 0.0) {
            let (i, j) = (
                self.min_cell.0 + (k % self.width) as i64,
                self.min_cell.1 + (k / self.width) as i64,
            );
            out = Some(match out {
                None => ((i, j), (i, j)),
                Some((lo, hi)) => ((lo.0.min(i), lo.1.min(j)), (hi.0.max(i), hi.1.max(j))),
            });
        }
        out
    }

    /// The cells whose probability exceeds `threshold`, sorted by `(j, i)`.
    pub fn cells_above(&self, threshold: f64) -> Vec<(i64, i64)> {
        let l = logit(threshold) - logit(self.config.prior);
        let mut out = Vec::new();
        for (k, &v) in self.log_odds.iter().enumerate() {
            if v > l {
                out.push((
                    self.min_cell.0 + (k % self.width) as i64,
                    self.min_cell.1 + (k / self.width) as i64,
                ));
            }
        }
        out
    }

    /// Stores the cells a profile reaching `reach_m` from any sensor
    /// position within `lo..=hi` touches, at once (so that inserting such
    /// profiles never grows the grid, and never holds two copies of it);
    /// false, storing nothing more, where they would pass the budget.
    pub fn reserve(&mut self, lo: Point2, hi: Point2, reach_m: f64) -> bool {
        let r = reach_m + 2.0 * self.config.resolution_m;
        let (lo, hi) = (Point2::new(lo.x - r, lo.y - r), Point2::new(hi.x + r, hi.y + r));
        let far = |p: Point2| {
            !(p.x.is_finite() && p.y.is_finite())
                || p.x.abs().max(p.y.abs()) / self.config.resolution_m >= 1e15
        };
        !far(lo) && !far(hi) && self.ensure(self.cell_of(lo), self.cell_of(hi))
    }

    /// Whether some profile was left out because the grid would have grown
    /// beyond [`GridConfig::max_cells`]: the grid is then incomplete.
    pub fn overflowed(&self) -> bool {
        self.overflow
    }

    /// Grows the storage (with a margin) so that cells `lo..=hi` exist;
    /// false, growing nothing, where that would pass the cell budget.
    fn ensure(&mut self, lo: (i64, i64), hi: (i64, i64)) -> bool {
        let cur_hi = (
            self.min_cell.0 + self.width as i64 - 1,
            self.min_cell.1 + self.height as i64 - 1,
        );
        if self.width > 0
            && lo.0 >= self.min_cell.0
            && lo.1 >= self.min_cell.1
            && hi.0 <= cur_hi.0
            && hi.1 <= cur_hi.1
        {
            return true;
        }
        // Grow by at least half the current size each way, so that a robot
        // exploring steadily re-allocates only logarithmically often.
        let margin_x = (self.width as i64 / 2).max(16);
        let margin_y = (self.height as i64 / 2).max(16);
        let (new_lo, new_hi) = if self.width == 0 {
            ((lo.0 - 16, lo.1 - 16), (hi.0 + 16, hi.1 + 16))
        } else {
            (
                (
                    lo.0.min(self.min_cell.0 - if lo.0 < self.min_cell.0 { margin_x } else { 0 }),
                    lo.1.min(self.min_cell.1 - if lo.1 < self.min_cell.1 { margin_y } else { 0 }),
                ),
                (
                    hi.0.max(cur_hi.0 + if hi.0 > cur_hi.0 { margin_x } else { 0 }),
                    hi.1.max(cur_hi.1 + if hi.1 > cur_hi.1 { margin_y } else { 0 }),
                ),
            )
        };
        // Counted in i128: cell indices of absurd poses overflow i64 sums.
        let (w, h) = (
            new_hi.0 as i128 - new_lo.0 as i128 + 1,
            new_hi.1 as i128 - new_lo.1 as i128 + 1,
        );
        // The margin is a convenience: without it, what is stored and
        // asked for must fit the budget.
        let budget = self.config.max_cells as i128;
        let (new_lo, w, h) = if w * h <= budget {
            (new_lo, w, h)
        } else {
            let (lo, hi) = if self.width == 0 {
                (lo, hi)
            } else {
                (
                    (lo.0.min(self.min_cell.0), lo.1.min(self.min_cell.1)),
                    (hi.0.max(cur_hi.0), hi.1.max(cur_hi.1)),
                )
            };
            let (w, h) = (hi.0 as i128 - lo.0 as i128 + 1, hi.1 as i128 - lo.1 as i128 + 1);
            if w * h > budget {
                return false;
            }
            (lo, w, h)
        };
        let (w, h) = (w as usize, h as usize);
        let mut log_odds = vec![0f32; w * h];
        for y in 0..self.height {
            let src = y * self.width;
            let dst =
                (y as i64 + self.min_cell.1 - new_lo.1) as usize * w + (self.min_cell.0 - new_lo.0) as usize;
            log_odds[dst..dst + self.width].copy_from_slice(&self.log_odds[src..src + self.width]);
        }
        self.log_odds = log_odds;
        self.stamp = vec![0; w * h];
        self.mark = vec![Seen::Free; w * h];
        self.min_cell = new_lo;
        self.width = w;
        self.height = h;
        true
    }

    /// Inserts one profile seen from `world_from_robot` (the robot centre)
    /// with blind distance `blind_m` (the floor nearer than the bottom
    /// scanline is not seen). Every cell counts at most once per profile;
    /// a cell that some bearing saw occupied is occupied. Returns the cells
    /// updated.
    pub fn insert_profile(&mut self, world_from_robot: &Pose2, rop: &Rop, blind_m: f64) -> usize {
        let max_range = rop.max_range_m as f64;
        let s = self.config.resolution_m;
        let c = world_from_robot.translation();
        let reach = max_range + 2.0 * s;
        // Far beyond any map (and beyond what cell indices hold), or
        // beyond the budget: left out, and said.
        let far = (c.x.abs().max(c.y.abs()) + reach) / s;
        if !(c.x.is_finite() && c.y.is_finite())
            || far >= 1e15
            || !self.ensure(
                self.cell_of(Point2::new(c.x - reach, c.y - reach)),
                self.cell_of(Point2::new(c.x + reach, c.y + reach)),
            )
        {
            self.overflow = true;
            return 0;
        }
        self.profiles = self.profiles.wrapping_add(1).max(1);
        let id = self.profiles;
        // The cells this profile touches, in a buffer kept between calls.
        let mut touched = std::mem::take(&mut self.touched);
        touched.clear();
        for i in 0..rop.len() {
            if !rop.seen(i) {
                continue;
            }
            let r = rop.range_m[i] as f64;
            let known = rop.free_reach(i) as f64;
            let (end, hit) = if r.is_finite() && r <= max_range {
                (r, true)
            } else {
                // Free up to the soft limit, or as far as the bin was seen.
                (max_range.min(known), false)
            };
            if end <= blind_m {
                continue;
            }
            let dir = world_from_robot.rotate_vector(Point2::from_polar(1.0, rop.bin_centre_rad(i)));
            let from = [c.x + blind_m * dir.x, c.y + blind_m * dir.y];
            let to = [c.x + end * dir.x, c.y + end * dir.y];
            let end_cell = self.cell_of(Point2::new(to[0], to[1]));
            let (min_cell, width) = (self.min_cell, self.width);
            let index =
                |(ci, cj): (i64, i64)| (cj - min_cell.1) as usize * width + (ci - min_cell.0) as usize;
            let (stamp, mark) = (&mut self.stamp, &mut self.mark);
            // Every cell along the ray is free; the obstacle's cell, the
            // last, is then raised to occupied (occupied wins).
            let mut visit = |k: usize, seen: Seen| {
                if stamp[k] != id {
                    stamp[k] = id;
                    mark[k] = seen;
                    touched.push(k);
                } else if seen > mark[k] {
                    mark[k] = seen;
                }
            };
            // An obstacle seen beyond floor known only so far (a mark or a
            // low obstacle left undecided before it): free up to there.
            let free_to = if hit && known < end {
                [c.x + known * dir.x, c.y + known * dir.y]
            } else {
                to
            };
            if !hit || known > blind_m {
                traverse(from, free_to, s, |ci, cj| visit(index((ci, cj)), Seen::Free));
            }
            if hit {
                visit(index(end_cell), Seen::Occupied);
            }
        }
        let clamp = self.config.clamp_log_odds;
        for &k in &touched {
            let delta = if self.mark[k] == Seen::Occupied {
                self.l_hit
            } else {
                self.l_miss
            };
            self.log_odds[k] = (self.log_odds[k] + delta).clamp(-clamp, clamp);
        }
        let n = touched.len();
        self.touched = touched;
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A profile that would grow the grid past its budget is left out, and
    /// the grid says so; one at an absurd or non-finite pose likewise.
    #[test]
    fn profiles_beyond_the_cell_budget_are_left_out_and_reported() {
        use pirouette_profile::Rop;
        let mut rop = Rop::covering(-0.5, 0.5, 1f64.to_radians(), 1.0).unwrap();
        rop.range_m.iter_mut().for_each(|r| *r = 0.5);
        let config = GridConfig {
            max_cells: 100_000,
            ..GridConfig::default()
        };
        let mut g = OccupancyGrid::new(config).unwrap();
        assert!(g.insert_profile(&Pose2::IDENTITY, &rop, 0.1) > 0);
        assert!(!g.overflowed());
        // 10 m away: 1000 × 1000 cells would be needed.
        assert_eq!(g.insert_profile(&Pose2::new(10.0, 0.0, 0.0), &rop, 0.1), 0);
        assert!(g.overflowed());
        assert!(g.width * g.height <= 100_000);
        for far in [Pose2::new(1e300, 0.0, 0.0), Pose2::new(f64::NAN, 0.0, 0.0)] {
            let mut g = OccupancyGrid::new(GridConfig::default()).unwrap();
            assert_eq!(g.insert_profile(&far, &rop, 0.1), 0);
            assert!(g.overflowed() && g.log_odds.is_empty());
        }
        // A map around the origin, then a profile 10⁷ km away.
        let mut g = OccupancyGrid::new(GridConfig::default()).unwrap();
        g.insert_profile(&Pose2::IDENTITY, &rop, 0.1);
        let cells = g.log_odds.len();
        assert_eq!(g.insert_profile(&Pose2::new(-1e10, 1e10, 0.0), &rop, 0.1), 0);
        assert!(g.overflowed() && g.log_odds.len() == cells);
    }

    /// A grid reserved for a box holds every profile from within it
    /// without growing, and no more cells than the box's count says; the
    /// fitted settings double the cell side until that count fits.
    #[test]
    fn a_reserved_grid_holds_its_box_and_fitted_cells_fit_the_budget() {
        use pirouette_profile::Rop;
        let mut rop = Rop::covering(-3.0, 3.0, 1f64.to_radians(), 2.0).unwrap();
        rop.range_m.iter_mut().for_each(|r| *r = 1.5);
        let (lo, hi) = (Point2::new(-1.0, 2.0), Point2::new(3.0, 4.5));
        let config = GridConfig {
            resolution_m: 0.05,
            max_cells: 60_000,
            ..GridConfig::default()
        };
        // (4 + 2·2.1)/0.05 + 34 = 198 by (2.5 + 4.2)/0.05 + 34 = 168.
        let need = config.cells_for(lo, hi, 2.0);
        assert!((need - 198.0 * 168.0).abs() < 1e-6, "{need}");
        assert_eq!(config.fitted(lo, hi, 2.0), Some(config.clone()));
        let mut g = OccupancyGrid::new(config.clone()).unwrap();
        assert!(g.reserve(lo, hi, 2.0));
        assert!(((g.width * g.height) as f64) <= need);
        let stored = g.extent();
        for pose in [
            Pose2::new(-1.0, 2.0, 0.3),
            Pose2::new(3.0, 4.5, -2.0),
            Pose2::new(1.0, 3.0, 1.0),
        ] {
            assert!(g.insert_profile(&pose, &rop, 0.0) > 0);
        }
        assert_eq!(g.extent(), stored);
        assert!(!g.overflowed());
        // A quarter of the budget: cells twice as wide hold the box.
        let small = GridConfig {
            max_cells: 15_000,
            ..config.clone()
        };
        let fitted = small.fitted(lo, hi, 2.0).unwrap();
        assert_eq!(fitted.resolution_m, 0.1);
        assert!(fitted.cells_for(lo, hi, 2.0) <= 15_000.0);
        let mut g = OccupancyGrid::new(small).unwrap();
        assert!(!g.reserve(lo, hi, 2.0) && g.log_odds.is_empty());
        let far = Point2::new(1e12, 0.0);
        assert_eq!(config.fitted(lo, far, 2.0), None);
        assert_eq!(config.fitted(lo, Point2::new(f64::NAN, 0.0), 2.0), None);
        assert!(!OccupancyGrid::new(config).unwrap().reserve(lo, far, 2.0));
    }

    #[test]
    fn log_odds_reaching_a_probability_split_cells_as_the_probability_does() {
        let mut g = OccupancyGrid::new(GridConfig::default()).unwrap();
        for p in [0.196, 0.5, 0.65, 0.999, 1e-9] {
            let l = g.log_odds_reaching(p);
            assert!(g.probability_of(l) >= p, "{p}");
            let below = f32::from_bits(if l > 0.0 { l.to_bits() - 1 } else { l.to_bits() + 1 });
            assert!(g.probability_of(below) < p, "{p}");
        }
        // Every log-odds a grid can hold, near the threshold and far.
        let l = g.log_odds_reaching(FREE_THRESH);
        let mut checked = 0;
        for k in -2000..2000 {
            let v = l + k as f32 * 1e-3;
            assert_eq!(v < l, g.probability_of(v) < FREE_THRESH, "{v}");
            checked += 1;
        }
        assert_eq!(checked, 4000);
        assert_eq!(g.log_odds_reaching(2.0), f32::INFINITY);
        g.config.prior = 0.5;
        assert!(g.log_odds_reaching(0.5).abs() < 1e-6);
    }

    fn wall_profile(range: f32) -> Rop {
        let mut rop = Rop::covering(-0.5, 0.5, 0.25f64.to_radians(), 0.9).unwrap();
        rop.range_m.iter_mut().for_each(|r| *r = range);
        rop
    }

    #[test]
    fn obstacle_cells_occupied_floor_free_rest_unknown() {
        let mut g = OccupancyGrid::new(GridConfig::default()).unwrap();
        g.insert_profile(&Pose2::IDENTITY, &wall_profile(0.5), 0.1);
        assert!(g.probability_at(0.505, 0.0) > 0.6, "the obstacle's cell");
        assert!(g.probability_at(0.3, 0.0) < 0.45, "floor in front");
        assert_eq!(g.probability_at(0.7, 0.0), 0.5, "behind the obstacle: unknown");
        assert_eq!(
            g.probability_at(0.05, 0.0),
            0.5,
            "inside the blind distance: unknown"
        );
        assert_eq!(
            g.probability_at(0.3, 0.3),
            0.5,
            "outside the view (±28.6°): untouched"
        );
    }

    #[test]
    fn soft_limit_frees_up_to_max_range_and_marks_no_obstacle() {
        for far in [1.3f32, f32::INFINITY] {
            let mut g = OccupancyGrid::new(GridConfig::default()).unwrap();
            g.insert_profile(&Pose2::IDENTITY, &wall_profile(far), 0.1);
            assert!(g.probability_at(0.85, 0.0) < 0.45);
            let (min_i, min_j, w, h) = g.extent();
            let occupied = (0..w as i64)
                .flat_map(|x| (0..h as i64).map(move |y| (min_i + x, min_j + y)))
                .filter(|&(i, j)| g.probability(i, j) > 0.5)
                .count();
            assert_eq!(occupied, 0);
            assert_eq!(g.probability_at(0.95, 0.0), 0.5);
        }
    }

    #[test]
    fn nothing_in_sight_frees_only_as_far_as_the_bin_was_seen() {
        let mut g = OccupancyGrid::new(GridConfig::default()).unwrap();
        let mut rop = wall_profile(f32::INFINITY);
        rop.free_m.iter_mut().for_each(|f| *f = 0.3);
        g.insert_profile(&Pose2::IDENTITY, &rop, 0.1);
        assert!(g.probability_at(0.25, 0.0) < 0.45, "seen floor is free");
        assert_eq!(g.probability_at(0.35, 0.0), 0.5, "beyond what was seen: unknown");
        assert_eq!(
            g.probability_at(0.8, 0.0),
            0.5,
            "short of the soft limit: still unknown"
        );
    }

    /// An obstacle beyond floor known only so far (an undecided base in
    /// front of it): the floor up to there is free, the obstacle's cell
    /// occupied, and the cells between left as they were.
    #[test]
    fn an_obstacle_beyond_floor_known_only_so_far_leaves_the_gap_unknown() {
        let mut g = OccupancyGrid::new(GridConfig::default()).unwrap();
        let mut rop = wall_profile(0.5);
        rop.free_m.iter_mut().for_each(|f| *f = 0.3);
        g.insert_profile(&Pose2::IDENTITY, &rop, 0.1);
        assert!(g.probability_at(0.25, 0.0) < 0.45, "known floor is free");
        assert_eq!(g.probability_at(0.4, 0.0), 0.5, "between: unknown");
        assert!(g.probability_at(0.505, 0.0) > 0.6, "the obstacle's cell");
        // Known floor within the blind distance: only the obstacle.
        let mut g = OccupancyGrid::new(GridConfig::default()).unwrap();
        rop.free_m.iter_mut().for_each(|f| *f = 0.05);
        g.insert_profile(&Pose2::IDENTITY, &rop, 0.1);
        assert_eq!(g.probability_at(0.25, 0.0), 0.5);
        assert!(g.probability_at(0.505, 0.0) > 0.6);
    }

    #[test]
    fn each_cell_counts_once_per_profile_and_evidence_accumulates() {
        let config = GridConfig::default();
        let mut g = OccupancyGrid::new(config.clone()).unwrap();
        g.insert_profile(&Pose2::IDENTITY, &wall_profile(0.5), 0.1);
        // Many 0.25° rays cross the cells near the robot: still one miss each.
        let one_miss = logit(config.miss_probability) - logit(config.prior);
        assert!((g.log_odds(15, 0) - one_miss).abs() < 1e-6);
        g.insert_profile(&Pose2::IDENTITY, &wall_profile(0.5), 0.1);
        assert!((g.log_odds(15, 0) - 2.0 * one_miss).abs() < 1e-6);
        for _ in 0..20 {
            g.insert_profile(&Pose2::IDENTITY, &wall_profile(0.5), 0.1);
        }
        assert_eq!(g.log_odds(15, 0), -config.clamp_log_odds);
    }

    #[test]
    fn grows_as_the_robot_explores_and_keeps_what_it_saw() {
        let mut g = OccupancyGrid::new(GridConfig::default()).unwrap();
        g.insert_profile(&Pose2::IDENTITY, &wall_profile(0.5), 0.1);
        let before = g.log_odds(50, 0);
        g.insert_profile(&Pose2::new(-5.0, 3.0, 2.0), &wall_profile(0.5), 0.1);
        g.insert_profile(&Pose2::new(6.0, -4.0, -1.0), &wall_profile(0.5), 0.1);
        assert_eq!(g.log_odds(50, 0), before);
        let p = Pose2::new(6.0, -4.0, -1.0).transform_point(Point2::new(0.505, 0.0));
        assert!(g.probability_at(p.x, p.y) > 0.6);
    }

    #[test]
    fn bad_settings_are_errors() {
        assert!(OccupancyGrid::new(GridConfig {
            resolution_m: 0.0,
            ..GridConfig::default()
        })
        .is_err());
        assert!(OccupancyGrid::new(GridConfig {
            hit_probability: 0.4,
            ..GridConfig::default()
        })
        .is_err());
    }
}
