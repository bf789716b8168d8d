//! The likelihood field of a map: how well a point explains an obstacle.

use crate::floor_i64;
use pirouette_geom::Point2;
use pirouette_grid::OccupancyGrid;
use std::sync::OnceLock;

/// Per-cell log-likelihood of a profile endpoint falling there: a Gaussian
/// in the distance to the nearest mapped obstacle point, mixed with a
/// floor for endpoints the map cannot explain: `ε` where the map knows
/// nothing (obstacles not yet mapped), a smaller `ε_free` where the map has
/// seen free floor (only a false range lands there).
///
/// `value = ln(ε_c + (1 − ε)·exp(−d² / 2σ²))`, `ε_c` being `ε` or
/// `ε_free`, so an endpoint on a mapped obstacle scores about `0`, one on
/// unknown ground `ln ε`, one on known floor `ln ε_free`: a pose that slides
/// a wall along a wall but throws other endpoints onto seen floor loses.
///
/// Two forms of one function: a lattice of cell-centre values for the
/// search ([`LikelihoodField::cell`]; the Gaussian within `3σ` and a cell
/// of each point, the floor beyond), with max-pooled levels over blocks of
/// `2ʰ` cells for branch and bound; and the exact value from the
/// nearest obstacle point within [`CUTOFF_SIGMAS`]` σ` (the floor beyond,
/// where the Gaussian adds less than `10⁻⁷` of it) for refinement below one
/// cell ([`LikelihoodField::exact`]), where interpolating the lattice
/// would flatten the peak of a wall lying between two cell centres.
///
/// A field grows: [`LikelihoodField::insert`] adds obstacle points, each
/// touching only the cells within its reach (a submap takes a scan at a
/// time).
///
/// # Memory
/// About 5 bytes per cell of the points' extent (plus a border of `3σ`):
/// value and seen floor; four more once a branch and bound asks for the
/// pooled levels, four more (the squared distances) in a field that
/// grows; and 16 bytes per point.
#[derive(Debug, Clone)]
pub struct LikelihoodField {
    /// The obstacle points, bucketed for nearest-point queries.
    points: Buckets,
    epsilon: f64,
    epsilon_free: f64,
    two_sigma2: f64,
    resolution_m: f64,
    /// Cells about a point the lattice's Gaussian reaches.
    reach: i64,
    /// Cell index of storage element 0.
    min_cell: (i64, i64),
    width: usize,
    height: usize,
    values: Vec<f32>,
    /// Squared distance from each cell centre to the nearest point within
    /// `reach` cells (infinite beyond); kept once the field has grown
    /// (empty in a field made at once, which needs it no more).
    d2: Vec<f32>,
    /// Cells the map has seen free (empty: none).
    free: Vec<bool>,
    /// The max-pooled levels `1..=POOLED_LEVELS` (index 0 unused; see
    /// [`LikelihoodField::pooled`]): per cell from `−PAD`, the largest
    /// value over the block of `2ʰ` cells a side starting there, quantised
    /// upward to a byte. Made when a branch and bound first asks for them
    /// (a registration that scores every pose never does), then kept as
    /// the field grows.
    levels: OnceLock<Vec<Vec<u8>>>,
    /// The quantisation's lowest value and step (see [`LikelihoodField::quantum`]).
    lowest: f64,
    step: f64,
    floor: f32,
    /// The floor quantised.
    floor_q: u8,
}

/// The exact value counts the nearest obstacle point within this many σ:
/// beyond, the Gaussian's `exp(−18)` adds under `10⁻⁷` of the floor's
/// likelihood, and its slope is as small.
pub const CUTOFF_SIGMAS: f64 = 6.0;

/// Levels of max-pooled blocks kept above the lattice: up to blocks of
/// `2⁴ = 16` cells a side.
pub(crate) const POOLED_LEVELS: usize = 4;

/// Pooled levels also hold the blocks starting this many cells before the
/// lattice (those that reach into it).
const PAD: i64 = (1 << POOLED_LEVELS) - 1;

/// Cells added beyond what a growing field needs, each side, at least
/// (more for larger fields), so that growth reallocates seldom.
const GROWTH_MARGIN_CELLS: i64 = 64;

impl LikelihoodField {
    /// The field of the cells of `grid` that are occupied with probability
    /// above `occupied_threshold` (each taken at its centre), with Gaussian
    /// width `sigma_m` and floor `epsilon` (in `(0, 1)`); no free space.
    pub fn from_grid(grid: &OccupancyGrid, occupied_threshold: f64, sigma_m: f64, epsilon: f64) -> Self {
        let s = grid.resolution_m();
        let centres: Vec<Point2> = grid
            .cells_above(occupied_threshold)
            .into_iter()
            .map(|(i, j)| Point2::new((i as f64 + 0.5) * s, (j as f64 + 0.5) * s))
            .collect();
        Self::from_points(&centres, s, sigma_m, epsilon)
    }

    /// The field of a set of obstacle points on a lattice of `resolution_m`
    /// cells, with no knowledge of free space. Distances are measured from
    /// each cell centre to the points themselves, so the field keeps the
    /// points' sub-cell positions (a wall on a cell border does not move by
    /// half a cell).
    pub fn from_points(points: &[Point2], resolution_m: f64, sigma_m: f64, epsilon: f64) -> Self {
        Self::build(points, None, None, resolution_m, sigma_m, epsilon, epsilon)
    }

    /// The field of obstacle points on the lattice of `grid`, whose cells
    /// below `free_threshold` are known floor (floor `epsilon_free`).
    pub fn from_map(
        points: &[Point2],
        grid: &OccupancyGrid,
        free_threshold: f64,
        sigma_m: f64,
        epsilon: f64,
        epsilon_free: f64,
    ) -> Self {
        Self::build(
            points,
            Some((grid, free_threshold)),
            None,
            grid.resolution_m(),
            sigma_m,
            epsilon,
            epsilon_free,
        )
    }

    /// As [`LikelihoodField::from_map`], only within the box from `lo` to
    /// `hi` (map frame, metres): outside it every value is the floor. A
    /// registration that only looks near one spot pays for that spot.
    #[allow(clippy::too_many_arguments)]
    pub fn from_map_within(
        points: &[Point2],
        grid: &OccupancyGrid,
        lo: Point2,
        hi: Point2,
        free_threshold: f64,
        sigma_m: f64,
        epsilon: f64,
        epsilon_free: f64,
    ) -> Self {
        let s = grid.resolution_m();
        let cell = |p: Point2| (floor_i64(p.x / s), floor_i64(p.y / s));
        Self::build(
            points,
            Some((grid, free_threshold)),
            Some((cell(lo), cell(hi))),
            s,
            sigma_m,
            epsilon,
            epsilon_free,
        )
    }

