//! The floor model and the column-wise state the boundary scan follows.
//!
//! Every column follows its own floor up from the bottom of the image, but
//! all columns move up one row at a time together: the floor tracks of all
//! columns are held column-wise ([`Lanes`]), so classifying a row and
//! following the floor are loops over columns without branches, which the
//! compiler vectorises. Only the few pixels that leave the floor are looked
//! at one by one.

// The loops over a block's lanes index several arrays in step; indices say
// that more plainly than zipped iterators.
#![allow(clippy::needless_range_loop)]

/// Decides whether a pixel is floor, given the floor colour predicted there.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Classifier {
    /// Noise threshold, 8-bit levels (a multiple of the image's σ).
    pub noise: f32,
    pub brightness_step: f32,
    pub chroma_step: f32,
}

pub(crate) const SQRT_3: f32 = 1.732_050_8;

impl Classifier {
    /// Floor when the brightness step and the chromaticity change, each
    /// relative to its own tolerance (widened to the noise), lie inside the
    /// unit ellipse: `(Δb/τ_b)² + max_c (Δc/τ_c)² ≤ 1`. A surface that
    /// differs a little in both brightness and hue is caught, while a
    /// larger change of brightness alone (shading, tonal patches) is not.
    ///
    /// Written without branches, so that a loop over columns vectorises.
    #[inline(always)]
    pub fn is_floor(&self, p: &[f32; 3], q: &[f32; 3]) -> bool {
        self.floor_mask(p, q) != 0
    }

    /// [`Classifier::is_floor`] as 1 or 0, computed without branches so
    /// that a loop over columns vectorises.
    #[inline(always)]
    pub fn floor_mask(&self, p: &[f32; 3], q: &[f32; 3]) -> u32 {
        self.masks(p, q, self).floor
    }

    /// [`Classifier::floor_mask`] and, sharing its work, two tests with
    /// tighter tolerances, each as 1 or 0: `close`, the same test with
    /// chromaticity tolerance `edge.chroma_step` (that of
    /// [`Classifier::scaled`]); `steady`, whether the brightness step also
    /// lies within `edge.brightness_step` (that of
    /// [`Classifier::scaled_both`]). The noise allowance is the same in all.
    #[inline(always)]
    pub fn masks(&self, p: &[f32; 3], q: &[f32; 3], edge: &Classifier) -> Masks {
        let sum_p = p[0] + p[1] + p[2];
        let sum_q = max0(q[0] + q[1] + q[2], 0.0);
        let db = sum_p - sum_q;
        let tb = max0(self.brightness_step * sum_q, self.noise * SQRT_3);
        let tb2 = tb * tb;
        let inside = (db * db <= tb2) as u32;
        let tb_edge = max0(edge.brightness_step * sum_q, self.noise * SQRT_3);
        let steady = (db * db <= tb_edge * tb_edge) as u32;
        // Room left inside the ellipse for the chromaticity term.
        let room = 1.0 - db * db / tb2;
        let b = if sum_q > 0.0 { sum_p / sum_q } else { 1.0 };
        let channel = |c: usize| {
            let expect = b * q[c];
            let e = p[c] - expect;
            let t = max0(self.chroma_step * expect, self.noise);
            let t_edge = max0(edge.chroma_step * expect, self.noise);
            (
                (e * e <= room * t * t) as u32,
                (e * e <= room * t_edge * t_edge) as u32,
            )
        };
        let (c0, c1, c2) = (channel(0), channel(1), channel(2));
        Masks {
            floor: inside & c0.0 & c1.0 & c2.0,
            close: inside & c0.1 & c1.1 & c2.1,
            steady,
        }
    }
}

/// The outcomes of [`Classifier::masks`], each 1 or 0.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Masks {
    /// Floor.
    pub floor: u32,
    /// Floor with the edge test's chromaticity tolerance.
    pub close: u32,
    /// The brightness step within the edge test's brightness tolerance.
    pub steady: u32,
}

impl Classifier {
    /// The same test with the chromaticity tolerance scaled by `fraction`
    /// (the brightness tolerance and the noise allowance stay).
    pub fn scaled(&self, fraction: f32) -> Self {
        Self {
            chroma_step: self.chroma_step * fraction,
            ..*self
        }
    }

