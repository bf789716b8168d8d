//! Branch-and-bound over the registration lattice: every lattice pose whose
//! posterior score lies within a set margin of the best, found without
//! scoring the rest.
//!
//! A block of `2ʰ × 2ʰ` translations at one rotation scores at most the sum,
//! over the endpoints, of the field's largest value in the block each
//! endpoint sweeps (bounded by the field's pooled level `h`,
//! [`LikelihoodField::pooled`]), plus the prior's largest value
//! over the block. A block whose bound falls below the best score found so
//! far less the margin cannot hold a pose the posterior keeps, and is
//! dropped whole; the others split into four, best first, down to single
//! poses (the depth-first search of Olson's multi-resolution matcher and
//! Cartographer's fast correlative matcher, with the bound widened by the
//! margin so that the posterior's mass is found as well as its peak).
//!
//! Scores are summed in the exhaustive search's order with its arithmetic,
//! so a pose found here scores bit for bit what the exhaustive lattice
//! gives it, and a bound sums larger values in the same order, which
//! rounding cannot invert.

use crate::field::{LikelihoodField, Window};
use pirouette_geom::wrap_angle;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

/// The coarsest level a search starts from: blocks of `2⁶ = 64` cells a
/// side (the field's coarsest pooled level). Wider windows start from
/// several blocks.
pub(crate) const TOP_LEVEL: usize = crate::field::POOLED_LEVELS;

/// A field's pooled levels as a search looks them up.
pub(crate) struct Pyramid<'f> {
    pub field: &'f LikelihoodField,
    /// The field's pooled levels ([`LikelihoodField::levels`]).
    pub levels: &'f [Vec<u8>],
    /// The coarsest level a search starts from.
    pub top: usize,
    /// The field and its levels `1..=top` copied out of their tiles over
    /// the cells the search reads, where it reads each many times; a
    /// rotation whose reads it does not hold reads the tiles.
    pub window: Option<Window>,
}

impl Pyramid<'_> {
    /// The sums over `cells`, each moved by `(a, b)`, `(a + d, b)`,
    /// `(a, b + d)` and `(a + d, b + d)`, of level `h`'s bound of the
    /// block of side `2ʰ` from there, in one pass over the cells; at
    /// `h = 0`, of the cells' values in the order given (the exhaustive
    /// search's order: its rounding). From `window` where given (which
    /// holds every cell read).
    #[inline]
    fn sum4(
        &self,
        window: Option<&Window>,
        h: usize,
        cells: &[(i64, i64)],
        a: i64,
        b: i64,
        d: i64,
    ) -> [f32; 4] {
        match (window, h) {
            (Some(w), 0) => w.cells_sum4(cells, a, b, d),
            (Some(w), _) => w.pooled_sum4(self.field, h, cells, a, b, d),
            (None, 0) => self.field.cells_sum4(cells, a, b, d),
            (None, _) => self.field.pooled_sum4(self.levels, h, cells, a, b, d),
        }
    }
}

/// The lattice a search covers: translations `a·res`, `b·res` about the
/// prior's mean (`|a| ≤ nx`, `|b| ≤ ny`) at one rotation.
pub(crate) struct Block {
    /// Translation steps covered.
    pub nx: i64,
    /// Translation steps covered.
    pub ny: i64,
}

/// The prior's log density over a rotation's translations: the exact
/// value per lattice pose, and its largest value over a box.
pub(crate) trait PriorTerm {
    /// `ln p` of the lattice pose `(a, b)` of this rotation, computed as
    /// the exhaustive search computes it.
    fn at(&self, a: i64, b: i64) -> f64;
    /// At least the largest `ln p` over the translations
    /// `[a0, a1] × [b0, b1]` of this rotation.
    fn at_most(&self, a0: i64, a1: i64, b0: i64, b1: i64) -> f64;
}

/// The Gaussian prior `−½ (forward²/σf² + left²/σl² + dθ²/σθ²)` at one
/// rotation, on a lattice of `res` about its mean.
pub(crate) struct GaussianTerm<F: Fn(i64, i64) -> f64> {
    /// The exact value of a lattice pose.
    pub exact: F,
    /// `dθ²/σθ²` of this rotation.
    pub theta_term: f64,
    /// The quadratic form `A dx² + 2B dx dy + C dy²` of the translation
    /// part, in world offsets from the mean.
    pub form: (f64, f64, f64),
    /// Lattice step, metres.
    pub res: f64,
}