    fn build(
        points: &[Point2],
        free_space: Option<(&OccupancyGrid, f64)>,
        region: Option<((i64, i64), (i64, i64))>,
        resolution_m: f64,
        sigma_m: f64,
        epsilon: f64,
        epsilon_free: f64,
    ) -> Self {
        let mut field = Self::empty(resolution_m, sigma_m, epsilon, epsilon_free);
        let reach = field.reach;
        // Points that can reach the region.
        let near_region = |p: &Point2| {
            region.is_none_or(|(lo, hi)| {
                let (i, j) = field.cell_of(p);
                i >= lo.0 - reach && i <= hi.0 + reach && j >= lo.1 - reach && j <= hi.1 + reach
            })
        };
        let points: Vec<Point2> = points
            .iter()
            .copied()
            .filter(|p| p.x.is_finite() && p.y.is_finite() && near_region(p))
            .collect();
        let Some(extent) = lattice_extent(&points, free_space, region, reach, &|p| field.cell_of(p)) else {
            field.points.add(&points);
            return field;
        };
        field.resize(extent);
        if let Some((grid, threshold)) = free_space {
            let reaching = grid.log_odds_reaching(threshold);
            let (min_cell, width) = (field.min_cell, field.width);
            field.free = vec![false; field.width * field.height];
            for (k, f) in field.free.iter_mut().enumerate() {
                let (i, j) = (min_cell.0 + (k % width) as i64, min_cell.1 + (k / width) as i64);
                *f = grid.log_odds(i, j) < reaching;
            }
        }
        let mut scratch = Vec::new();
        for p in &points {
            field.stamp_distances(p, &mut scratch);
        }
        // Most cells lie beyond every point's reach, where the value is
        // the base's logarithm alone.
        let (ln_eps, ln_eps_free) = (epsilon.ln() as f32, epsilon_free.ln() as f32);
        for k in 0..field.values.len() {
            let free = field.free.get(k).copied().unwrap_or(false);
            field.values[k] = match (field.d2[k].is_infinite(), free) {
                (true, true) => ln_eps_free,
                (true, false) => ln_eps,
                (false, _) => field.value_of(field.d2[k], free),
            };
        }
        field.points.add(&points);
        // Kept only by a field that grows (see `insert`).
        field.d2 = Vec::new();
        field
    }

    /// A field of no points and no cells.
    fn empty(resolution_m: f64, sigma_m: f64, epsilon: f64, epsilon_free: f64) -> Self {
        let mut field = Self {
            points: Buckets::new(CUTOFF_SIGMAS * sigma_m),
            epsilon,
            epsilon_free,
            two_sigma2: 2.0 * sigma_m * sigma_m,
            resolution_m,
            // Beyond 3σ the Gaussian adds less than 1.2 % to the floor.
            reach: (3.0 * sigma_m / resolution_m).ceil() as i64 + 1,
            min_cell: (0, 0),
            width: 0,
            height: 0,
            values: Vec::new(),
            d2: Vec::new(),
            free: Vec::new(),
            levels: OnceLock::new(),
            lowest: 0.0,
            step: 1.0,
            floor: epsilon.ln() as f32,
            floor_q: 0,
        };
        (field.lowest, field.step) = field.quantum();
        field.floor_q = field.quantise(field.floor);
        field
    }

    /// Adds obstacle points (non-finite ones left out): the lattice grows
    /// to hold them (with room to spare), and only the cells within each
    /// point's reach change. The field is then what
    /// [`LikelihoodField::from_points`] makes of all its points, but for
    /// the last bits of the values' rounding.
    pub fn insert(&mut self, points: &[Point2]) {
        let points: Vec<Point2> = points
            .iter()
            .copied()
            .filter(|p| p.x.is_finite() && p.y.is_finite())
            .collect();
        if self.d2.len() != self.values.len() {
            // A field made at once keeps no distances: found again.
            self.d2 = vec![f32::INFINITY; self.values.len()];
            let held: Vec<Point2> = self.points.all().collect();
            let mut scratch = Vec::new();
            for p in &held {
                self.stamp_distances(p, &mut scratch);
            }
        }
        let Some((lo, hi)) = lattice_extent(&points, None, None, self.reach, &|p| self.cell_of(p)) else {
            return;
        };
        let (old_lo, old_hi) = (
            self.min_cell,
            (
                self.min_cell.0 + self.width as i64 - 1,
                self.min_cell.1 + self.height as i64 - 1,
            ),
        );
        let inside =
            self.width > 0 && lo.0 >= old_lo.0 && lo.1 >= old_lo.1 && hi.0 <= old_hi.0 && hi.1 <= old_hi.1;
        if !inside {
            let (lo, hi) = if self.width == 0 {
                (lo, hi)
            } else {
                (
                    (lo.0.min(old_lo.0), lo.1.min(old_lo.1)),
                    (hi.0.max(old_hi.0), hi.1.max(old_hi.1)),
                )
            };
            let margin = GROWTH_MARGIN_CELLS.max((hi.0 - lo.0) / 8).max((hi.1 - lo.1) / 8);
            self.resize(((lo.0 - margin, lo.1 - margin), (hi.0 + margin, hi.1 + margin)));
        }
        for p in &points {
            let rect = self.stamp(p);
            self.pool_rect(rect);
        }
        self.points.add(&points);
    }

    /// Whether an obstacle point lies within half a cell of the centre of
    /// the cell holding `p` (a point added there would add little).
    pub fn covers(&self, p: Point2) -> bool {
        let (i, j) = self.cell_of(&p);
        let (x, y) = (i - self.min_cell.0, j - self.min_cell.1);
        let inside = x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height;
        inside
            && self
                .d2
                .get(y as usize * self.width + x as usize)
                .is_some_and(|&d| (d as f64) <= 0.25 * self.resolution_m * self.resolution_m)
    }

