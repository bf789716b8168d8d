//! Symmetric block-sparse normal equations on faer's sparse Cholesky: the
//! pattern and its symbolic factorisation are made once, then each solve
//! only refills the values.

use crate::GraphError;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Mat, Side};
use std::collections::HashMap;

/// The lower triangle of a symmetric matrix of `n × n` blocks of side `B`,
/// compressed by columns, with a fixed pattern: the diagonal blocks and
/// the off-diagonal blocks named when it was made.
///
/// # Memory
/// `8·B²` bytes per stored block for the values, about as much again for
/// the row indices, and the Cholesky factor's fill-in (which the symbolic
/// factorisation's ordering keeps small on pose graphs).
pub(crate) struct BlockSystem<const B: usize> {
    blocks: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// Position of off-diagonal block `(row, col)` (`row > col`) among its
    /// block column's off-diagonal blocks.
    offdiag: HashMap<(usize, usize), usize>,
    values: Vec<f64>,
    symbolic: SymbolicLlt<usize>,
}

/// Where one block's entries live in [`BlockSystem`]'s values.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BlockAt {
    row: usize,
    col: usize,
    /// Index among the block column's off-diagonal blocks (unused on the
    /// diagonal).
    k: usize,
}

impl<const B: usize> BlockSystem<B> {
    /// The system of `blocks` diagonal blocks and the off-diagonal blocks
    /// `pairs` (either order; repeats and diagonal pairs are fine).
    pub(crate) fn new(
        blocks: usize,
        pairs: impl IntoIterator<Item = (usize, usize)>,
    ) -> Result<Self, GraphError> {
        let mut below: Vec<Vec<usize>> = vec![Vec::new(); blocks];
        for (a, b) in pairs {
            if a != b {
                below[a.min(b)].push(a.max(b));
            }
        }
        let mut offdiag = HashMap::new();
        for (col, rows) in below.iter_mut().enumerate() {
            rows.sort_unstable();
            rows.dedup();
            for (k, &row) in rows.iter().enumerate() {
                offdiag.insert((row, col), k);
            }
        }
        let n = blocks * B;
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for (bc, rows) in below.iter().enumerate() {
            for k in 0..B {
                row_idx.extend((k..B).map(|a| bc * B + a));
                for &br in rows {
                    row_idx.extend((0..B).map(|a| br * B + a));
                }
                col_ptr.push(row_idx.len());
            }
        }
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
        let symbolic = SymbolicLlt::try_new(pattern, Side::Lower).map_err(|e| GraphError::Solver {
            problem: format!("symbolic factorisation: {e:?}"),
        })?;
        let values = vec![0.0; row_idx.len()];
        Ok(Self {
            blocks,
            col_ptr,
            row_idx,
            offdiag,
            values,
            symbolic,
        })
    }

    /// The unknowns: blocks times `B`.
    pub(crate) fn dim(&self) -> usize {
        self.blocks * B
    }

    /// Where block `(row, col)` lives (`None` where the pattern has no such
    /// block).
    pub(crate) fn at(&self, row: usize, col: usize) -> Option<BlockAt> {
        let (row, col) = (row.max(col), row.min(col));
        if row == col {
            return (row < self.blocks).then_some(BlockAt { row, col, k: 0 });
        }
        self.offdiag.get(&(row, col)).map(|&k| BlockAt { row, col, k })
    }

    /// Zeroes every value.
    pub(crate) fn clear(&mut self) {
        self.values.iter_mut().for_each(|v| *v = 0.0);
    }

    fn position(&self, at: BlockAt, a: usize, k: usize) -> usize {
        let base = self.col_ptr[at.col * B + k];
        if at.row == at.col {
            base + (a - k)
        } else {
            base + (B - k) + at.k * B + a
        }
    }

    /// Adds `block`, the matrix's block at `(r, c)` as laid out where `at`
    /// was asked for (`block[a][k]` is row `a`, column `k` of block
    /// `(r, c)`). On the diagonal only its lower triangle is read; above
    /// it, the block is added transposed below.
    pub(crate) fn add(&mut self, at: BlockAt, asked: (usize, usize), block: &[[f64; B]; B]) {
        let transposed = asked.0 < asked.1;
        for k in 0..B {
            for a in 0..B {
                if at.row == at.col && a < k {
                    continue;
                }
                let v = if transposed { block[k][a] } else { block[a][k] };
                let p = self.position(at, a, k);
                self.values[p] += v;
            }
        }
    }