impl GaussianTerm<fn(i64, i64) -> f64> {
    /// The quadratic form of a prior with spreads `sigma_forward_m`,
    /// `sigma_left_m` about a mean heading with `(sin, cos)` = `turned`.
    pub(crate) fn form(turned: (f64, f64), sigma_forward_m: f64, sigma_left_m: f64) -> (f64, f64, f64) {
        let (s, c) = turned;
        let (f, l) = (sigma_forward_m.powi(-2), sigma_left_m.powi(-2));
        (c * c * f + s * s * l, c * s * (f - l), s * s * f + c * c * l)
    }

    /// `dθ²/σθ²` of rotation `theta` about the mean heading.
    pub(crate) fn theta_term(theta: f64, mean_theta: f64, sigma_theta_rad: f64) -> f64 {
        (wrap_angle(theta - mean_theta) / sigma_theta_rad).powi(2)
    }
}

/// Slack on every bound: the bounds are computed in other floating-point
/// steps than the scores, which may differ by a few units in the last
/// place.
const BOUND_SLACK: f64 = 1e-6;

impl<F: Fn(i64, i64) -> f64> PriorTerm for GaussianTerm<F> {
    fn at(&self, a: i64, b: i64) -> f64 {
        (self.exact)(a, b)
    }

    fn at_most(&self, a0: i64, a1: i64, b0: i64, b1: i64) -> f64 {
        let q = min_quadratic_on_box(
            self.form,
            (a0 as f64 * self.res, a1 as f64 * self.res),
            (b0 as f64 * self.res, b1 as f64 * self.res),
        );
        -0.5 * (q + self.theta_term)
    }
}

/// The least value of the convex form `A x² + 2B xy + C y²` (`A, C > 0`,
/// `AC ≥ B²`) over the box `[x0, x1] × [y0, y1]`: zero when the box holds
/// the origin, else the least over its four edges, each a convex parabola
/// whose minimum is clamped to the edge.
pub(crate) fn min_quadratic_on_box(
    (a, b, c): (f64, f64, f64),
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
) -> f64 {
    if x0 <= 0.0 && 0.0 <= x1 && y0 <= 0.0 && 0.0 <= y1 {
        return 0.0;
    }
    let q = |x: f64, y: f64| a * x * x + 2.0 * b * x * y + c * y * y;
    let on_x = |x: f64| q(x, (-b * x / c).clamp(y0, y1));
    let on_y = |y: f64| q((-b * y / a).clamp(x0, x1), y);
    on_x(x0).min(on_x(x1)).min(on_y(y0)).min(on_y(y1)).max(0.0)
}

/// The best score found so far by any rotation's search, shared between
/// threads (an `f64` in its bits; only ever raised).
pub(crate) struct SharedBest(AtomicU64);

impl SharedBest {
    pub(crate) fn new() -> Self {
        Self(AtomicU64::new(f64::NEG_INFINITY.to_bits()))
    }

    /// A best already known, `score`.
    pub(crate) fn at(score: f64) -> Self {
        Self(AtomicU64::new(score.to_bits()))
    }

    pub(crate) fn get(&self) -> f64 {
        f64::from_bits(self.0.load(Ordering::Relaxed))
    }

    fn raise(&self, score: f64) {
        let _ = self.0.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |bits| {
            (score > f64::from_bits(bits)).then_some(score.to_bits())
        });
    }
}

/// A lattice pose kept by the search: its translation steps and score.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Kept {
    pub a: i64,
    pub b: i64,
    pub score: f64,
}

/// Translations `[a0, a1] × [b0, b1]` of one rotation left out of a
/// search (the best answer's own neighbourhood, when rivals are sought).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Excluded {
    pub a: (i64, i64),
    pub b: (i64, i64),
}

impl Excluded {
    /// Whether translation `(a, b)` lies inside.
    pub(crate) fn contains(&self, a: i64, b: i64) -> bool {
        self.holds(a, a, b, b)
    }

    /// Whether the box `[a0, a1] × [b0, b1]` lies wholly inside.
    fn holds(&self, a0: i64, a1: i64, b0: i64, b1: i64) -> bool {
        self.a.0 <= a0 && a1 <= self.a.1 && self.b.0 <= b0 && b1 <= self.b.1
    }
}

/// A block of translations `2ʰ` a side from `(a, b)` at one rotation,
/// with its bound: `(a, b, h, bound)`; at `h = 0`, one pose and its score.
pub(crate) type Node = (i64, i64, usize, f64);

