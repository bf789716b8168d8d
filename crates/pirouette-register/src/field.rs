//! The likelihood field of a map: how well a point explains an obstacle.

mod window;

use crate::floor_i64;
use pirouette_geom::Point2;
use pirouette_grid::OccupancyGrid;
use std::sync::OnceLock;
pub(crate) use window::Window;

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
/// The lattice is kept in tiles of 32 × 32 cells, and only tiles within
/// reach of an obstacle point or on seen floor (and the tiles just before
/// them, whose pooled blocks reach into them) are stored: about 5 bytes
/// per cell of those tiles (value and seen floor), four more (the squared
/// distances) in a field that grows, four more once a branch and bound
/// asks for the pooled levels; and 16 bytes per point. A laser's submap
/// out to 40 m stores about a fifteenth of the box its points span.
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
    /// Where each tile's cells are stored.
    table: Table,
    /// The stored tiles' values, [`TILE_CELLS`] a tile, row-major within
    /// it; tile 0 is every tile not stored: all floor.
    values: Vec<f32>,
    /// The squared distance from each stored cell's centre to the nearest
    /// point within `reach` cells (infinite beyond), as `values`; kept
    /// once the field has grown (empty in a field made at once, which
    /// needs it no more).
    d2: Vec<f32>,
    /// The stored tiles' cells the map has seen free, as `values` (empty:
    /// none).
    free: Vec<bool>,
    /// The max-pooled levels `1..=POOLED_LEVELS` (index 0 unused; see
    /// [`LikelihoodField::pooled`]), stored as `values`: per cell, the
    /// largest value over the block of `2ʰ` cells a side starting there,
    /// quantised upward to a byte. Made when a branch and bound first asks
    /// for them (a registration that scores every pose never does), then
    /// kept as the field grows.
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

/// A pooled block starting up to this many cells before (below or left
/// of) a cell reaches it.
const PAD: i64 = (1 << POOLED_LEVELS) - 1;

/// `log₂` of a tile's side.
const TILE_SHIFT: u32 = 5;

/// A tile's side, cells: more than [`PAD`], so that a block reaches at
/// most the tiles right of, above and diagonally from its own.
const TILE: i64 = 1 << TILE_SHIFT;

/// Cells a tile holds.
const TILE_CELLS: usize = (TILE * TILE) as usize;

/// Tiles added beyond what a growing table needs, each side, at least
/// (more for larger ones), so that it grows seldom.
const GROWTH_MARGIN_TILES: i64 = 4;

/// Where each tile of a box of tiles is stored: the index of its first
/// cell (0: not stored, tile 0, as is every tile beyond the box).
#[derive(Debug, Clone, Default)]
struct Table {
    /// Tile index of element 0.
    min: (i64, i64),
    width: usize,
    height: usize,
    starts: Vec<usize>,
}

/// A [`Table`] borrowed, its fields in locals for an inner loop.
#[derive(Clone, Copy)]
struct TableView<'t> {
    min: (i64, i64),
    width: u64,
    height: u64,
    starts: &'t [usize],
}

impl TableView<'_> {
    /// Where cell `(i, j)` is stored (see [`Table::locate`]).
    #[inline(always)]
    fn locate(&self, i: i64, j: i64) -> usize {
        let (x, y) = (
            ((i >> TILE_SHIFT) - self.min.0) as u64,
            ((j >> TILE_SHIFT) - self.min.1) as u64,
        );
        // Below the box, the differences wrap to beyond it.
        let start = if x < self.width && y < self.height {
            self.starts[(y * self.width + x) as usize]
        } else {
            0
        };
        start + (((j & (TILE - 1)) << TILE_SHIFT) | (i & (TILE - 1))) as usize
    }
}