    /// The lattice made to cover `lo..=hi` (cells), keeping what it held
    /// there; new cells are the floor, beyond every point and unseen.
    fn resize(&mut self, (lo, hi): ((i64, i64), (i64, i64))) {
        let (width, height) = ((hi.0 - lo.0 + 1) as usize, (hi.1 - lo.1 + 1) as usize);
        let mut values = vec![self.floor; width * height];
        let mut d2 = vec![f32::INFINITY; width * height];
        let mut free = if self.free.is_empty() {
            Vec::new()
        } else {
            vec![false; width * height]
        };
        // The old rows' overlap with the new block.
        let (x0, x1) = (
            self.min_cell.0.max(lo.0),
            (self.min_cell.0 + self.width as i64 - 1).min(hi.0),
        );
        for y in 0..self.height {
            let j = self.min_cell.1 + y as i64;
            if j < lo.1 || j > hi.1 || x0 > x1 {
                continue;
            }
            let n = (x1 - x0 + 1) as usize;
            let from = y * self.width + (x0 - self.min_cell.0) as usize;
            let to = (j - lo.1) as usize * width + (x0 - lo.0) as usize;
            values[to..to + n].copy_from_slice(&self.values[from..from + n]);
            d2[to..to + n].copy_from_slice(&self.d2[from..from + n]);
            if !free.is_empty() {
                free[to..to + n].copy_from_slice(&self.free[from..from + n]);
            }
        }
        // The levels hold over a block that holds the old one: a block
        // starting beyond the old one's padded rows and columns lies in new
        // cells (the floor) alone, and blocks the old levels held reach the
        // same values as before (new cells are the floor, as the levels took
        // them to be).
        let holds_old = lo.0 <= self.min_cell.0
            && lo.1 <= self.min_cell.1
            && hi.0 >= self.min_cell.0 + self.width as i64 - 1
            && hi.1 >= self.min_cell.1 + self.height as i64 - 1;
        let (old_w, old_h) = self.level_dims();
        let floor_q = self.floor_q;
        match self.levels.get_mut() {
            Some(levels) if holds_old => {
                let new_w = width + PAD as usize;
                let (dx, dy) = (
                    (self.min_cell.0 - lo.0) as usize,
                    (self.min_cell.1 - lo.1) as usize,
                );
                for level in levels.iter_mut().filter(|l| !l.is_empty()) {
                    let mut moved = vec![floor_q; new_w * (height + PAD as usize)];
                    for y in 0..old_h {
                        let to = (y + dy) * new_w + dx;
                        moved[to..to + old_w].copy_from_slice(&level[y * old_w..(y + 1) * old_w]);
                    }
                    *level = moved;
                }
            }
            _ => self.levels = OnceLock::new(),
        }
        self.min_cell = lo;
        (self.width, self.height) = (width, height);
        (self.values, self.d2, self.free) = (values, d2, free);
    }

    /// The cell holding `p`.
    fn cell_of(&self, p: &Point2) -> (i64, i64) {
        (
            floor_i64(p.x / self.resolution_m),
            floor_i64(p.y / self.resolution_m),
        )
    }

    /// The cells within `reach` of point `p` on the lattice, as storage
    /// ranges `(x_lo..=x_hi, y_lo..=y_hi)`; `None` where none lies on it.
    fn reach_of(&self, p: &Point2) -> Option<((usize, usize), (usize, usize))> {
        let (i, j) = self.cell_of(p);
        let (ci, cj) = (i - self.min_cell.0, j - self.min_cell.1);
        let (x_lo, x_hi) = (
            (ci - self.reach).max(0),
            (ci + self.reach).min(self.width as i64 - 1),
        );
        let (y_lo, y_hi) = (
            (cj - self.reach).max(0),
            (cj + self.reach).min(self.height as i64 - 1),
        );
        (x_lo <= x_hi && y_lo <= y_hi)
            .then_some(((x_lo as usize, x_hi as usize), (y_lo as usize, y_hi as usize)))
    }

    /// Lowers the squared distances within `p`'s reach to `p`'s
    /// (`scratch`: room for the squared offsets of its columns).
    fn stamp_distances(&mut self, p: &Point2, scratch: &mut Vec<f64>) {
        let Some(((x_lo, x_hi), (y_lo, y_hi))) = self.reach_of(p) else {
            return;
        };
        let res = self.resolution_m;
        // The squared offsets across the columns, shared by every row.
        scratch.clear();
        scratch.extend((x_lo..=x_hi).map(|x| {
            let ddx = ((self.min_cell.0 + x as i64) as f64 + 0.5) * res - p.x;
            ddx * ddx
        }));
        for y in y_lo..=y_hi {
            let ddy = ((self.min_cell.1 + y as i64) as f64 + 0.5) * res - p.y;
            let dy2 = ddy * ddy;
            let row = &mut self.d2[y * self.width + x_lo..=y * self.width + x_hi];
            for (d, &dx2) in row.iter_mut().zip(scratch.iter()) {
                *d = d.min((dx2 + dy2) as f32);
            }
        }
    }

    /// Lowers the squared distances within `p`'s reach to `p`'s and
    /// raises the values where they fell; the storage rectangle touched.
    fn stamp(&mut self, p: &Point2) -> Option<((usize, usize), (usize, usize))> {
        let rect = self.reach_of(p)?;
        let ((x_lo, x_hi), (y_lo, y_hi)) = rect;
        let res = self.resolution_m;
        for y in y_lo..=y_hi {
            let ddy = ((self.min_cell.1 + y as i64) as f64 + 0.5) * res - p.y;
            for x in x_lo..=x_hi {
                let ddx = ((self.min_cell.0 + x as i64) as f64 + 0.5) * res - p.x;
                let k = y * self.width + x;
                let d = (ddx * ddx + ddy * ddy) as f32;
                if d < self.d2[k] {
                    self.d2[k] = d;
                    let free = self.free.get(k).copied().unwrap_or(false);
                    self.values[k] = self.value_of(d, free);
                }
            }
        }
        Some(rect)
    }

    /// The lattice value of a cell `d2` (squared) from its nearest point.
    fn value_of(&self, d2: f32, free: bool) -> f32 {
        let base = if free { self.epsilon_free } else { self.epsilon };
        (base + (1.0 - self.epsilon) * (-(d2 as f64) / self.two_sigma2).exp()).ln() as f32
    }

    /// The pooled levels' quantisation: `(lowest value, step)`. Every
    /// value lies in `[ln ε_c, 0]`; a level stores `⌈(v − lowest) / step⌉`,
    /// so what it gives back is never below the value it stands for.
    fn quantum(&self) -> (f64, f64) {
        let lowest = self.epsilon.min(self.epsilon_free).ln();
        (lowest, -lowest / 255.0)
    }

    /// A value as a level stores it (rounded up).
    fn quantise(&self, v: f32) -> u8 {
        ((v as f64 - self.lowest) / self.step).ceil().clamp(0.0, 255.0) as u8
    }

    /// The levels' row length and rows (the lattice's, with `PAD` more
    /// cells before each).
    fn level_dims(&self) -> (usize, usize) {
        (self.width + PAD as usize, self.height + PAD as usize)
    }

    /// The pooled levels (see [`LikelihoodField::pooled`]), made now if
    /// not yet.
    pub(crate) fn levels(&self) -> &[Vec<u8>] {
        self.levels.get_or_init(|| self.pool_all())
    }

    /// Whether the pooled levels are made (a branch and bound has asked
    /// for them).
    pub(crate) fn has_levels(&self) -> bool {
        self.levels.get().is_some()
    }

    /// The cells each pooled level holds (what making them costs, per
    /// level).
    pub(crate) fn level_cells(&self) -> usize {
        let (w, ht) = self.level_dims();
        w * ht
    }