    /// The same test with both the brightness and the chromaticity
    /// tolerances scaled by `fraction` (the noise allowance stays).
    pub fn scaled_both(&self, fraction: f32) -> Self {
        Self {
            brightness_step: self.brightness_step * fraction,
            chroma_step: self.chroma_step * fraction,
            ..*self
        }
    }
}

/// The larger of `a` and `b`, `b` when `a` is NaN: `f32::max` for the
/// values met here (`b` is never NaN), in a form that compiles to a single
/// vector instruction.
#[inline(always)]
fn max0(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// The floor's colour followed up a column: a level and a trend per row
/// (Holt's linear smoothing), so a floor that brightens steadily upwards
/// is predicted without lag.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FloorTrack {
    pub level: [f32; 3],
    pub trend: [f32; 3],
}

impl FloorTrack {
    /// A least-squares line through the seed rows (bottom first); the level
    /// is the line's value at the last (topmost) seed row.
    pub fn seed(rows: &[[f32; 3]]) -> Self {
        let k = rows.len() as f32;
        let mean_x = (k - 1.0) / 2.0;
        let var_x: f32 = (0..rows.len())
            .map(|i| (i as f32 - mean_x).powi(2))
            .sum::<f32>()
            .max(1e-6);
        let mut level = [0f32; 3];
        let mut trend = [0f32; 3];
        for c in 0..3 {
            let mean_y = rows.iter().map(|p| p[c]).sum::<f32>() / k;
            let cov: f32 = rows
                .iter()
                .enumerate()
                .map(|(i, p)| (i as f32 - mean_x) * (p[c] - mean_y))
                .sum();
            trend[c] = if rows.len() > 1 { cov / var_x } else { 0.0 };
            level[c] = mean_y + trend[c] * (k - 1.0 - mean_x);
        }
        Self { level, trend }
    }

    /// One row: takes in pixel `p` when it is `floor` (Holt's update of
    /// level and trend), otherwise coasts along the trend. The same
    /// arithmetic as the lock-step update.
    pub fn step(&mut self, p: &[f32; 3], floor: bool, rate: f32, trend_rate: f32) {
        for c in 0..3 {
            let pred = self.level[c] + self.trend[c];
            if floor {
                let taken = pred + rate * (p[c] - pred);
                self.trend[c] += trend_rate * (taken - self.level[c] - self.trend[c]);
                self.level[c] = taken;
            } else {
                self.level[c] = pred;
            }
        }
    }

    /// The floor colour expected at the next row up.
    pub fn predict(&self) -> [f32; 3] {
        std::array::from_fn(|c| self.level[c] + self.trend[c])
    }
}

/// The pixel at `(u, v)` averaged with its left and right neighbours.
#[inline(always)]
pub(crate) fn smoothed(px: &[u8], width: u32, u: u32, v: u32) -> [f32; 3] {
    let row = &px[(v * width) as usize * 3..((v + 1) * width) as usize * 3];
    let l = u.saturating_sub(1) as usize * 3;
    let c = u as usize * 3;
    let r = (u + 1).min(width - 1) as usize * 3;
    let (l, c, r) = (&row[l..l + 3], &row[c..c + 3], &row[r..r + 3]);
    let sum = |k: usize| (l[k] as u16 + c[k] as u16 + r[k] as u16) as f32 * (1.0 / 3.0);
    [sum(0), sum(1), sum(2)]
}

/// Columns per block of [`Lanes`]: eight `f32` fill one AVX register.
const BLOCK: usize = 8;

/// Eight columns' floor tracks and current pixels, one array per channel.
#[derive(Debug, Clone, Copy, Default)]
struct Block {
    level: [[f32; BLOCK]; 3],
    trend: [[f32; BLOCK]; 3],
    /// The current row, each pixel averaged with its left and right
    /// neighbours (as [`smoothed`]).
    pixel: [[f32; BLOCK]; 3],
    /// The floor colour the tracks predicted for the current row.
    predicted: [[f32; BLOCK]; 3],
    /// 1 where a column is still being scanned.
    alive: [u8; BLOCK],
    /// 1 where an alive column's pixel in the current row is not floor.
    off: [u8; BLOCK],
    /// 1 where the pixel of the row last classified was close to the floor
    /// (within the edge test's tolerances).
    close: [u8; BLOCK],
    /// 1 where an alive column's pixel is floor but, unlike the pixel below
    /// it, not close to it: a sharp step.
    edge: [u8; BLOCK],
    /// 1 where the pixel of the row last classified was close to the floor
    /// and its brightness steady (within the edge test's tolerances).
    steady: [u8; BLOCK],
    /// 1 where an alive column's pixel is close to the floor but, unlike the
    /// pixel below it, its brightness not steady: a sharp step of
    /// brightness alone.
    bright_edge: [u8; BLOCK],
    /// The tracks' trend before the current row's update.
    trend_before: [[f32; BLOCK]; 3],
    /// Rows found not floor so far, the current one included.
    off_rows: [u32; BLOCK],
}