/// Visits, for each of `cells` moved by `(a, b)`, where the cell and
/// the three `d > 0` to its right, above and diagonally from it are
/// stored: one lookup of the table where all four lie in one tile, four
/// where they do not (always, for `d ≥ TILE`).
#[inline(always)]
fn corners(
    table: TableView,
    cells: &[(i64, i64)],
    a: i64,
    b: i64,
    d: i64,
    mut visit: impl FnMut([usize; 4]),
) {
    let up = (d << TILE_SHIFT) as usize;
    let du = d as usize;
    for &(ci, cj) in cells {
        let (i, j) = (ci + a, cj + b);
        if (i & (TILE - 1)) + d < TILE && (j & (TILE - 1)) + d < TILE {
            let k = table.locate(i, j);
            visit([k, k + du, k + up, k + up + du]);
        } else {
            visit([
                table.locate(i, j),
                table.locate(i + d, j),
                table.locate(i, j + d),
                table.locate(i + d, j + d),
            ]);
        }
    }
}

impl Table {
    /// The table for an inner loop.
    #[inline]
    fn view(&self) -> TableView<'_> {
        TableView {
            min: self.min,
            width: self.width as u64,
            height: self.height as u64,
            starts: &self.starts,
        }
    }

    /// The first cell of tile `(ti, tj)`: 0 where not stored.
    #[inline]
    fn start(&self, ti: i64, tj: i64) -> usize {
        let (x, y) = ((ti - self.min.0) as u64, (tj - self.min.1) as u64);
        // Below the box, the differences wrap to beyond it.
        if x < self.width as u64 && y < self.height as u64 {
            self.starts[y as usize * self.width + x as usize]
        } else {
            0
        }
    }

    /// The slot of tile `(ti, tj)`: 0 where not stored.
    #[inline]
    fn slot(&self, ti: i64, tj: i64) -> usize {
        self.start(ti, tj) / TILE_CELLS
    }

    /// Where cell `(i, j)` is stored (in tile 0, the floor's, where its
    /// tile is not stored).
    #[inline]
    fn locate(&self, i: i64, j: i64) -> usize {
        self.start(i >> TILE_SHIFT, j >> TILE_SHIFT)
            + (((j & (TILE - 1)) << TILE_SHIFT) | (i & (TILE - 1))) as usize
    }

    /// Grows the box to hold tiles `lo..=hi`, with a margin.
    fn hold(&mut self, lo: (i64, i64), hi: (i64, i64)) {
        let old_hi = (
            self.min.0 + self.width as i64 - 1,
            self.min.1 + self.height as i64 - 1,
        );
        let empty = self.starts.is_empty();
        if !empty && lo.0 >= self.min.0 && lo.1 >= self.min.1 && hi.0 <= old_hi.0 && hi.1 <= old_hi.1 {
            return;
        }
        let (lo, hi) = if empty {
            (lo, hi)
        } else {
            (
                (lo.0.min(self.min.0), lo.1.min(self.min.1)),
                (hi.0.max(old_hi.0), hi.1.max(old_hi.1)),
            )
        };
        let margin = GROWTH_MARGIN_TILES.max((hi.0 - lo.0) / 8).max((hi.1 - lo.1) / 8);
        let (lo, hi) = ((lo.0 - margin, lo.1 - margin), (hi.0 + margin, hi.1 + margin));
        let (width, height) = ((hi.0 - lo.0 + 1) as usize, (hi.1 - lo.1 + 1) as usize);
        let mut starts = vec![0usize; width * height];
        if !empty {
            for y in 0..self.height {
                let to = (self.min.1 + y as i64 - lo.1) as usize * width + (self.min.0 - lo.0) as usize;
                starts[to..to + self.width].copy_from_slice(&self.starts[y * self.width..][..self.width]);
            }
        }
        *self = Self {
            min: lo,
            width,
            height,
            starts,
        };
    }

    /// The stored tiles with their tile indices.
    fn stored(&self) -> impl Iterator<Item = ((i64, i64), usize)> + '_ {
        self.starts
            .iter()
            .enumerate()
            .filter(|(_, &s)| s != 0)
            .map(|(k, &s)| {
                (
                    (
                        self.min.0 + (k % self.width) as i64,
                        self.min.1 + (k / self.width) as i64,
                    ),
                    s / TILE_CELLS,
                )
            })
    }
}