    /// Every pooled level made anew (from the lattice quantised).
    fn pool_all(&self) -> Vec<Vec<u8>> {
        let mut levels = vec![Vec::new(); POOLED_LEVELS + 1];
        let (w, ht) = self.level_dims();
        let mut q = vec![self.floor_q; w * ht];
        for y in 0..self.height {
            let row = &self.values[y * self.width..][..self.width];
            let to = &mut q[(y + PAD as usize) * w + PAD as usize..][..self.width];
            for (t, &v) in to.iter_mut().zip(row) {
                *t = ((v as f64 - self.lowest) / self.step).ceil().clamp(0.0, 255.0) as u8;
            }
        }
        for h in 1..=POOLED_LEVELS {
            let half = 1usize << (h - 1);
            let below = if h == 1 { &q } else { &levels[h - 1] };
            let mut level = vec![self.floor_q; w * ht];
            for y in 0..ht {
                let row = &below[y * w..][..w];
                let up = (y + half < ht).then(|| &below[(y + half) * w..][..w]);
                let out = &mut level[y * w..][..w];
                for x in 0..w {
                    let mut m = row[x];
                    if x + half < w {
                        m = m.max(row[x + half]);
                    } else {
                        m = m.max(self.floor_q);
                    }
                    match up {
                        Some(up) => {
                            m = m.max(up[x]);
                            m = m.max(if x + half < w { up[x + half] } else { self.floor_q });
                        }
                        None => m = m.max(self.floor_q),
                    }
                    out[x] = m;
                }
            }
            levels[h] = level;
        }
        levels
    }

    /// The levels made anew where a rectangle of the lattice that changed
    /// (storage ranges, inclusive) reaches: blocks starting up to `2ʰ − 1`
    /// cells before it.
    fn pool_rect(&mut self, rect: Option<((usize, usize), (usize, usize))>) {
        let Some(((x_lo, x_hi), (y_lo, y_hi))) = rect else {
            return;
        };
        let (w, ht) = self.level_dims();
        let Some(levels) = self.levels.get_mut() else {
            return;
        };
        let pad = PAD as usize;
        // In padded coordinates from here.
        let (x_hi, y_hi) = (x_hi + pad, y_hi + pad);
        for h in 1..=POOLED_LEVELS {
            let half = 1usize << (h - 1);
            let back = (1usize << h) - 1;
            let (lower, upper) = levels.split_at_mut(h);
            let (below, level) = (&lower[h - 1], &mut upper[0]);
            // Level 0 is the lattice's values quantised.
            let (values, width, height) = (&self.values, self.width, self.height);
            let (lowest, step, floor_q) = (self.lowest, self.step, self.floor_q);
            let get = |x: usize, y: usize| {
                if h == 1 {
                    let (vx, vy) = (x.wrapping_sub(pad), y.wrapping_sub(pad));
                    if vx < width && vy < height {
                        ((values[vy * width + vx] as f64 - lowest) / step)
                            .ceil()
                            .clamp(0.0, 255.0) as u8
                    } else {
                        floor_q
                    }
                } else if x < w && y < ht {
                    below[y * w + x]
                } else {
                    floor_q
                }
            };
            for y in (y_lo + pad).saturating_sub(back)..=y_hi {
                for x in (x_lo + pad).saturating_sub(back)..=x_hi {
                    level[y * w + x] = get(x, y)
                        .max(get(x + half, y))
                        .max(get(x, y + half))
                        .max(get(x + half, y + half));
                }
            }
        }
    }

    /// At least the largest lattice value over the cells
    /// `[i, i + 2ʰ) × [j, j + 2ʰ)` (the floor beyond the lattice), to one
    /// step of the levels' quantisation. At `h = 0`,
    /// [`LikelihoodField::cell`].
    #[inline]
    #[cfg(test)]
    pub(crate) fn pooled(&self, h: usize, i: i64, j: i64) -> f32 {
        if h == 0 {
            return self.cell(i, j);
        }
        let (px, py) = (i - self.min_cell.0 + PAD, j - self.min_cell.1 + PAD);
        let (w, ht) = self.level_dims();
        let q = if px >= 0 && py >= 0 && (px as usize) < w && (py as usize) < ht {
            self.levels()[h][py as usize * w + px as usize]
        } else {
            self.floor_q
        };
        (self.lowest + q as f64 * self.step) as f32 + f32::EPSILON
    }

    /// At least the sum, in `f32` in any order, of the lattice values of
    /// `cells` each moved by `(a, b)` and then by any offset within the
    /// block of side `2ʰ` (`h ≥ 1`): level `h`'s bytes summed as integers,
    /// turned into a value once, plus the most that summing `n` values of
    /// magnitude at most `|lowest|` in `f32` can add by rounding.
    #[inline]
    pub(crate) fn pooled_sum(
        &self,
        levels: &[Vec<u8>],
        h: usize,
        cells: &[(i64, i64)],
        a: i64,
        b: i64,
    ) -> f32 {
        let (w, ht) = self.level_dims();
        let level = &levels[h];
        let (dx, dy) = (a - self.min_cell.0 + PAD, b - self.min_cell.1 + PAD);
        let mut q: u64 = 0;
        for &(i, j) in cells {
            let (px, py) = (i + dx, j + dy);
            q += u64::from(if px >= 0 && py >= 0 && (px as usize) < w && (py as usize) < ht {
                level[py as usize * w + px as usize]
            } else {
                self.floor_q
            });
        }
        let n = cells.len() as f64;
        // Summing n terms in f32 errs by at most (n − 1)·2⁻²⁴ of their
        // magnitudes' sum: twice that, to spare.
        let rounding = n * n * self.lowest.abs() * f64::from(f32::EPSILON);
        let sum = n * self.lowest + q as f64 * self.step + rounding;
        // Rounding to the nearest f32 moves it by at most half of this.
        (sum + sum.abs() * f64::from(f32::EPSILON)) as f32
    }

    /// Cell side, metres.
    pub fn resolution_m(&self) -> f64 {
        self.resolution_m
    }

    /// How many obstacle points the field was made of.
    pub fn obstacle_points(&self) -> usize {
        self.points.len
    }

    /// The log-likelihood of an endpoint far from every mapped obstacle.
    pub fn floor(&self) -> f32 {
        self.floor
    }