/// The floor tracks of every column and the row they are looking at, in
/// blocks of eight columns held channel by channel, so that the loops over
/// a block's columns compile to vector instructions.
///
/// # Memory
/// About 59 bytes a column (20 KB for 320 columns), rebuilt per image.
#[derive(Debug, Clone)]
pub(crate) struct Lanes {
    width: usize,
    blocks: Vec<Block>,
    /// The current image row with each edge pixel repeated once outside
    /// it and zeros to fill the last block, as 8-bit RGB.
    row: Vec<u8>,
}

impl Lanes {
    pub fn new(width: usize) -> Self {
        let blocks = width.div_ceil(BLOCK);
        Self {
            width,
            blocks: vec![Block::default(); blocks],
            row: vec![0; (blocks * BLOCK + 2) * 3],
        }
    }

    /// Starts scanning column `u` from `track`.
    pub fn start(&mut self, u: usize, track: FloorTrack) {
        let (b, i) = (u / BLOCK, u % BLOCK);
        let block = &mut self.blocks[b];
        for c in 0..3 {
            block.level[c][i] = track.level[c];
            block.trend[c][i] = track.trend[c];
        }
        block.alive[i] = 1;
        // The seed below the first row scanned is floor.
        block.close[i] = 1;
        block.steady[i] = 1;
    }

    /// Stops scanning column `u`.
    pub fn stop(&mut self, u: usize) {
        self.blocks[u / BLOCK].alive[u % BLOCK] = 0;
    }

    pub fn is_alive(&self, u: usize) -> bool {
        self.blocks[u / BLOCK].alive[u % BLOCK] != 0
    }

    /// Rows of column `u` found not floor so far, the row last classified
    /// included.
    pub fn off_rows(&self, u: usize) -> u32 {
        self.blocks[u / BLOCK].off_rows[u % BLOCK]
    }

    /// Column `u`'s track as it would be after coasting over the row last
    /// classified (its prediction, with the trend it had before that row).
    pub fn coasted(&self, u: usize) -> FloorTrack {
        let (block, i) = (&self.blocks[u / BLOCK], u % BLOCK);
        FloorTrack {
            level: [
                block.predicted[0][i],
                block.predicted[1][i],
                block.predicted[2][i],
            ],
            trend: [
                block.trend_before[0][i],
                block.trend_before[1][i],
                block.trend_before[2][i],
            ],
        }
    }

    /// The floor colour column `u`'s track predicted for the row last
    /// classified.
    pub fn predicted(&self, u: usize) -> [f32; 3] {
        let (block, i) = (&self.blocks[u / BLOCK], u % BLOCK);
        [
            block.predicted[0][i],
            block.predicted[1][i],
            block.predicted[2][i],
        ]
    }

    /// The blocks holding columns `cols`.
    fn block_span(cols: &std::ops::Range<usize>) -> std::ops::Range<usize> {
        cols.start / BLOCK..cols.end.div_ceil(BLOCK)
    }

    /// Loads row `v` of the interleaved RGB image `px`, classifies it
    /// against each column's predicted floor and follows the floor, over
    /// the blocks holding `cols`: columns whose pixel is floor take it in
    /// (Holt's update of level and trend), the others coast along their
    /// trend. Afterwards [`Lanes::off_columns`] lists the alive columns
    /// whose pixel is not floor.
    pub fn step(
        &mut self,
        px: &[u8],
        v: usize,
        classifiers: (&Classifier, &Classifier),
        rates: (f32, f32),
        cols: std::ops::Range<usize>,
    ) {
        let m = self.width;
        let src = &px[v * m * 3..(v + 1) * m * 3];
        self.row[3..3 + m * 3].copy_from_slice(src);
        self.row.copy_within(3..6, 0);
        self.row.copy_within(m * 3..m * 3 + 3, m * 3 + 3);
        let span = Self::block_span(&cols);
        step_blocks(
            &mut self.blocks[span.clone()],
            &self.row[span.start * BLOCK * 3..],
            classifiers,
            rates,
        );
    }