/// Cells `lo..=hi` (inclusive, each axis).
type Rect = ((i64, i64), (i64, i64));

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
        region: Option<Rect>,
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
        if let Some((grid, threshold)) = free_space {
            field.mark_free(grid, threshold, region);
        }
        let mut scratch = Vec::new();
        for p in &points {
            field.stamp(p, region, false, &mut scratch);
        }
        // Each cell's value once, from its nearest point.
        for k in 0..field.values.len() {
            if field.d2[k].is_finite() {
                let free = field.free.get(k).copied().unwrap_or(false);
                field.values[k] = field.value_of(field.d2[k], free);
            }
        }
        field.points.add(&points);
        // Kept only by a field that grows (see `insert`).
        field.d2 = Vec::new();
        field
    }

    /// A field of no points and no cells.
    fn empty(resolution_m: f64, sigma_m: f64, epsilon: f64, epsilon_free: f64) -> Self {
        let floor = epsilon.ln() as f32;
        let mut field = Self {
            points: Buckets::new(CUTOFF_SIGMAS * sigma_m),
            epsilon,
            epsilon_free,
            two_sigma2: 2.0 * sigma_m * sigma_m,
            resolution_m,
            // Beyond 3σ the Gaussian adds less than 1.2 % to the floor.
            reach: (3.0 * sigma_m / resolution_m).ceil() as i64 + 1,
            table: Table::default(),
            values: vec![floor; TILE_CELLS],
            d2: vec![f32::INFINITY; TILE_CELLS],
            free: Vec::new(),
            levels: OnceLock::new(),
            lowest: 0.0,
            step: 1.0,
            floor,
            floor_q: 0,
        };
        (field.lowest, field.step) = field.quantum();
        field.floor_q = field.quantise(field.floor);
        field
    }

    /// Marks the cells of `grid` below `threshold` (within `region`) seen
    /// free: their value becomes `ln ε_free`.
    fn mark_free(&mut self, grid: &OccupancyGrid, threshold: f64, region: Option<Rect>) {
        let (i0, j0, w, h) = grid.extent();
        if w == 0 || h == 0 {
            return;
        }
        let (mut lo, mut hi) = ((i0, j0), (i0 + w as i64 - 1, j0 + h as i64 - 1));
        if let Some((a, b)) = region {
            (lo, hi) = ((lo.0.max(a.0), lo.1.max(a.1)), (hi.0.min(b.0), hi.1.min(b.1)));
            if lo.0 > hi.0 || lo.1 > hi.1 {
                return;
            }
        }
        let reaching = grid.log_odds_reaching(threshold);
        self.free = vec![false; self.values.len()];
        let ln_eps_free = self.epsilon_free.ln() as f32;
        for tj in (lo.1 >> TILE_SHIFT)..=(hi.1 >> TILE_SHIFT) {
            for ti in (lo.0 >> TILE_SHIFT)..=(hi.0 >> TILE_SHIFT) {
                let (x0, y0) = ((ti << TILE_SHIFT).max(lo.0), (tj << TILE_SHIFT).max(lo.1));
                let (x1, y1) = (
                    ((ti << TILE_SHIFT) + TILE - 1).min(hi.0),
                    ((tj << TILE_SHIFT) + TILE - 1).min(hi.1),
                );
                let seen = |i: i64, j: i64| grid.log_odds(i, j) < reaching;
                if !(y0..=y1).any(|j| (x0..=x1).any(|i| seen(i, j))) {
                    continue;
                }
                self.store(((x0 - PAD, y0 - PAD), (x1, y1)));
                for j in y0..=y1 {
                    for i in x0..=x1 {
                        if seen(i, j) {
                            let k = self.table.locate(i, j);
                            self.free[k] = true;
                            self.values[k] = ln_eps_free;
                        }
                    }
                }
            }
        }
    }

    /// Stores every tile holding a cell of `rect` not stored yet (all
    /// floor and unseen; their pooled levels the floor, which they are
    /// as long as nothing in reach of their blocks changed).
    fn store(&mut self, (lo, hi): Rect) {
        let (tlo, thi) = (
            (lo.0 >> TILE_SHIFT, lo.1 >> TILE_SHIFT),
            (hi.0 >> TILE_SHIFT, hi.1 >> TILE_SHIFT),
        );
        self.table.hold(tlo, thi);
        for tj in tlo.1..=thi.1 {
            for ti in tlo.0..=thi.0 {
                if self.table.slot(ti, tj) != 0 {
                    continue;
                }
                let k =
                    (tj - self.table.min.1) as usize * self.table.width + (ti - self.table.min.0) as usize;
                self.table.starts[k] = self.values.len();
                self.values.resize(self.values.len() + TILE_CELLS, self.floor);
                if !self.d2.is_empty() {
                    self.d2.resize(self.d2.len() + TILE_CELLS, f32::INFINITY);
                }
                if !self.free.is_empty() {
                    self.free.resize(self.free.len() + TILE_CELLS, false);
                }
                if let Some(levels) = self.levels.get_mut() {
                    for level in levels.iter_mut().skip(1) {
                        level.resize(level.len() + TILE_CELLS, self.floor_q);
                    }
                }
            }
        }
    }

    /// Adds obstacle points (non-finite ones left out), each changing only
    /// the cells within its reach. The field is then what
    /// [`LikelihoodField::from_points`] makes of all its points, to the
    /// bit.
    pub fn insert(&mut self, points: &[Point2]) {
        let points: Vec<Point2> = points
            .iter()
            .copied()
            .filter(|p| p.x.is_finite() && p.y.is_finite())
            .collect();
        let mut scratch = Vec::new();
        if self.d2.len() != self.values.len() {
            // A field made at once keeps no distances: found again.
            self.d2 = vec![f32::INFINITY; self.values.len()];
            let held: Vec<Point2> = self.points.all().collect();
            for p in &held {
                self.stamp(p, None, false, &mut scratch);
            }
        }
        for p in &points {
            let rect = self.stamp(p, None, true, &mut scratch);
            self.pool_rect(rect);
        }
        self.points.add(&points);
    }

    /// Whether an obstacle point lies within half a cell of the centre of
    /// the cell holding `p` (a point added there would add little).
    pub fn covers(&self, p: Point2) -> bool {
        let (i, j) = self.cell_of(&p);
        (self.d2.get(self.table.locate(i, j)))
            .is_some_and(|&d| (d as f64) <= 0.25 * self.resolution_m * self.resolution_m)
    }

    /// The cell holding `p`.
    fn cell_of(&self, p: &Point2) -> (i64, i64) {
        (
            floor_i64(p.x / self.resolution_m),
            floor_i64(p.y / self.resolution_m),
        )
    }

    /// Lowers the squared distances within `p`'s reach (cut to `region`,
    /// where given) to `p`'s, storing the tiles that needs, and with
    /// `values` raises the values where they fell (`scratch`: room for the
    /// squared offsets of its columns); the cells touched, `None` where
    /// none.
    fn stamp(
        &mut self,
        p: &Point2,
        region: Option<Rect>,
        values: bool,
        scratch: &mut Vec<f64>,
    ) -> Option<Rect> {
        let (i, j) = self.cell_of(p);
        let (mut lo, mut hi) = ((i - self.reach, j - self.reach), (i + self.reach, j + self.reach));
        if let Some((a, b)) = region {
            (lo, hi) = ((lo.0.max(a.0), lo.1.max(a.1)), (hi.0.min(b.0), hi.1.min(b.1)));
            if lo.0 > hi.0 || lo.1 > hi.1 {
                return None;
            }
        }
        // The blocks that reach the cells touched start in these.
        self.store(((lo.0 - PAD, lo.1 - PAD), hi));
        let res = self.resolution_m;
        // The squared offsets across the columns, shared by every row.
        scratch.clear();
        scratch.extend((lo.0..=hi.0).map(|x| {
            let ddx = (x as f64 + 0.5) * res - p.x;
            ddx * ddx
        }));
        for y in lo.1..=hi.1 {
            let ddy = (y as f64 + 0.5) * res - p.y;
            let dy2 = ddy * ddy;
            // Along the row a tile at a time: its cells lie in a run.
            let mut x = lo.0;
            while x <= hi.0 {
                let end = (x | (TILE - 1)).min(hi.0);
                let n = (end - x + 1) as usize;
                let start = self.table.locate(x, y);
                let columns = &scratch[(x - lo.0) as usize..][..n];
                if values {
                    for (c, &dx2) in columns.iter().enumerate() {
                        let (k, d) = (start + c, (dx2 + dy2) as f32);
                        if d < self.d2[k] {
                            self.d2[k] = d;
                            let free = self.free.get(k).copied().unwrap_or(false);
                            self.values[k] = self.value_of(d, free);
                        }
                    }
                } else {
                    let row = &mut self.d2[start..start + n];
                    for (d, &dx2) in row.iter_mut().zip(columns) {
                        *d = d.min((dx2 + dy2) as f32);
                    }
                }
                x = end + 1;
            }
        }
        Some((lo, hi))
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
    #[inline]
    fn quantise(&self, v: f32) -> u8 {
        ((v as f64 - self.lowest) / self.step).ceil().clamp(0.0, 255.0) as u8
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
        self.values.len()
    }

    /// Every pooled level made anew (from the lattice quantised), a stored
    /// tile at a time.
    fn pool_all(&self) -> Vec<Vec<u8>> {
        let n = self.values.len();
        let mut levels = vec![Vec::new(); POOLED_LEVELS + 1];
        levels[0] = self.values.iter().map(|&v| self.quantise(v)).collect();
        let stored: Vec<((i64, i64), usize)> = self.table.stored().collect();
        for h in 1..=POOLED_LEVELS {
            let half = 1usize << (h - 1);
            let mut level = vec![self.floor_q; n];
            let below = &levels[h - 1];
            for &((ti, tj), slot) in &stored {
                // The tile, and those right of, above and diagonally from
                // it, which its blocks reach.
                let near = [
                    slot,
                    self.table.slot(ti + 1, tj),
                    self.table.slot(ti, tj + 1),
                    self.table.slot(ti + 1, tj + 1),
                ];
                let get = |x: usize, y: usize| {
                    let t = near[(x >> TILE_SHIFT) | ((y >> TILE_SHIFT) << 1)];
                    below[t * TILE_CELLS
                        + ((y & (TILE as usize - 1)) << TILE_SHIFT)
                        + (x & (TILE as usize - 1))]
                };
                let out = &mut level[slot * TILE_CELLS..][..TILE_CELLS];
                for y in 0..TILE as usize {
                    for x in 0..TILE as usize {
                        out[(y << TILE_SHIFT) + x] = get(x, y)
                            .max(get(x + half, y))
                            .max(get(x, y + half))
                            .max(get(x + half, y + half));
                    }
                }
            }
            levels[h] = level;
        }
        levels[0] = Vec::new();
        levels
    }

    /// The levels made anew where a rectangle of the lattice that changed
    /// reaches: blocks starting up to `2ʰ − 1` cells before it.
    fn pool_rect(&mut self, rect: Option<Rect>) {
        let Some((lo, hi)) = rect else {
            return;
        };
        let Some(levels) = self.levels.get_mut() else {
            return;
        };
        let (table, values) = (&self.table, &self.values);
        let (lowest, step) = (self.lowest, self.step);
        for h in 1..=POOLED_LEVELS {
            let half = 1i64 << (h - 1);
            let back = (1i64 << h) - 1;
            let (lower, upper) = levels.split_at_mut(h);
            let (below, level) = (&lower[h - 1], &mut upper[0]);
            // Level 0 is the lattice's values quantised.
            let get = |i: i64, j: i64| {
                let k = table.locate(i, j);
                if h == 1 {
                    ((values[k] as f64 - lowest) / step).ceil().clamp(0.0, 255.0) as u8
                } else {
                    below[k]
                }
            };
            for j in lo.1 - back..=hi.1 {
                for i in lo.0 - back..=hi.0 {
                    let k = table.locate(i, j);
                    debug_assert!(k >= TILE_CELLS, "a pooled block before a changed cell is stored");
                    level[k] = get(i, j)
                        .max(get(i + half, j))
                        .max(get(i, j + half))
                        .max(get(i + half, j + half));
                }
            }
        }
    }

    /// At least the largest lattice value over the cells
    /// `[i, i + 2ʰ) × [j, j + 2ʰ)`, to one step of the levels'
    /// quantisation. At `h = 0`, [`LikelihoodField::cell`].
    #[inline]
    #[cfg(test)]
    pub(crate) fn pooled(&self, h: usize, i: i64, j: i64) -> f32 {
        if h == 0 {
            return self.cell(i, j);
        }
        let q = self.levels()[h][self.table.locate(i, j)];
        (self.lowest + q as f64 * self.step) as f32 + f32::EPSILON
    }

    /// At least the sum, in `f32` in any order, of the lattice values of
    /// `cells` each moved by `(a, b)` and then by any offset within the
    /// block of side `2ʰ` (`h ≥ 1`): level `h`'s bytes summed as integers,
    /// turned into a value once, plus the most that summing `n` values of
    /// magnitude at most `|lowest|` in `f32` can add by rounding.
    #[cfg(test)]
    pub(crate) fn pooled_sum(
        &self,
        levels: &[Vec<u8>],
        h: usize,
        cells: &[(i64, i64)],
        a: i64,
        b: i64,
    ) -> f32 {
        let level = &levels[h][..];
        let table = self.table.view();
        let mut q: u64 = 0;
        for &(i, j) in cells {
            q += u64::from(level[table.locate(i + a, j + b)]);
        }
        self.pooled_value(cells.len(), q)
    }

    /// The bound of `n` cells whose quantised values sum to `q`.
    #[inline]
    fn pooled_value(&self, n: usize, q: u64) -> f32 {
        let n = n as f64;
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

    /// The value of cell `(i, j)` (the floor where nothing is stored).
    #[inline]
    pub fn cell(&self, i: i64, j: i64) -> f32 {
        self.values[self.table.locate(i, j)]
    }

    /// [`LikelihoodField::cells_sum`] at `(a, b)`, `(a + d, b)`,
    /// `(a, b + d)` and `(a + d, b + d)` (`d > 0`), each summed as
    /// it would be alone, in one pass.
    #[inline]
    pub(crate) fn cells_sum4(&self, cells: &[(i64, i64)], a: i64, b: i64, d: i64) -> [f32; 4] {
        let values = &self.values[..];
        let mut s = [0f32; 4];
        corners(self.table.view(), cells, a, b, d, |k| {
            for (s, k) in s.iter_mut().zip(k) {
                *s += values[k];
            }
        });
        s
    }

    /// [`LikelihoodField::pooled_sum`] at `(a, b)`, `(a + d, b)`,
    /// `(a, b + d)` and `(a + d, b + d)` (`d > 0`), in one pass.
    #[inline]
    pub(crate) fn pooled_sum4(
        &self,
        levels: &[Vec<u8>],
        h: usize,
        cells: &[(i64, i64)],
        a: i64,
        b: i64,
        d: i64,
    ) -> [f32; 4] {
        let level = &levels[h][..];
        let mut q = [0u64; 4];
        corners(self.table.view(), cells, a, b, d, |k| {
            for (q, k) in q.iter_mut().zip(k) {
                *q += u64::from(level[k]);
            }
        });
        q.map(|q| self.pooled_value(cells.len(), q))
    }

    /// The values of `cells`, each moved by `(a, b)`, summed in `f32` in
    /// their order.
    #[inline]
    pub(crate) fn cells_sum(&self, cells: &[(i64, i64)], a: i64, b: i64) -> f32 {
        let (table, values) = (self.table.view(), &self.values[..]);
        let mut s = 0f32;
        for &(i, j) in cells {
            s += values[table.locate(i + a, j + b)];
        }
        s
    }

    /// Adds the values of the cells `(i, j)` to `(i + out.len() − 1, j)`
    /// to `out`, element by element, a tile's run at a time.
    pub(crate) fn add_row(&self, i: i64, j: i64, out: &mut [f32]) {
        let mut x = i;
        let mut rest = out;
        while !rest.is_empty() {
            let run = ((x | (TILE - 1)) - x + 1).min(rest.len() as i64) as usize;
            let start = self.table.locate(x, j);
            let (now, later) = rest.split_at_mut(run);
            now.iter_mut()
                .zip(&self.values[start..start + run])
                .for_each(|(v, f)| *v += f);
            rest = later;
            x += run as i64;
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
        if self.free[self.table.locate(i, j)] {
            self.epsilon_free
        } else {
            self.epsilon
        }
    }

    /// The value at `p`, its nearest obstacle point `d2` (squared) away.
    fn value(&self, p: Point2, d2: f64) -> f64 {
        (self.base_at(p) + (1.0 - self.epsilon) * (-d2 / self.two_sigma2).exp()).ln()
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

    /// Checks that the pooled level of `n` random blocks, starting within
    /// `xs × ys` (cells), is their largest value rounded up by less than a
    /// step; how many of them lie wholly below the floor (on seen floor).
    fn check_blocks(
        field: &LikelihoodField,
        rng: &mut impl rand::Rng,
        n: usize,
        xs: (i64, i64),
        ys: (i64, i64),
    ) -> usize {
        let step = (field.step + 1e-6) as f32;
        let mut below_floor = 0;
        for _ in 0..n {
            let h = rng.random_range(1..=POOLED_LEVELS);
            let (i, j) = (rng.random_range(xs.0..xs.1), rng.random_range(ys.0..ys.1));
            let side = 1i64 << h;
            let most = (j..j + side)
                .flat_map(|y| (i..i + side).map(move |x| (x, y)))
                .map(|(x, y)| field.cell(x, y))
                .fold(f32::NEG_INFINITY, f32::max);
            below_floor += usize::from(most < field.floor());
            let bound = field.pooled(h, i, j);
            assert!(
                bound >= most && bound <= most + step,
                "level {h} at ({i}, {j}): {bound} for {most}"
            );
        }
        below_floor
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
            check_blocks(field, &mut rng, 2000, (-300, 300), (-300, 200));
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

    /// A wall ring 40 m out, as a laser's far returns: only the tiles
    /// near it are stored, under a sixth of the box it spans, and the
    /// cells far from it read as the floor.
    #[test]
    fn only_tiles_near_points_are_stored() {
        let ring: Vec<Point2> = (0..25_000)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 25_000.0;
                Point2::new(40.01 * a.cos(), 40.01 * a.sin())
            })
            .collect();
        let mut f = LikelihoodField::from_points(&[], 0.05, 0.05, 0.2);
        for chunk in ring.chunks(700) {
            f.insert(chunk);
        }
        f.levels();
        let span = (2.0 * 40.0 / 0.05) as usize;
        let stored = f.level_cells();
        assert!(
            stored * 6 < span * span,
            "{stored} cells stored of {}",
            span * span
        );
        assert_eq!(f.cell(0, 0), f.floor());
        assert_eq!(f.cell(400, 400), f.floor());
        // On the wall, the exact value at the cell's centre.
        let on = f.exact(Point2::new(40.025, 0.025));
        assert!(on > -0.2 && (f.cell(800, 0) as f64 - on).abs() < 1e-6, "{on}");
        assert!(f.covers(Point2::new(40.0, 0.0)) && !f.covers(Point2::new(39.8, 0.0)));
    }

    /// The four corners' sums in one pass are the four sums taken alone,
    /// to the bit, across tile borders and beyond the stored tiles, read
    /// through the tiles or from a window copied out of them; the pooled
    /// bounds hold on a field with seen floor too.
    #[test]
    fn corner_sums_are_the_single_sums() {
        use pirouette_geom::Pose2;
        use pirouette_grid::{GridConfig, OccupancyGrid, FREE_THRESH};
        use pirouette_profile::Rop;
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut rop = Rop::covering(-1.5, 1.5, 0.5f64.to_radians(), 0.9).unwrap();
        rop.range_m.iter_mut().for_each(|r| *r = 0.7);
        let mut grid = OccupancyGrid::new(GridConfig::default()).unwrap();
        for _ in 0..5 {
            grid.insert_profile(&Pose2::IDENTITY, &rop, 0.1);
        }
        let pts: Vec<Point2> = (0..400)
            .map(|_| Point2::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)))
            .collect();
        let f = LikelihoodField::from_map(&pts, &grid, FREE_THRESH, 0.015, 0.2, 0.02);
        let levels = f.levels();
        // A window over every cell read below (and one a cell short).
        let window = f.window(levels, POOLED_LEVELS, ((-196, -196), (196, 196)));
        let short = f.window(levels, POOLED_LEVELS, ((-196, -196), (195, 196)));
        for _ in 0..300 {
            let cells: Vec<(i64, i64)> = (0..rng.random_range(1..200))
                .map(|_| (rng.random_range(-140..140i64), rng.random_range(-140..140i64)))
                .collect();
            let (a, b) = (rng.random_range(-40..40i64), rng.random_range(-40..40i64));
            let h = rng.random_range(0..=POOLED_LEVELS - 1);
            let d = 1i64 << h.max(1);
            let corners = [(a, b), (a + d, b), (a, b + d), (a + d, b + d)];
            let four = f.cells_sum4(&cells, a, b, d);
            assert!(window.holds(&cells, (a, a + d), (b, b + d)));
            let copied = window.cells_sum4(&cells, a, b, d);
            for (k, &(x, y)) in corners.iter().enumerate() {
                assert_eq!(four[k].to_bits(), f.cells_sum(&cells, x, y).to_bits());
                assert_eq!(copied[k].to_bits(), four[k].to_bits());
            }
            let right = cells.iter().map(|c| c.0).max().unwrap_or(0) + a + d;
            assert_eq!(short.holds(&cells, (a, a + d), (b, b + d)), right < 196);
            if h >= 1 {
                let four = f.pooled_sum4(levels, h, &cells, a, b, d);
                let copied = window.pooled_sum4(&f, h, &cells, a, b, d);
                for (k, &(x, y)) in corners.iter().enumerate() {
                    assert_eq!(four[k].to_bits(), f.pooled_sum(levels, h, &cells, x, y).to_bits());
                    assert_eq!(copied[k].to_bits(), four[k].to_bits());
                }
            }
        }
        // Blocks over seen floor, its edge and the points bound their cells.
        let free_blocks = check_blocks(&f, &mut rng, 3000, (-140, 140), (-140, 140));
        assert!(free_blocks > 100, "{free_blocks} blocks wholly on seen floor");
    }
}