    /// The value of cell `(i, j)` (the floor outside the stored extent).
    #[inline]
    pub fn cell(&self, i: i64, j: i64) -> f32 {
        let (x, y) = (i - self.min_cell.0, j - self.min_cell.1);
        if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
            self.values[y as usize * self.width + x as usize]
        } else {
            self.floor
        }
    }

    /// Whether an obstacle point lies within `radius` of `p` (map frame).
    pub(crate) fn obstacle_within(&self, p: Point2, radius: f64) -> bool {
        self.points.any_within(p, radius)
    }

    /// How far from its nearest obstacle point an endpoint may lie and
    /// still count as matched (its exact value at least that of a point
    /// `2σ` off an obstacle on unseen floor, see [`Registration::matched`](crate::Registration::matched)),
    /// with a hair to spare for rounding; `None` where a point with no
    /// obstacle near may count (a base above that value).
    pub(crate) fn matched_radius(&self) -> Option<f64> {
        let eps = self.epsilon;
        let near = eps + (1.0 - eps) * (-2.0f64).exp();
        let base = eps.max(self.epsilon_free);
        if base >= near {
            return None;
        }
        let d2 = -self.two_sigma2 * ((near - base) / (1.0 - eps)).ln();
        let d = d2.max(0.0).sqrt().min(self.points.cutoff);
        Some(d * (1.0 + 1e-6) + 1e-9)
    }

    /// The exact value at a map point, from its nearest obstacle point
    /// within the cutoff.
    pub fn exact(&self, p: Point2) -> f64 {
        match self.points.nearest(p) {
            Some((_, d2)) => self.value(p, d2),
            None => self.base_at(p).ln(),
        }
    }

    /// [`LikelihoodField::exact`] at `p`, which lies within the reach of
    /// `near`'s endpoint `k` (see [`Neighbourhood`]): its nearest obstacle
    /// point within the cutoff is among the endpoint's candidates, the same
    /// point at the same distance to the bit.
    pub(crate) fn exact_near(&self, near: &Neighbourhood, k: usize, p: Point2) -> f64 {
        match near.nearest(k, p, self.points.cutoff2) {
            Some((_, d2)) => self.value(p, d2),
            None => self.base_at(p).ln(),
        }
    }

    /// The value at `p` with its slope and curvature (see [`Slope`]): as
    /// [`LikelihoodField::exact_near`] where `p` lies within the reach of
    /// `near`'s endpoint `k` (`within`), else as [`LikelihoodField::exact`].
    pub(crate) fn slope(&self, near: &Neighbourhood, k: usize, p: Point2, within: bool) -> Slope {
        let nearest = if within {
            near.nearest(k, p, self.points.cutoff2)
        } else {
            self.points.nearest(p)
        };
        let base = self.base_at(p);
        let Some((o, d2)) = nearest else {
            return Slope {
                value: base.ln(),
                offset: [0.0, 0.0],
                share: 0.0,
            };
        };
        let gauss = (1.0 - self.epsilon) * (-d2 / self.two_sigma2).exp();
        Slope {
            value: (base + gauss).ln(),
            offset: [p.x - o[0], p.y - o[1]],
            share: gauss / (base + gauss),
        }
    }

    /// The normal of the surface the obstacle point `o` lies on: the least
    /// axis of the scatter of the obstacle points within `radius` of it,
    /// where they lie along a line (the least spread under a third of the
    /// most, at least three points); `None` at a post, a corner or a lone
    /// point, which bound every direction alike.
    pub(crate) fn surface_normal(
        &self,
        o: [f64; 2],
        radius: f64,
        buffer: &mut Vec<[f64; 2]>,
    ) -> Option<[f64; 2]> {
        buffer.clear();
        self.points.within(Point2::new(o[0], o[1]), radius, buffer);
        if buffer.len() < 3 {
            return None;
        }
        let n = buffer.len() as f64;
        let (mx, my) = buffer.iter().fold((0.0, 0.0), |(x, y), c| (x + c[0], y + c[1]));
        let (mx, my) = (mx / n, my / n);
        let (sxx, sxy, syy) = buffer.iter().fold((0.0, 0.0, 0.0), |(a, b, c), p| {
            let (dx, dy) = (p[0] - mx, p[1] - my);
            (a + dx * dx, b + dx * dy, c + dy * dy)
        });
        // The scatter's eigenvalues and the least one's axis.
        let (half_trace, half_diff) = (0.5 * (sxx + syy), 0.5 * (sxx - syy));
        let root = half_diff.hypot(sxy);
        let (least, most) = (half_trace - root, half_trace + root);
        if most.is_nan() || most <= 0.0 || least * 9.0 > most {
            return None;
        }
        // The most's axis is (cos φ, sin φ) with tan 2φ = 2sxy / (sxx − syy).
        let phi = 0.5 * sxy.atan2(half_diff);
        Some([-phi.sin(), phi.cos()])
    }

    /// The share `w` of the Gaussian in the value at `p` for an obstacle
    /// `d2` (squared) away.
    pub(crate) fn share_at(&self, p: Point2, d2: f64) -> f64 {
        let gauss = (1.0 - self.epsilon) * (-d2 / self.two_sigma2).exp();
        gauss / (self.base_at(p) + gauss)
    }

    /// `σ²` of the field's Gaussian.
    pub(crate) fn sigma2(&self) -> f64 {
        0.5 * self.two_sigma2
    }

    /// The obstacle points that can be nearest within the cutoff to any
    /// point within `reach_m` of each of `starts`.
    pub(crate) fn neighbourhood(&self, starts: &[Point2], reach_m: f64) -> Neighbourhood {
        let mut offsets = Vec::with_capacity(starts.len() + 1);
        let mut candidates = Vec::new();
        offsets.push(0u32);
        for p in starts {
            // A point `q` within reach of a start whose nearest obstacle
            // lies `d₀` away has its own within `d₀ + reach`: all within
            // `d₀ + 2·reach` of the start. Without one within the cutoff,
            // any within the cutoff of `q` lies within cutoff + reach.
            let radius = match self.points.nearest(*p) {
                Some((_, d0)) => d0.sqrt() + 2.0 * reach_m,
                None => self.points.cutoff + reach_m,
            };
            // A hair wider against rounding: a point too many costs
            // nothing, a point missed would change the value.
            let radius = radius.min(self.points.cutoff + reach_m) * (1.0 + 1e-9) + 1e-12;
            self.points.within(*p, radius, &mut candidates);
            offsets.push(candidates.len() as u32);
        }
        Neighbourhood {
            reach_m,
            offsets,
            candidates,
        }
    }

    /// The floor's base at a map point: `ε_free` on seen floor, else `ε`.
    fn base_at(&self, p: Point2) -> f64 {
        if self.free.is_empty() {
            return self.epsilon;
        }
        let (i, j) = self.cell_of(&p);
        let (x, y) = (i - self.min_cell.0, j - self.min_cell.1);
        let inside = x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height;
        if inside && self.free[y as usize * self.width + x as usize] {
            self.epsilon_free
        } else {
            self.epsilon
        }
    }

    /// The value at `p`, its nearest obstacle point `d2` (squared) away.
    fn value(&self, p: Point2, d2: f64) -> f64 {
        (self.base_at(p) + (1.0 - self.epsilon) * (-d2 / self.two_sigma2).exp()).ln()
    }

    /// The stored block: `(min_cell, width, height, values)`, row-major.
    pub(crate) fn raw(&self) -> ((i64, i64), usize, usize, &[f32]) {
        (self.min_cell, self.width, self.height, &self.values)
    }
}

