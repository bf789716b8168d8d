//! A field's lattice copied out of its tiles, row-major over the box of
//! cells a wide branch and bound reads: each read is then an offset into
//! one array, without the tile table's lookup between it and the value.

use super::{LikelihoodField, Rect, TILE};

/// A field's values and its pooled levels `1..=top`, row-major over the
/// cells `lo..=hi`, bit for bit as the field holds them.
#[derive(Debug)]
pub(crate) struct Window {
    lo: (i64, i64),
    hi: (i64, i64),
    width: usize,
    values: Vec<f32>,
    /// Index `h` holds level `h` (`1..=top`); index 0 is empty.
    levels: Vec<Vec<u8>>,
}

impl LikelihoodField {
    /// The window of the cells `lo..=hi` (non-empty) over the field's
    /// values and `levels` (its pooled levels, [`LikelihoodField::levels`])
    /// `1..=top`: `4 + top` bytes a cell.
    pub(crate) fn window(&self, levels: &[Vec<u8>], top: usize, (lo, hi): Rect) -> Window {
        let width = (hi.0 - lo.0 + 1) as usize;
        let cells = width * (hi.1 - lo.1 + 1) as usize;
        let mut values = Vec::with_capacity(cells);
        let mut copied: Vec<Vec<u8>> = (0..=top)
            .map(|h| {
                if h == 0 {
                    Vec::new()
                } else {
                    Vec::with_capacity(cells)
                }
            })
            .collect();
        for j in lo.1..=hi.1 {
            // A row a tile's run at a time.
            let mut x = lo.0;
            while x <= hi.0 {
                let run = ((x | (TILE - 1)) - x + 1).min(hi.0 - x + 1) as usize;
                let start = self.table.locate(x, j);
                values.extend_from_slice(&self.values[start..start + run]);
                for (to, from) in copied.iter_mut().zip(levels).skip(1) {
                    to.extend_from_slice(&from[start..start + run]);
                }
                x += run as i64;
            }
        }
        Window {
            lo,
            hi,
            width,
            values,
            levels: copied,
        }
    }
}

impl Window {
    /// Whether every one of `cells`, moved by any `(a, b)` in
    /// `a.0..=a.1` × `b.0..=b.1`, lies inside.
    pub(crate) fn holds(&self, cells: &[(i64, i64)], a: (i64, i64), b: (i64, i64)) -> bool {
        let (mut lo, mut hi) = ((i64::MAX, i64::MAX), (i64::MIN, i64::MIN));
        for &(i, j) in cells {
            lo = (lo.0.min(i), lo.1.min(j));
            hi = (hi.0.max(i), hi.1.max(j));
        }
        cells.is_empty()
            || (lo.0 + a.0 >= self.lo.0
                && lo.1 + b.0 >= self.lo.1
                && hi.0 + a.1 <= self.hi.0
                && hi.1 + b.1 <= self.hi.1)
    }

    /// Where cell `(i, j)` (inside) is held.
    #[inline(always)]
    fn index(&self, i: i64, j: i64) -> usize {
        (j - self.lo.1) as usize * self.width + (i - self.lo.0) as usize
    }

    /// [`LikelihoodField::cells_sum4`], for cells that, moved by `(a, b)`
    /// and by `d` more, stay inside ([`Window::holds`]): the same sums
    /// in the same order, so bit for bit the same.
    #[inline]
    pub(crate) fn cells_sum4(&self, cells: &[(i64, i64)], a: i64, b: i64, d: i64) -> [f32; 4] {
        let (du, values) = (d as usize, &self.values[..]);
        let up = du * self.width;
        let mut s = [0f32; 4];
        for &(i, j) in cells {
            let k = self.index(i + a, j + b);
            s[0] += values[k];
            s[1] += values[k + du];
            s[2] += values[k + up];
            s[3] += values[k + up + du];
        }
        s
    }

    /// [`LikelihoodField::pooled_sum4`] of `field` (whose window this is)
    /// at level `h` (`1..=top`), for cells that stay inside.
    #[inline]
    pub(crate) fn pooled_sum4(
        &self,
        field: &LikelihoodField,
        h: usize,
        cells: &[(i64, i64)],
        a: i64,
        b: i64,
        d: i64,
    ) -> [f32; 4] {
        let (du, level) = (d as usize, &self.levels[h][..]);
        let up = du * self.width;
        let mut q = [0u64; 4];
        for &(i, j) in cells {
            let k = self.index(i + a, j + b);
            q[0] += u64::from(level[k]);
            q[1] += u64::from(level[k + du]);
            q[2] += u64::from(level[k + up]);
            q[3] += u64::from(level[k + up + du]);
        }
        q.map(|q| field.pooled_value(cells.len(), q))
    }
}
