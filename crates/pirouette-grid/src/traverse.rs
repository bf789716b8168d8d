//! Exact grid traversal of a segment (Amanatides & Woo).

/// Calls `visit` for every cell of side `cell_m` (cell `(i, j)` covers
/// `[i·s, (i+1)·s) × [j·s, (j+1)·s)`) that the segment from `from` to `to`
/// passes through, in order from `from`'s cell to `to`'s, each once. The
/// cells form a 4-connected path: where the segment passes exactly through
/// a corner, one of the two side cells is taken. Non-finite endpoints or
/// cell size visit nothing.
pub fn traverse(from: [f64; 2], to: [f64; 2], cell_m: f64, mut visit: impl FnMut(i64, i64)) {
    if !(from.iter().chain(&to).all(|v| v.is_finite()) && cell_m.is_finite() && cell_m > 0.0) {
        return;
    }
    let cell = |v: f64| (v / cell_m).floor() as i64;
    let (mut cx, mut cy) = (cell(from[0]), cell(from[1]));
    let (ex, ey) = (cell(to[0]), cell(to[1]));
    let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
    let step_x: i64 = if dx > 0.0 { 1 } else { -1 };
    let step_y: i64 = if dy > 0.0 { 1 } else { -1 };
    // Ray parameter t ∈ [0, 1] at the next vertical / horizontal cell border.
    let next_border = |c: i64, step: i64, start: f64, d: f64| {
        if d == 0.0 {
            f64::INFINITY
        } else {
            let border = (c + (step > 0) as i64) as f64 * cell_m;
            (border - start) / d
        }
    };
    let mut t_max_x = next_border(cx, step_x, from[0], dx);
    let mut t_max_y = next_border(cy, step_y, from[1], dy);
    let t_delta_x = if dx == 0.0 {
        f64::INFINITY
    } else {
        cell_m / dx.abs()
    };
    let t_delta_y = if dy == 0.0 {
        f64::INFINITY
    } else {
        cell_m / dy.abs()
    };
    visit(cx, cy);
    // Exactly as many steps as the cells lie apart: the walk ends in `to`'s
    // cell whatever rounding does near the borders.
    let mut left_x = (ex - cx).abs();
    let mut left_y = (ey - cy).abs();
    while left_x + left_y > 0 {
        let go_x = left_y == 0 || (left_x > 0 && t_max_x < t_max_y);
        if go_x {
            cx += step_x;
            t_max_x += t_delta_x;
            left_x -= 1;
        } else {
            cy += step_y;
            t_max_y += t_delta_y;
            left_y -= 1;
        }
        visit(cx, cy);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::collections::BTreeSet;

    /// The oracle: cells met by densely sampled points of the segment.
    fn sampled(from: [f64; 2], to: [f64; 2], s: f64) -> BTreeSet<(i64, i64)> {
        let n = 20_000;
        (0..=n)
            .map(|k| {
                let t = k as f64 / n as f64;
                let (x, y) = (from[0] + t * (to[0] - from[0]), from[1] + t * (to[1] - from[1]));
                ((x / s).floor() as i64, (y / s).floor() as i64)
            })
            .collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 300, rng_seed: proptest::test_runner::RngSeed::Fixed(5), ..ProptestConfig::default() })]

        #[test]
        fn visits_exactly_the_cells_the_segment_crosses(
            x0 in -0.5f64..0.5, y0 in -0.5f64..0.5, x1 in -0.5f64..0.5, y1 in -0.5f64..0.5
        ) {
            let s = 0.013;
            let mut cells = Vec::new();
            traverse([x0, y0], [x1, y1], s, |i, j| cells.push((i, j)));
            let set: BTreeSet<_> = cells.iter().copied().collect();
            prop_assert_eq!(set.len(), cells.len(), "no cell twice");
            for w in cells.windows(2) {
                prop_assert_eq!((w[0].0 - w[1].0).abs() + (w[0].1 - w[1].1).abs(), 1, "4-connected");
            }
            let oracle = sampled([x0, y0], [x1, y1], s);
            // Dense sampling can only miss a corner's sliver of a cell: every
            // sampled cell is visited, and at most a few visited cells are
            // not sampled.
            prop_assert!(oracle.is_subset(&set), "gap: {:?}", oracle.difference(&set).collect::<Vec<_>>());
            prop_assert!(set.len() - oracle.len() <= 2, "extra cells {:?}", set.difference(&oracle).collect::<Vec<_>>());
        }
    }

    #[test]
    fn axis_aligned_and_single_cell_segments() {
        let mut cells = Vec::new();
        traverse([0.005, 0.005], [0.035, 0.005], 0.01, |i, j| cells.push((i, j)));
        assert_eq!(cells, [(0, 0), (1, 0), (2, 0), (3, 0)]);
        cells.clear();
        traverse([0.005, 0.005], [0.006, 0.007], 0.01, |i, j| cells.push((i, j)));
        assert_eq!(cells, [(0, 0)]);
        cells.clear();
        traverse([0.005, -0.005], [0.005, -0.025], 0.01, |i, j| cells.push((i, j)));
        assert_eq!(cells, [(0, -1), (0, -2), (0, -3)]);
        cells.clear();
        traverse([0.0, 0.0], [f64::NEG_INFINITY, f64::NAN], 0.01, |i, j| {
            cells.push((i, j))
        });
        assert!(cells.is_empty(), "non-finite input visits nothing");
    }
}