/// Obstacle points in square buckets of the cutoff's side: every point
/// within the cutoff of a query lies in the 3 × 3 buckets about it.
#[derive(Debug, Clone)]
struct Buckets {
    cutoff: f64,
    cutoff2: f64,
    /// Bucket index of storage element 0.
    min: (i64, i64),
    width: usize,
    height: usize,
    cells: Vec<Vec<[f64; 2]>>,
    len: usize,
}

impl Buckets {
    fn new(cutoff: f64) -> Self {
        Self {
            cutoff,
            cutoff2: cutoff * cutoff,
            min: (0, 0),
            width: 0,
            height: 0,
            cells: Vec::new(),
            len: 0,
        }
    }

    fn bucket_of(&self, p: Point2) -> (i64, i64) {
        (floor_i64(p.x / self.cutoff), floor_i64(p.y / self.cutoff))
    }

    /// Adds finite points, growing the buckets' extent where needed.
    fn add(&mut self, points: &[Point2]) {
        let Some((lo, hi)) = points
            .iter()
            .fold(None, |e: Option<((i64, i64), (i64, i64))>, p| {
                let b = self.bucket_of(*p);
                Some(match e {
                    None => (b, b),
                    Some((lo, hi)) => ((lo.0.min(b.0), lo.1.min(b.1)), (hi.0.max(b.0), hi.1.max(b.1))),
                })
            })
        else {
            return;
        };
        let old_hi = (
            self.min.0 + self.width as i64 - 1,
            self.min.1 + self.height as i64 - 1,
        );
        let inside = self.width > 0
            && lo.0 >= self.min.0
            && lo.1 >= self.min.1
            && hi.0 <= old_hi.0
            && hi.1 <= old_hi.1;
        if !inside {
            let (lo, hi) = if self.width == 0 {
                (lo, hi)
            } else {
                (
                    (lo.0.min(self.min.0), lo.1.min(self.min.1)),
                    (hi.0.max(old_hi.0), hi.1.max(old_hi.1)),
                )
            };
            let margin = 4.max((hi.0 - lo.0) / 4).max((hi.1 - lo.1) / 4);
            let (lo, hi) = ((lo.0 - margin, lo.1 - margin), (hi.0 + margin, hi.1 + margin));
            let (width, height) = ((hi.0 - lo.0 + 1) as usize, (hi.1 - lo.1 + 1) as usize);
            let mut cells = vec![Vec::new(); width * height];
            for (k, bucket) in self.cells.drain(..).enumerate() {
                let (x, y) = (
                    self.min.0 + (k % self.width) as i64 - lo.0,
                    self.min.1 + (k / self.width) as i64 - lo.1,
                );
                cells[y as usize * width + x as usize] = bucket;
            }
            (self.min, self.width, self.height, self.cells) = (lo, width, height, cells);
        }
        for p in points {
            let (i, j) = self.bucket_of(*p);
            let k = (j - self.min.1) as usize * self.width + (i - self.min.0) as usize;
            self.cells[k].push([p.x, p.y]);
        }
        self.len += points.len();
    }

    /// The points of the buckets `lo..=hi` (bucket indices).
    fn buckets(&self, lo: (i64, i64), hi: (i64, i64)) -> impl Iterator<Item = &[f64; 2]> {
        let (x_lo, x_hi) = (
            (lo.0 - self.min.0).max(0),
            (hi.0 - self.min.0).min(self.width as i64 - 1),
        );
        let (y_lo, y_hi) = (
            (lo.1 - self.min.1).max(0),
            (hi.1 - self.min.1).min(self.height as i64 - 1),
        );
        (y_lo..=y_hi).flat_map(move |y| {
            (x_lo..=x_hi).flat_map(move |x| self.cells[y as usize * self.width + x as usize].iter())
        })
    }

    /// Every point held.
    fn all(&self) -> impl Iterator<Item = Point2> + '_ {
        self.cells.iter().flatten().map(|c| Point2::new(c[0], c[1]))
    }

    /// The nearest point within the cutoff of `p` and its squared distance.
    fn nearest(&self, p: Point2) -> Option<([f64; 2], f64)> {
        let (i, j) = self.bucket_of(p);
        nearest_of(self.buckets((i - 1, j - 1), (i + 1, j + 1)), p, self.cutoff2)
    }

    /// Whether any point lies within `radius` of `p`.
    fn any_within(&self, p: Point2, radius: f64) -> bool {
        let r2 = radius * radius;
        let lo = self.bucket_of(Point2::new(p.x - radius, p.y - radius));
        let hi = self.bucket_of(Point2::new(p.x + radius, p.y + radius));
        self.buckets(lo, hi).any(|c| squared_distance(p, c) <= r2)
    }

    /// Appends every point within `radius` of `p`.
    fn within(&self, p: Point2, radius: f64, out: &mut Vec<[f64; 2]>) {
        let r2 = radius * radius;
        let lo = self.bucket_of(Point2::new(p.x - radius, p.y - radius));
        let hi = self.bucket_of(Point2::new(p.x + radius, p.y + radius));
        out.extend(self.buckets(lo, hi).filter(|c| squared_distance(p, c) <= r2));
    }
}

/// `|p − c|²`, the one formula every nearest-point query uses (so that
/// they agree to the bit).
#[inline]
fn squared_distance(p: Point2, c: &[f64; 2]) -> f64 {
    (p.x - c[0]) * (p.x - c[0]) + (p.y - c[1]) * (p.y - c[1])
}

/// The nearest of `candidates` to `p` within `cutoff2` (squared), and its
/// squared distance; the first among equals.
fn nearest_of<'a>(
    candidates: impl Iterator<Item = &'a [f64; 2]>,
    p: Point2,
    cutoff2: f64,
) -> Option<([f64; 2], f64)> {
    candidates
        .map(|c| (*c, squared_distance(p, c)))
        .filter(|c| c.1 <= cutoff2)
        .fold(None, |m: Option<([f64; 2], f64)>, c| match m {
            Some(m) if m.1 <= c.1 => Some(m),
            _ => Some(c),
        })
}

