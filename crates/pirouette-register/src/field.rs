//! The likelihood field of a map: how well a point explains an obstacle.

use crate::floor_i64;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use pirouette_geom::Point2;
use pirouette_grid::OccupancyGrid;

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
/// exhaustive search ([`LikelihoodField::cell`]), and the exact value from
/// the nearest obstacle point ([`LikelihoodField::exact`], a k-d tree
/// query) for refinement below one cell, where interpolating the lattice
/// would flatten the peak of a wall lying between two cell centres.
///
/// # Memory
/// Five bytes per cell of the map's extent (plus a border of `3σ`), and
/// the k-d tree of the points (about 20 bytes each: coordinates and an
/// index).
#[derive(Debug, Clone)]
pub struct LikelihoodField {
    /// `None` without points.
    tree: Option<ImmutableKdTree<f64, 2>>,
    /// The points of the tree, by its item index.
    coords: Vec<[f64; 2]>,
    epsilon: f64,
    epsilon_free: f64,
    two_sigma2: f64,
    resolution_m: f64,
    /// Cell index of storage element 0.
    min_cell: (i64, i64),
    width: usize,
    height: usize,
    values: Vec<f32>,
    /// Cells the map has seen free.
    free: Vec<bool>,
    floor: f32,
    occupied: usize,
}

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
        let floor = epsilon.ln() as f32;
        // Beyond 3σ the Gaussian adds less than 1.2 % to the floor.
        let reach = (3.0 * sigma_m / resolution_m).ceil() as i64 + 1;
        let cell = |p: &Point2| (floor_i64(p.x / resolution_m), floor_i64(p.y / resolution_m));
        // Points that can reach the region.
        let near_region = |p: &Point2| {
            region.is_none_or(|(lo, hi)| {
                let (i, j) = cell(p);
                i >= lo.0 - reach && i <= hi.0 + reach && j >= lo.1 - reach && j <= hi.1 + reach
            })
        };
        let points: Vec<Point2> = points
            .iter()
            .copied()
            .filter(|p| p.x.is_finite() && p.y.is_finite() && near_region(p))
            .collect();
        // Built once and only queried: the immutable tree, balanced at
        // construction, answers faster.
        let coords: Vec<[f64; 2]> = points.iter().map(|p| [p.x, p.y]).collect();
        let tree = (!coords.is_empty()).then(|| ImmutableKdTree::new_from_slice(&coords));
        let mut field = Self {
            tree,
            coords,
            epsilon,
            epsilon_free,
            two_sigma2: 2.0 * sigma_m * sigma_m,
            resolution_m,
            min_cell: (0, 0),
            width: 0,
            height: 0,
            values: Vec::new(),
            free: Vec::new(),
            floor,
            occupied: 0,
        };
        let Some((min_cell, max_cell)) = lattice_extent(&points, free_space, region, reach, &cell) else {
            return field;
        };
        field.min_cell = min_cell;
        field.width = (max_cell.0 - min_cell.0 + 1) as usize;
        field.height = (max_cell.1 - min_cell.1 + 1) as usize;
        let d2 = field.nearest_squared(&points, reach, &cell);
        field.free = vec![false; field.width * field.height];
        if let Some((grid, threshold)) = free_space {
            let reaching = grid.log_odds_reaching(threshold);
            let (width, free) = (field.width, &mut field.free);
            for (k, f) in free.iter_mut().enumerate() {
                let (i, j) = (min_cell.0 + (k % width) as i64, min_cell.1 + (k / width) as i64);
                *f = grid.log_odds(i, j) < reaching;
            }
        }
        // Most cells lie beyond every point's reach, where the value is
        // the base's logarithm alone.
        let (ln_eps, ln_eps_free) = (epsilon.ln() as f32, epsilon_free.ln() as f32);
        let two_sigma2 = field.two_sigma2;
        field.values = d2
            .into_iter()
            .zip(&field.free)
            .map(|(d, &f)| match (d.is_infinite(), f) {
                (true, true) => ln_eps_free,
                (true, false) => ln_eps,
                (false, _) => {
                    let base = if f { epsilon_free } else { epsilon };
                    (base + (1.0 - epsilon) * (-d / two_sigma2).exp()).ln() as f32
                }
            })
            .collect();
        field.occupied = points.len();
        field
    }

    /// Squared distance from each cell centre of the lattice to the nearest
    /// of `points`, exact within `reach` cells (infinite beyond): every
    /// point stamps its neighbourhood (as far as the lattice goes).
    fn nearest_squared(
        &self,
        points: &[Point2],
        reach: i64,
        cell: &impl Fn(&Point2) -> (i64, i64),
    ) -> Vec<f64> {
        let (min_cell, width, height, resolution_m) =
            (self.min_cell, self.width, self.height, self.resolution_m);
        let mut d2 = vec![f64::INFINITY; width * height];
        // A point's squared offsets across the columns it reaches, shared by
        // all its rows.
        let mut dx2 = Vec::with_capacity(2 * reach as usize + 1);
        for p in points {
            let (i, j) = cell(p);
            let (ci, cj) = (i - min_cell.0, j - min_cell.1);
            let (i_lo, i_hi) = ((ci - reach).max(0), (ci + reach).min(width as i64 - 1));
            let (j_lo, j_hi) = ((cj - reach).max(0), (cj + reach).min(height as i64 - 1));
            if i_lo > i_hi {
                continue;
            }
            dx2.clear();
            dx2.extend((i_lo..=i_hi).map(|x| {
                let ddx = ((min_cell.0 + x) as f64 + 0.5) * resolution_m - p.x;
                ddx * ddx
            }));
            for y in j_lo..=j_hi {
                let ddy = ((min_cell.1 + y) as f64 + 0.5) * resolution_m - p.y;
                let dy2 = ddy * ddy;
                let row = y as usize * width;
                for (d, &dx2) in d2[row + i_lo as usize..=row + i_hi as usize].iter_mut().zip(&dx2) {
                    *d = d.min(dx2 + dy2);
                }
            }
        }
        d2
    }

    /// Cell side, metres.
    pub fn resolution_m(&self) -> f64 {
        self.resolution_m
    }

    /// How many obstacle points the field was made of.
    pub fn obstacle_points(&self) -> usize {
        self.occupied
    }

    /// The log-likelihood of an endpoint far from every mapped obstacle.
    pub fn floor(&self) -> f32 {
        self.floor
    }

    /// The value of cell `(i, j)` (the floor outside the stored extent).
    pub fn cell(&self, i: i64, j: i64) -> f32 {
        let (x, y) = (i - self.min_cell.0, j - self.min_cell.1);
        if x >= 0 && y >= 0 && (x as usize) < self.width && (y as usize) < self.height {
            self.values[y as usize * self.width + x as usize]
        } else {
            self.floor
        }
    }

    /// The distance from a map point to the nearest obstacle point,
    /// metres (`None` without points).
    pub fn nearest_distance_m(&self, p: Point2) -> Option<f64> {
        let tree = self.tree.as_ref()?;
        Some(tree.nearest_one::<SquaredEuclidean>(&[p.x, p.y]).distance.sqrt())
    }

    /// The exact value at a map point, from its nearest obstacle point.
    pub fn exact(&self, p: Point2) -> f64 {
        let Some(tree) = &self.tree else {
            return self.base_at(p).ln();
        };
        let d2 = tree.nearest_one::<SquaredEuclidean>(&[p.x, p.y]).distance;
        self.value(p, d2)
    }

    /// [`LikelihoodField::exact`] at `p`, which lies within the reach of
    /// `near`'s endpoint `k` (see [`Neighbourhood`]): its nearest obstacle
    /// point is among the endpoint's candidates, the same point the tree
    /// would find, at the same distance to the bit.
    pub(crate) fn exact_near(&self, near: &Neighbourhood, k: usize, p: Point2) -> f64 {
        let candidates = &near.candidates[near.offsets[k] as usize..near.offsets[k + 1] as usize];
        if candidates.is_empty() {
            return self.exact(p);
        }
        let d2 = candidates
            .iter()
            .map(|c| (p.x - c[0]) * (p.x - c[0]) + (p.y - c[1]) * (p.y - c[1]))
            .fold(f64::INFINITY, f64::min);
        self.value(p, d2)
    }

    /// The obstacle points that can be nearest to any point within
    /// `reach_m` of each of `starts`: all within `d₀ + 2·reach` of a start
    /// whose own nearest lies `d₀` away (the nearest to a point `q` lies
    /// within `d(q) + |q − start| ≤ d₀ + 2·reach` of the start).
    pub(crate) fn neighbourhood(&self, starts: &[Point2], reach_m: f64) -> Neighbourhood {
        let mut offsets = Vec::with_capacity(starts.len() + 1);
        let mut candidates = Vec::new();
        offsets.push(0u32);
        for p in starts {
            if let Some(tree) = &self.tree {
                let q = [p.x, p.y];
                let d0 = tree.nearest_one::<SquaredEuclidean>(&q).distance.sqrt();
                // A hair wider against rounding: a point too many costs
                // nothing, a point missed would change the value.
                let radius = (d0 + 2.0 * reach_m) * (1.0 + 1e-9) + 1e-12;
                if radius.is_finite() {
                    for n in tree.within_unsorted::<SquaredEuclidean>(&q, radius * radius) {
                        candidates.push(self.coords[n.item as usize]);
                    }
                }
            }
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
        let (i, j) = (
            floor_i64(p.x / self.resolution_m) - self.min_cell.0,
            floor_i64(p.y / self.resolution_m) - self.min_cell.1,
        );
        let inside = i >= 0 && j >= 0 && (i as usize) < self.width && (j as usize) < self.height;
        if inside && self.free[j as usize * self.width + i as usize] {
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

/// The cells a field's lattice covers: the points with the Gaussian's
/// `reach` about each, and the free-space grid's stored cells, cut to
/// `region` where one is given; `None` where nothing is left.
fn lattice_extent(
    points: &[Point2],
    free_space: Option<(&OccupancyGrid, f64)>,
    region: Option<((i64, i64), (i64, i64))>,
    reach: i64,
    cell: &impl Fn(&Point2) -> (i64, i64),
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

    #[test]
    fn an_empty_map_is_all_floor() {
        let f = LikelihoodField::from_points(&[], 0.01, 0.02, 0.1);
        assert!((f.exact(Point2::new(0.3, 0.2)) - f.floor() as f64).abs() < 1e-6);
    }
}