    /// The columns in `cols` that [`Lanes::step`] found alive and not
    /// floor, left to right.
    pub fn off_columns(&self, cols: std::ops::Range<usize>) -> impl Iterator<Item = usize> + '_ {
        self.flagged(cols, |b| &b.off)
    }

    /// The columns in `cols` where [`Lanes::step`] found a sharp step that
    /// stays within the floor's tolerances, left to right.
    pub fn edge_columns(&self, cols: std::ops::Range<usize>) -> impl Iterator<Item = usize> + '_ {
        self.flagged(cols, |b| &b.edge)
    }

    /// The columns in `cols` where [`Lanes::step`] found a sharp step of
    /// brightness alone that stays within the edge test's chromaticity
    /// tolerance, left to right.
    pub fn bright_edge_columns(&self, cols: std::ops::Range<usize>) -> impl Iterator<Item = usize> + '_ {
        self.flagged(cols, |b| &b.bright_edge)
    }

    fn flagged(
        &self,
        cols: std::ops::Range<usize>,
        flags: impl Fn(&Block) -> &[u8; BLOCK] + Copy + 'static,
    ) -> impl Iterator<Item = usize> + '_ {
        let span = Self::block_span(&cols);
        let first = span.start;
        self.blocks[span]
            .iter()
            .enumerate()
            .filter(move |(_, b)| u64::from_ne_bytes(*flags(b)) != 0)
            .flat_map(move |(k, b)| {
                (0..BLOCK)
                    .filter(move |&i| flags(b)[i] != 0)
                    .map(move |i| (first + k) * BLOCK + i)
            })
    }
}

/// One row's step of the blocks (see [`Lanes::step`]); `row` is the padded
/// row from the blocks' first column on.
#[multiversion::multiversion(targets("x86_64+avx2", "x86_64+sse4.1", "aarch64+neon"))]
fn step_blocks(
    blocks: &mut [Block],
    row: &[u8],
    (classifier, edge_classifier): (&Classifier, &Classifier),
    (rate, trend_rate): (f32, f32),
) {
    for (block, bytes) in blocks
        .iter_mut()
        .zip(row.windows((BLOCK + 2) * 3).step_by(BLOCK * 3))
    {
        if u64::from_ne_bytes(block.alive) == 0 {
            block.off = [0; BLOCK];
            block.edge = [0; BLOCK];
            block.bright_edge = [0; BLOCK];
            continue;
        }
        for c in 0..3 {
            for i in 0..BLOCK {
                let sum = bytes[3 * i + c] as u16 + bytes[3 * i + 3 + c] as u16 + bytes[3 * i + 6 + c] as u16;
                block.pixel[c][i] = sum as f32 * (1.0 / 3.0);
                block.predicted[c][i] = block.level[c][i] + block.trend[c][i];
            }
        }
        let mut floor = [0u32; BLOCK];
        let mut close = [0u32; BLOCK];
        let mut steady = [0u32; BLOCK];
        for i in 0..BLOCK {
            let q = [
                block.predicted[0][i],
                block.predicted[1][i],
                block.predicted[2][i],
            ];
            let p = [block.pixel[0][i], block.pixel[1][i], block.pixel[2][i]];
            let masks = classifier.masks(&p, &q, edge_classifier);
            (floor[i], close[i], steady[i]) = (masks.floor, masks.close, masks.steady);
        }
        for i in 0..BLOCK {
            block.off[i] = (floor[i] == 0) as u8 & block.alive[i];
            block.off_rows[i] += block.off[i] as u32;
            block.edge[i] = (floor[i] as u8) & (close[i] == 0) as u8 & block.close[i] & block.alive[i];
            block.close[i] = close[i] as u8;
            let steady_close = (close[i] & steady[i]) as u8;
            block.bright_edge[i] =
                (close[i] as u8) & (steady[i] == 0) as u8 & block.steady[i] & block.alive[i];
            block.steady[i] = steady_close;
        }
        block.trend_before = block.trend;
        // Weights 1 (take the pixel in) or 0 (coast): the choice as
        // arithmetic, which gives the same values and vectorises.
        let take = floor.map(|f| f as f32);
        for c in 0..3 {
            for i in 0..BLOCK {
                let (level, trend) = (block.level[c][i], block.trend[c][i]);
                let pred = block.predicted[c][i];
                let taken = pred + (take[i] * rate) * (block.pixel[c][i] - pred);
                block.trend[c][i] = trend + (take[i] * trend_rate) * (taken - level - trend);
                block.level[c][i] = taken;
            }
        }
    }
}