/// The cells a field's lattice covers: the points with the Gaussian's
/// `reach` about each, and the free-space grid's stored cells, cut to
/// `region` where one is given; `None` where nothing is left.
fn lattice_extent(
    points: &[Point2],
    free_space: Option<(&OccupancyGrid, f64)>,
    region: Option<((i64, i64), (i64, i64))>,
    reach: i64,
    cell: &dyn Fn(&Point2) -> (i64, i64),
) -> Option<((i64, i64), (i64, i64))> {
    let mut extent: Option<((i64, i64), (i64, i64))> = None;
    let mut grow = |lo: (i64, i64), hi: (i64, i64)| {
        extent = Some(match extent {
            None => (lo, hi),
            Some((a, b)) => ((a.0.min(lo.0), a.1.min(lo.1)), (b.0.max(hi.0), b.1.max(hi.1))),
        });
    };
    for p in points {
        let (i, j) = cell(p);
        grow((i - reach, j - reach), (i + reach, j + reach));
    }
    if let Some((grid, _)) = free_space {
        let (i, j, w, h) = grid.extent();
        if w > 0 && h > 0 {
            grow((i, j), (i + w as i64 - 1, j + h as i64 - 1));
        }
    }
    match (extent, region) {
        (Some((a, b)), Some((lo, hi))) => {
            let (a, b) = ((a.0.max(lo.0), a.1.max(lo.1)), (b.0.min(hi.0), b.1.min(hi.1)));
            (a.0 <= b.0 && a.1 <= b.1).then_some((a, b))
        }
        (e, _) => e,
    }
}

/// The field near a point `q` whose nearest obstacle point `o` stays put:
/// `value = ln(ε_c + g)`, `g = (1 − ε)·exp(−|r|²/2σ²)`, `r = q − o`. With
/// `w = g / (ε_c + g)` (the share of the Gaussian in the value) its
/// gradient is `−w·r/σ²` and its Hessian `−w/σ²·I + w(1 − w)·r rᵀ/σ⁴`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Slope {
    /// The value.
    pub value: f64,
    /// `r`, metres (zero without an obstacle point within the cutoff).
    pub offset: [f64; 2],
    /// `w`.
    pub share: f64,
}

/// Candidate nearest obstacle points for a set of endpoints, for exact
/// queries within `reach_m` of where each endpoint started
/// ([`LikelihoodField::neighbourhood`]): refinement moves a pose by little,
/// so each endpoint's nearest obstacle is one of a few known points.
#[derive(Debug, Clone)]
pub(crate) struct Neighbourhood {
    /// How far a query may lie from its endpoint's start, metres.
    pub reach_m: f64,
    /// Endpoint `k`'s candidates are `candidates[offsets[k]..offsets[k + 1]]`.
    offsets: Vec<u32>,
    candidates: Vec<[f64; 2]>,
}