/// One rotation's branch-and-bound search: the endpoint `cells` at that
/// rotation read from `pyramid` over the translations of `block`, scored
/// with `prior`, keeping every translation at least the best score any
/// search sharing `best` finds plus `margin_ln` (zero or negative);
/// translations `excluded` are neither scored nor kept; `nodes` counts
/// the blocks and poses scored.
pub(crate) struct RotationSearch<'a, P: PriorTerm> {
    pub pyramid: &'a Pyramid<'a>,
    pub cells: &'a [(i64, i64)],
    pub block: Block,
    pub prior: P,
    pub best: &'a SharedBest,
    pub margin_ln: f64,
    pub excluded: Option<Excluded>,
    pub nodes: &'a AtomicUsize,
}

impl<P: PriorTerm> RotationSearch<'_, P> {
    /// The translations kept, unsorted: among them surely all that reach
    /// the final best plus the margin. With `pruned = (keep_ln, out)`,
    /// every block dropped whose bound was at least the best then plus
    /// `keep_ln` (below the margin) goes to `out`: with the poses kept,
    /// they cover every pose that may score that much, from which
    /// [`RotationSearch::resume`] searches with a wider margin.
    pub(crate) fn search(&self, pruned: Option<(f64, &mut Vec<Node>)>) -> Vec<Kept> {
        let (pyramid, block) = (self.pyramid, &self.block);
        let top = pyramid.top;
        let step = 1i64 << top;
        let window = self.window();
        // The top blocks tile the lattice; the most promising is searched
        // first.
        let mut stack: Vec<Node> = Vec::new();
        // Two rows of top blocks at a time, two by two in one pass over
        // the cells; pushed row by row.
        let mut rows: [Vec<(i64, f32)>; 2] = [Vec::new(), Vec::new()];
        for b0 in (-block.ny..=block.ny).step_by(2 * step as usize) {
            rows.iter_mut().for_each(Vec::clear);
            for a0 in (-block.nx..=block.nx).step_by(2 * step as usize) {
                let sums = pyramid.sum4(window, top, self.cells, a0, b0, step);
                rows[0].extend([(a0, sums[0]), (a0 + step, sums[1])]);
                rows[1].extend([(a0, sums[2]), (a0 + step, sums[3])]);
            }
            for (r, row) in rows.iter().enumerate() {
                let b = b0 + r as i64 * step;
                for &(a, sum) in row {
                    if a <= block.nx && b <= block.ny && !self.left_out(a, b, top) {
                        stack.push((a, b, top, self.bound_of(sum, a, b, top)));
                    }
                }
            }
        }
        self.nodes.fetch_add(stack.len(), Ordering::Relaxed);
        self.run(window, stack, pruned)
    }

    /// [`RotationSearch::search`] from the blocks and poses `from` (what
    /// a search of the same rotation, cells and prior with a narrower
    /// margin dropped and kept, its `pruned`), without scoring them
    /// again: the same translations found, as those blocks cover every
    /// pose that may score at least the best plus the margin.
    pub(crate) fn resume(&self, from: &[Node]) -> Vec<Kept> {
        let floor = self.best.get() + self.margin_ln;
        let stack: Vec<Node> = (from.iter().copied())
            .filter(|&(a, b, h, v)| v >= floor && !self.left_out(a, b, h))
            .collect();
        if stack.is_empty() {
            return Vec::new();
        }
        self.run(self.window(), stack, None)
    }

    /// The bound of the block of side `2ʰ` from `(a0, b0)` whose field
    /// sum is `sum`, clipped to the lattice; at `h = 0` the pose's exact
    /// score.
    fn bound_of(&self, sum: f32, a0: i64, b0: i64, h: usize) -> f64 {
        let (sum, block) = (sum as f64, &self.block);
        if h == 0 {
            sum + self.prior.at(a0, b0)
        } else {
            let last = (1i64 << h) - 1;
            sum + self
                .prior
                .at_most(a0, (a0 + last).min(block.nx), b0, (b0 + last).min(block.ny))
                + BOUND_SLACK
        }
    }

    /// Whether the block of side `2ʰ` from `(a0, b0)` lies wholly in the
    /// excluded box.
    fn left_out(&self, a0: i64, b0: i64, h: usize) -> bool {
        let (last, block) = ((1i64 << h) - 1, &self.block);
        (self.excluded).is_some_and(|e| e.holds(a0, (a0 + last).min(block.nx), b0, (b0 + last).min(block.ny)))
    }

    /// The pyramid's window where it holds every cell this search reads:
    /// block origins run over `[-nx, nx + step]` (the top blocks, two by
    /// two), and a block's children lie within it.
    fn window(&self) -> Option<&Window> {
        let (step, block) = (1i64 << self.pyramid.top, &self.block);
        (self.pyramid.window.as_ref()).filter(|w| {
            w.holds(
                self.cells,
                (-block.nx, block.nx + 2 * step),
                (-block.ny, block.ny + 2 * step),
            )
        })
    }

    /// Searches `stack` (any order) depth first, the most promising block
    /// first, reading from `window` where given; see
    /// [`RotationSearch::search`].
    fn run(
        &self,
        window: Option<&Window>,
        mut stack: Vec<Node>,
        mut pruned: Option<(f64, &mut Vec<Node>)>,
    ) -> Vec<Kept> {
        let (block, best, margin_ln) = (&self.block, self.best, self.margin_ln);
        let mut set_aside = |node: Node| {
            if let Some((keep_ln, out)) = pruned.as_mut() {
                if node.3 >= best.get() + *keep_ln {
                    out.push(node);
                }
            }
        };
        let mut kept = Vec::new();
        let mut scored = 0;
        stack.sort_by(|x, y| x.3.total_cmp(&y.3));
        let mut children = Vec::with_capacity(4);
        while let Some(node) = stack.pop() {
            let (a0, b0, h, value) = node;
            if value < best.get() + margin_ln {
                set_aside(node);
                continue;
            }
            if h == 0 {
                best.raise(value);
                kept.push(Kept {
                    a: a0,
                    b: b0,
                    score: value,
                });
                continue;
            }
            let half = 1i64 << (h - 1);
            children.clear();
            // The four children's sums in one pass over the cells.
            let sums = self.pyramid.sum4(window, h - 1, self.cells, a0, b0, half);
            for ((da, db), sum) in [(0, 0), (half, 0), (0, half), (half, half)].into_iter().zip(sums) {
                let (a, b) = (a0 + da, b0 + db);
                if a <= block.nx && b <= block.ny && !self.left_out(a, b, h - 1) {
                    scored += 1;
                    let child = (a, b, h - 1, self.bound_of(sum, a, b, h - 1));
                    if child.3 >= best.get() + margin_ln {
                        children.push(child);
                    } else {
                        set_aside(child);
                    }
                }
            }
            // The most promising child last, so that it is searched first.
            children.sort_by(|x, y| x.3.total_cmp(&y.3));
            stack.extend_from_slice(&children);
        }
        self.nodes.fetch_add(scored, Ordering::Relaxed);
        kept
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn the_least_of_a_form_over_a_box_is_the_brute_force_least() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut cases = 0;
        for _ in 0..300 {
            let theta: f64 = rng.random_range(-3.2..3.2);
            let form = GaussianTerm::form(
                theta.sin_cos(),
                rng.random_range(0.01..0.5),
                rng.random_range(0.01..0.5),
            );
            let x0: f64 = rng.random_range(-1.0..1.0);
            let y0: f64 = rng.random_range(-1.0..1.0);
            let (x1, y1) = (x0 + rng.random_range(0.0..0.6), y0 + rng.random_range(0.0..0.6));
            let least = min_quadratic_on_box(form, (x0, x1), (y0, y1));
            let (a, b, c) = form;
            let q = |x: f64, y: f64| a * x * x + 2.0 * b * x * y + c * y * y;
            // A sampled least, zoomed in seven times about its place.
            let (mut lo, mut hi) = ((x0, y0), (x1, y1));
            let (mut brute, mut at) = (f64::INFINITY, lo);
            for _ in 0..8 {
                let n = 60;
                for u in 0..=n {
                    for v in 0..=n {
                        let x = lo.0 + (hi.0 - lo.0) * u as f64 / n as f64;
                        let y = lo.1 + (hi.1 - lo.1) * v as f64 / n as f64;
                        if q(x, y) < brute {
                            brute = q(x, y);
                            at = (x, y);
                        }
                    }
                }
                let (dx, dy) = (2.0 * (hi.0 - lo.0) / n as f64, 2.0 * (hi.1 - lo.1) / n as f64);
                lo = ((at.0 - dx).max(x0), (at.1 - dy).max(y0));
                hi = ((at.0 + dx).min(x1), (at.1 + dy).min(y1));
            }
            // Never above any sampled value, and as low as the samples go.
            assert!(least <= brute * (1.0 + 1e-12) + 1e-12, "{least} > {brute}");
            assert!(least >= brute * (1.0 - 1e-6) - 1e-9, "{least} < {brute}");
            cases += 1;
        }
        assert_eq!(cases, 300);
    }
}