/// A pixel that left the floor: the possible base of an obstacle, decided
/// once the rows an obstacle standing there would span (its run) have been
/// scanned. The floor track goes on through the run as if it were not an
/// obstacle, which is what the scan does if it is not.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Candidate {
    /// The candidate's row.
    pub row: u32,
    /// The top row of its run.
    pub lo: u32,
    /// The column's count of rows not floor below the candidate's row.
    pub off_before: u32,
    /// The floor colour predicted at the candidate's row.
    pub floor: [f32; 3],
    /// The floor track's change per row up the column there.
    pub trend: [f32; 3],
    /// A sharp step already found to be an obstacle's base (its run was
    /// followed when it was found); otherwise a pixel off the floor whose
    /// run the scan is following.
    pub edge: bool,
}

const NONE: u32 = u32::MAX;

#[derive(Debug, Clone, Copy)]
struct Node {
    candidate: Candidate,
    column: u32,
    /// The column's next candidate.
    next: u32,
    /// The next candidate whose run ends on the same row.
    next_due: u32,
    /// Rows of the run not floor, once the run is complete.
    off: Option<u32>,
}

/// The undecided candidates: per column a queue in scan order, per row the
/// candidates whose runs end there; linked lists through one arena, so
/// nothing is moved or allocated per candidate.
///
/// # Memory
/// 44 bytes a candidate (every pixel found not floor while its column is
/// scanned: a few thousand an image), 8 bytes a column and 4 a row.
#[derive(Debug, Clone)]
pub(crate) struct Candidates {
    nodes: Vec<Node>,
    head: Vec<u32>,
    tail: Vec<u32>,
    due: Vec<u32>,
}

impl Candidates {
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            nodes: Vec::with_capacity(4 * width),
            head: vec![NONE; width],
            tail: vec![NONE; width],
            due: vec![NONE; height],
        }
    }

    /// Queues `candidate` of column `u`.
    pub fn push(&mut self, u: usize, candidate: Candidate) {
        let id = self.nodes.len() as u32;
        let lo = candidate.lo as usize;
        self.nodes.push(Node {
            candidate,
            column: u as u32,
            next: NONE,
            next_due: self.due[lo],
            off: None,
        });
        self.due[lo] = id;
        match self.tail[u] {
            NONE => self.head[u] = id,
            t => self.nodes[t as usize].next = id,
        }
        self.tail[u] = id;
    }

    /// Marks the candidates whose runs end at `row` complete, with their
    /// counts of rows not floor from `off_rows` (per column, through
    /// `row`); `ready` becomes the columns where such a candidate is first
    /// in line.
    pub fn complete_row(&mut self, row: usize, off_rows: impl Fn(usize) -> u32, ready: &mut Vec<usize>) {
        ready.clear();
        let mut id = std::mem::replace(&mut self.due[row], NONE);
        while id != NONE {
            let node = &mut self.nodes[id as usize];
            let u = node.column as usize;
            node.off = Some(off_rows(u) - node.candidate.off_before);
            if self.head[u] == id {
                ready.push(u);
            }
            id = node.next_due;
        }
    }

    /// Column `u`'s first candidate and its count of rows not floor, when
    /// its run is complete.
    pub fn decidable(&self, u: usize) -> Option<(Candidate, u32)> {
        let node = self.nodes.get(self.head[u] as usize)?;
        Some((node.candidate, node.off?))
    }

    /// Drops column `u`'s first candidate.
    pub fn pop(&mut self, u: usize) {
        if let Some(node) = self.nodes.get(self.head[u] as usize) {
            self.head[u] = node.next;
            if self.head[u] == NONE {
                self.tail[u] = NONE;
            }
        }
    }

    /// Drops all of column `u`'s candidates.
    pub fn clear(&mut self, u: usize) {
        self.head[u] = NONE;
        self.tail[u] = NONE;
    }

    pub fn is_empty(&self, u: usize) -> bool {
        self.head[u] == NONE
    }
}