impl Neighbourhood {
    /// The nearest of endpoint `k`'s candidates to `p` within `cutoff2`.
    fn nearest(&self, k: usize, p: Point2, cutoff2: f64) -> Option<([f64; 2], f64)> {
        let candidates = &self.candidates[self.offsets[k] as usize..self.offsets[k + 1] as usize];
        nearest_of(candidates.iter(), p, cutoff2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peaks_on_occupied_cells_and_falls_with_distance() {
        let eps = 0.1;
        let f = LikelihoodField::from_points(&[Point2::new(0.105, 0.105)], 0.01, 0.015, eps);
        assert!(f.cell(10, 10).abs() < 1e-6, "on the obstacle: ln 1");
        // One cell away: ln(ε + (1-ε)·exp(-1 / (2·1.5²))).
        let one = (eps + (1.0 - eps) * (-1.0f64 / 4.5).exp()).ln() as f32;
        assert!((f.cell(11, 10) - one).abs() < 1e-6);
        assert!((f.cell(10, 9) - one).abs() < 1e-6);
        assert!(f.cell(12, 12) < f.cell(11, 11) && f.cell(11, 11) < f.cell(11, 10));
        assert_eq!(f.cell(30, 10), (eps as f32).ln(), "far: the floor");
        assert_eq!(f.cell(-1000, 5), f.floor());
        // The exact value agrees with the lattice at cell centres.
        assert!((f.exact(Point2::new(0.115, 0.105)) as f32 - f.cell(11, 10)).abs() < 1e-6);
        let half = (eps + (1.0 - eps) * (-0.25f64 / 4.5).exp()).ln();
        assert!((f.exact(Point2::new(0.11, 0.105)) - half).abs() < 1e-9);
    }

    #[test]
    fn the_nearest_obstacle_counts() {
        let f = LikelihoodField::from_points(
            &[Point2::new(0.005, 0.005), Point2::new(0.045, 0.005)],
            0.01,
            0.02,
            0.1,
        );
        assert_eq!(f.cell(1, 0), f.cell(3, 0));
        assert_eq!(f.cell(1, 0), f.cell(-1, 0));
        assert_eq!(f.obstacle_points(), 2);
    }

    #[test]
    fn keeps_sub_cell_positions() {
        // A wall on the border y = 0 between cell rows -1 and 0: the field
        // is symmetric about the border, not about row 0's centre.
        let wall: Vec<Point2> = (0..50).map(|k| Point2::new(k as f64 * 0.002, 0.0)).collect();
        let f = LikelihoodField::from_points(&wall, 0.01, 0.015, 0.2);
        assert!((f.cell(3, 0) - f.cell(3, -1)).abs() < 1e-6);
        assert!((f.exact(Point2::new(0.05, 0.004)) - f.exact(Point2::new(0.05, -0.004))).abs() < 1e-9);
        assert!(f.exact(Point2::new(0.05, 0.0)) > f.exact(Point2::new(0.05, 0.004)));
    }

    #[test]
    fn seen_floor_scores_below_unknown_ground() {
        use pirouette_geom::Pose2;
        use pirouette_grid::{GridConfig, OccupancyGrid, FREE_THRESH};
        use pirouette_profile::Rop;
        // Five looks along +x at a wall 0.5 m ahead: floor before it free.
        let mut rop = Rop::covering(-0.3, 0.3, 0.25f64.to_radians(), 0.9).unwrap();
        rop.range_m.iter_mut().for_each(|r| *r = 0.5);
        let mut grid = OccupancyGrid::new(GridConfig::default()).unwrap();
        for _ in 0..5 {
            grid.insert_profile(&Pose2::IDENTITY, &rop, 0.1);
        }
        let wall: Vec<Point2> = (-10..=10).map(|k| Point2::new(0.5, k as f64 * 0.01)).collect();
        let f = LikelihoodField::from_map(&wall, &grid, FREE_THRESH, 0.015, 0.2, 0.02);
        let on_floor = f.exact(Point2::new(0.3, 0.0));
        let unknown = f.exact(Point2::new(0.3, 0.6));
        assert!((on_floor - 0.02f64.ln()).abs() < 1e-9, "{on_floor}");
        assert!((unknown - 0.2f64.ln()).abs() < 1e-9, "{unknown}");
        assert!(f.exact(Point2::new(0.5, 0.0)) > -0.01);
        // The lattice agrees at cell centres.
        assert!((f.cell(30, 0) as f64 - f.exact(Point2::new(0.305, 0.005))).abs() < 1e-6);
    }

    #[test]
    fn a_field_within_a_region_matches_the_whole_field_there() {
        use pirouette_grid::{GridConfig, OccupancyGrid, FREE_THRESH};
        let grid = OccupancyGrid::new(GridConfig::default()).unwrap();
        let wall: Vec<Point2> = (0..300).map(|k| Point2::new(k as f64 * 0.01, 0.5)).collect();
        let whole = LikelihoodField::from_map(&wall, &grid, FREE_THRESH, 0.015, 0.2, 0.02);
        let part = LikelihoodField::from_map_within(
            &wall,
            &grid,
            Point2::new(1.0, 0.0),
            Point2::new(2.0, 1.0),
            FREE_THRESH,
            0.015,
            0.2,
            0.02,
        );
        for (i, j) in [(100, 50), (150, 49), (199, 51), (120, 47)] {
            assert_eq!(part.cell(i, j), whole.cell(i, j), "({i}, {j})");
        }
        assert_eq!(part.cell(50, 50), part.floor(), "outside the region");
        let p = Point2::new(1.5, 0.51);
        assert!((part.exact(p) - whole.exact(p)).abs() < 1e-12);
    }

    /// Within reach of its start, an endpoint's exact value from its
    /// candidates is the k-d tree's to the bit.
    #[test]
    fn a_neighbourhood_gives_the_exact_value() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let pts: Vec<Point2> = (0..500)
            .map(|_| Point2::new(rng.random_range(0.0..1.0), rng.random_range(0.0..1.0)))
            .collect();
        let f = LikelihoodField::from_points(&pts, 0.01, 0.015, 0.2);
        let starts: Vec<Point2> = (0..200)
            .map(|_| Point2::new(rng.random_range(-0.1..1.1), rng.random_range(-0.1..1.1)))
            .collect();
        let reach = 0.01;
        let near = f.neighbourhood(&starts, reach);
        let mut checked = 0;
        for (k, s) in starts.iter().enumerate() {
            for _ in 0..20 {
                let (r, a): (f64, f64) = (rng.random_range(0.0..reach), rng.random_range(0.0..6.3));
                let q = Point2::new(s.x + r * a.cos(), s.y + r * a.sin());
                assert_eq!(f.exact_near(&near, k, q).to_bits(), f.exact(q).to_bits(), "{q:?}");
                checked += 1;
            }
        }
        assert_eq!(checked, 4000);
    }

    /// Points inserted a batch at a time give the lattice of the field
    /// made of them all at once, to the bit; the pooled levels give every
    /// block's largest value, rounded up by less than their quantum.
    #[test]
    fn an_inserted_field_is_the_field_of_all_its_points() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let mut all = Vec::new();
        let mut grown = LikelihoodField::from_points(&[], 0.01, 0.015, 0.2);
        for batch in 0..6 {
            // Each batch further out: the lattice grows.
            let r = 0.3 + 0.4 * batch as f64;
            let pts: Vec<Point2> = (0..80)
                .map(|_| Point2::new(rng.random_range(-r..r), rng.random_range(-r..0.5 * r)))
                .collect();
            // The first batch made at once (a field that keeps no
            // distances until it grows), the others inserted.
            if batch == 0 {
                grown = LikelihoodField::from_points(&pts, 0.01, 0.015, 0.2);
            } else {
                grown.insert(&pts);
            }
            all.extend(pts);
        }
        let whole = LikelihoodField::from_points(&all, 0.01, 0.015, 0.2);
        assert_eq!(grown.obstacle_points(), 480);
        let mut on = 0;
        for j in -260..=140 {
            for i in -260..=260 {
                assert_eq!(
                    grown.cell(i, j).to_bits(),
                    whole.cell(i, j).to_bits(),
                    "({i}, {j})"
                );
                on += usize::from(whole.cell(i, j) > whole.floor());
            }
        }
        assert!(on > 10_000, "{on} cells near points");
        for _ in 0..3000 {
            let q = Point2::new(rng.random_range(-2.5..2.5), rng.random_range(-2.5..1.5));
            assert_eq!(grown.exact(q).to_bits(), whole.exact(q).to_bits(), "{q:?}");
        }
        for field in [&grown, &whole] {
            let step = (field.step + 1e-6) as f32;
            for _ in 0..2000 {
                let h = rng.random_range(1..=POOLED_LEVELS);
                let (i, j) = (rng.random_range(-300..300i64), rng.random_range(-300..200i64));
                let side = 1i64 << h;
                let most = (j..j + side)
                    .flat_map(|y| (i..i + side).map(move |x| (x, y)))
                    .map(|(x, y)| field.cell(x, y))
                    .fold(f32::NEG_INFINITY, f32::max);
                let bound = field.pooled(h, i, j);
                assert!(
                    bound >= most && bound <= most + step,
                    "level {h} at ({i}, {j}): {bound} for {most}"
                );
            }
            // A level's sum over many cells bounds their f32 sum at every
            // offset within the block, and exceeds the sum of each cell's
            // own largest value in the block by little more than a step each.
            for _ in 0..40 {
                let h = rng.random_range(1..=POOLED_LEVELS);
                let cells: Vec<(i64, i64)> = (0..rng.random_range(1..300))
                    .map(|_| (rng.random_range(-300..300i64), rng.random_range(-300..200i64)))
                    .collect();
                let (a, b) = (rng.random_range(-20..20i64), rng.random_range(-20..20i64));
                let side = 1i64 << h;
                let most = (0..side)
                    .flat_map(|v| (0..side).map(move |u| (u, v)))
                    .map(|(u, v)| {
                        cells
                            .iter()
                            .map(|&(i, j)| field.cell(i + a + u, j + b + v))
                            .sum::<f32>()
                    })
                    .fold(f32::NEG_INFINITY, f32::max);
                let own: f64 = (cells.iter())
                    .map(|&(i, j)| f64::from(field.pooled(h, i + a, j + b)))
                    .sum();
                let bound = field.pooled_sum(field.levels(), h, &cells, a, b);
                assert!(
                    bound >= most && f64::from(bound) <= own + cells.len() as f64 * 1e-3,
                    "level {h}, {} cells: {bound} for {most}",
                    cells.len()
                );
            }
        }
    }

    #[test]
    fn an_empty_map_is_all_floor() {
        let f = LikelihoodField::from_points(&[], 0.01, 0.02, 0.1);
        assert!((f.exact(Point2::new(0.3, 0.2)) - f.floor() as f64).abs() < 1e-6);
    }
}