    /// Adds `lambda` to every diagonal entry.
    pub(crate) fn add_to_diagonal(&mut self, lambda: f64) {
        for b in 0..self.blocks {
            let at = BlockAt { row: b, col: b, k: 0 };
            for k in 0..B {
                let p = self.position(at, k, k);
                self.values[p] += lambda;
            }
        }
    }

    /// The diagonal entries.
    pub(crate) fn diagonal(&self) -> Vec<f64> {
        (0..self.dim())
            .map(|c| {
                self.values[self.position(
                    BlockAt {
                        row: c / B,
                        col: c / B,
                        k: 0,
                    },
                    c % B,
                    c % B,
                )]
            })
            .collect()
    }

    /// The Cholesky factor of the current values, with the pattern's
    /// symbolic factorisation.
    pub(crate) fn factor(&self) -> Result<Factor, GraphError> {
        let n = self.dim();
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let matrix = SparseColMatRef::new(pattern, &self.values);
        Llt::try_new_with_symbolic(self.symbolic.clone(), matrix, Side::Lower)
            .map(Factor)
            .map_err(|e| GraphError::Solver {
                problem: format!(
                    "the system is not positive definite ({e:?}): is every pose tied to the held one?"
                ),
            })
    }
}

/// A Cholesky factor of a [`BlockSystem`].
pub(crate) struct Factor(Llt<usize, f64>);

impl Factor {
    /// Solves the system for the columns of `rhs` (`dim × m`, column-major)
    /// in place.
    pub(crate) fn solve(&self, rhs: &mut Mat<f64>) {
        self.0.solve_in_place(rhs.as_mut());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A block tridiagonal matrix assembled block by block solves as its
    /// dense twin does.
    #[test]
    fn assembled_blocks_solve_like_the_dense_matrix() {
        const N: usize = 5;
        let pairs: Vec<(usize, usize)> = (0..N - 1).map(|i| (i + 1, i)).chain([(0, 4)]).collect();
        let mut sys = BlockSystem::<3>::new(N, pairs.iter().copied()).unwrap();
        let mut dense = vec![[0.0f64; 15]; 15];
        // Diagonal blocks: diagonally dominant; off-diagonal: small.
        for b in 0..N {
            let mut block = [[0.0; 3]; 3];
            for a in 0..3 {
                for k in 0..3 {
                    block[a][k] = if a == k {
                        10.0 + b as f64
                    } else {
                        0.5 + 0.1 * (a + k) as f64
                    };
                }
            }
            sys.add(sys.at(b, b).unwrap(), (b, b), &block);
            for a in 0..3 {
                for k in 0..3 {
                    dense[3 * b + a][3 * b + k] += block[a][k];
                }
            }
        }
        for (n, &(r, c)) in pairs.iter().enumerate() {
            // Given as (c, r) for the last pair: above the diagonal.
            let asked = if n == pairs.len() - 1 { (c, r) } else { (r, c) };
            let mut block = [[0.0; 3]; 3];
            for a in 0..3 {
                for k in 0..3 {
                    block[a][k] = 0.3 * (a as f64 - k as f64) + 0.05 * n as f64;
                }
            }
            sys.add(sys.at(asked.0, asked.1).unwrap(), asked, &block);
            for a in 0..3 {
                for k in 0..3 {
                    dense[3 * asked.0 + a][3 * asked.1 + k] += block[a][k];
                    dense[3 * asked.1 + k][3 * asked.0 + a] += block[a][k];
                }
            }
        }
        let b: Vec<f64> = (0..15).map(|i| (i as f64 * 0.7).sin()).collect();
        let mut x = Mat::from_fn(15, 1, |i, _| b[i]);
        sys.factor().unwrap().solve(&mut x);
        for i in 0..15 {
            let row: f64 = (0..15).map(|j| dense[i][j] * x[(j, 0)]).sum();
            assert!((row - b[i]).abs() < 1e-12, "row {i}: {row} against {}", b[i]);
        }
        assert!(sys.at(1, 3).is_none());
        assert_eq!(sys.diagonal()[4], 11.0);
    }
}
