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
        self.masks(p, q, self, self.brightness_step).floor
    }

    /// [`Classifier::floor_mask`] and, sharing its work, three tests with
    /// tighter tolerances, each as 1 or 0: `close`, the same test with
    /// chromaticity tolerance `edge.chroma_step` (that of
    /// [`Classifier::scaled`]); `steady`, whether the brightness step also
    /// lies within `edge.brightness_step` (that of
    /// [`Classifier::scaled_both`]); `faint_steady`, whether it lies within
    /// the relative brightness tolerance `faint_step`. The noise allowance
    /// is the same in all.
    #[inline(always)]
    pub fn masks(&self, p: &[f32; 3], q: &[f32; 3], edge: &Classifier, faint_step: f32) -> Masks {
        let sum_p = p[0] + p[1] + p[2];
        let sum_q = max0(q[0] + q[1] + q[2], 0.0);
        let db = sum_p - sum_q;
        let tb = max0(self.brightness_step * sum_q, self.noise * SQRT_3);
        let tb2 = tb * tb;
        let inside = (db * db <= tb2) as u32;
        let tb_edge = max0(edge.brightness_step * sum_q, self.noise * SQRT_3);
        let steady = (db * db <= tb_edge * tb_edge) as u32;
        let tb_faint = max0(faint_step * sum_q, self.noise * SQRT_3);
        let faint_steady = (db * db <= tb_faint * tb_faint) as u32;
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
            faint_steady,
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
    /// The brightness step within the faint step's tolerance.
    pub faint_steady: u32,
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
    /// level and trend), otherwise coasts along the trend while the trend
    /// fades by `trend_rate` (Holt's update of the trend with no change
    /// seen), so that coasting over many rows moves the level by at most
    /// `trend / trend_rate`. The same arithmetic as the lock-step update.
    pub fn step(&mut self, p: &[f32; 3], floor: bool, rate: f32, trend_rate: f32) {
        for c in 0..3 {
            let pred = self.level[c] + self.trend[c];
            if floor {
                let taken = pred + rate * (p[c] - pred);
                self.trend[c] += trend_rate * (taken - self.level[c] - self.trend[c]);
                self.level[c] = taken;
            } else {
                self.level[c] = pred;
                self.trend[c] += trend_rate * -self.trend[c];
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
    /// 1 where the pixel of the row last classified was close to the floor
    /// and its brightness within the faint step's tolerance.
    faint_steady: [u8; BLOCK],
    /// 1 where an alive column's pixel is close to the floor and its
    /// brightness steady, but, unlike the pixel below it, not within the
    /// faint step's tolerance: a faint sharp step of brightness alone.
    faint_edge: [u8; BLOCK],
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
/// About 70 bytes a column (22 KB for 320 columns), rebuilt per image.
#[derive(Debug, Clone)]
pub(crate) struct Lanes {
    width: usize,
    blocks: Vec<Block>,
    /// The current image row one channel after another, each pixel summed
    /// with its left and right neighbours (the edge pixels repeated once
    /// outside the row), zeros filling the last block: `3 × blocks × 8`.
    sums: Vec<u16>,
    /// The current row's channels one after another, the edge pixels
    /// repeated once either side: `3 × (width + 2)`.
    planar: Vec<u8>,
}

impl Lanes {
    pub fn new(width: usize) -> Self {
        let blocks = width.div_ceil(BLOCK);
        Self {
            width,
            blocks: vec![Block::default(); blocks],
            sums: vec![0; 3 * blocks * BLOCK],
            planar: vec![0; 3 * (width + 2)],
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
        block.faint_steady[i] = 1;
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
    /// classified (see [`FloorTrack::step`]): its prediction, with the
    /// trend it had before that row faded by `trend_rate`.
    pub fn coasted(&self, u: usize, trend_rate: f32) -> FloorTrack {
        let mut track = FloorTrack {
            level: self.predicted(u),
            trend: self.trend_before(u),
        };
        for t in &mut track.trend {
            *t += trend_rate * -*t;
        }
        track
    }

    /// Column `u`'s trend before the row last classified.
    pub fn trend_before(&self, u: usize) -> [f32; 3] {
        let (block, i) = (&self.blocks[u / BLOCK], u % BLOCK);
        [
            block.trend_before[0][i],
            block.trend_before[1][i],
            block.trend_before[2][i],
        ]
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
    /// whose pixel is not floor. `classifiers` are the floor test, the edge
    /// tests' (see [`Classifier::masks`]) and the faint step's relative
    /// brightness tolerance.
    pub fn step(
        &mut self,
        px: &[u8],
        v: usize,
        classifiers: (&Classifier, &Classifier, f32),
        rates: (f32, f32),
        cols: std::ops::Range<usize>,
    ) {
        let m = self.width;
        let span = Self::block_span(&cols);
        // The columns of the span's blocks that lie in the image.
        let used = span.start * BLOCK..(span.end * BLOCK).min(m);
        load_row(
            &px[v * m * 3..(v + 1) * m * 3],
            used.clone(),
            &mut self.planar,
            &mut self.sums,
        );
        step_blocks(
            &mut self.blocks[span.clone()],
            &self.sums,
            span.start,
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

    /// The columns in `cols` where [`Lanes::step`] found a faint sharp step
    /// of brightness alone (beyond the faint step's tolerance, within the
    /// edge test's), left to right.
    pub fn faint_edge_columns(&self, cols: std::ops::Range<usize>) -> impl Iterator<Item = usize> + '_ {
        self.flagged(cols, |b| &b.faint_edge)
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

/// Row `row` of an interleaved RGB image (one row of it), columns `cols`,
/// as the three-pixel sums [`Lanes::step`] classifies: the row split into
/// its channels (`planar`, see [`Lanes`]), then each pixel summed with its
/// neighbours into `sums`. Two passes of plain loops over contiguous
/// arrays, which vectorise; the former per-block gathers from the
/// interleaved row did not.
#[multiversion::multiversion(targets("x86_64+avx2", "x86_64+sse4.1", "aarch64+neon"))]
fn load_row(row: &[u8], cols: std::ops::Range<usize>, planar: &mut [u8], sums: &mut [u16]) {
    let m = row.len() / 3;
    let (stride, lanes) = (m + 2, sums.len() / 3);
    if cols.is_empty() {
        return;
    }
    // The pixels the sums of `cols` reach, edge pixels repeated.
    let (lo, hi) = (cols.start.saturating_sub(1), (cols.end + 1).min(m));
    let (red, rest) = planar.split_at_mut(stride);
    let (green, blue) = rest.split_at_mut(stride);
    split_channels(
        &row[lo * 3..hi * 3],
        &mut red[lo + 1..],
        &mut green[lo + 1..],
        &mut blue[lo + 1..],
    );
    let k = cols.len();
    for (c, channel) in [red, green, blue].into_iter().enumerate() {
        channel[0] = row[c];
        channel[m + 1] = row[3 * (m - 1) + c];
        let out = &mut sums[c * lanes + cols.start..c * lanes + cols.end];
        let (left, centre, right) = (
            &channel[cols.start..cols.start + k],
            &channel[cols.start + 1..cols.start + 1 + k],
            &channel[cols.start + 2..cols.start + 2 + k],
        );
        for u in 0..k {
            out[u] = left[u] as u16 + centre[u] as u16 + right[u] as u16;
        }
    }
}

/// Interleaved RGB pixels `src` into the starts of three channels. A
/// function of its own whose outputs are arguments, so the compiler knows
/// they do not overlap, and slices of exactly the loop's length indexed
/// from 0: the form it turns into byte shuffles.
#[multiversion::multiversion(targets("x86_64+avx2", "x86_64+sse4.1", "aarch64+neon"))]
fn split_channels(src: &[u8], red: &mut [u8], green: &mut [u8], blue: &mut [u8]) {
    let n = src.len() / 3;
    let (red, green, blue) = (&mut red[..n], &mut green[..n], &mut blue[..n]);
    for i in 0..n {
        red[i] = src[3 * i];
        green[i] = src[3 * i + 1];
        blue[i] = src[3 * i + 2];
    }
}

/// One row's step of the blocks (see [`Lanes::step`]); `sums` holds the
/// row's three-pixel sums of every column, channel after channel (see
/// [`Lanes`]), and `first` is the first block's index among all.
#[multiversion::multiversion(targets("x86_64+avx2", "x86_64+sse4.1", "aarch64+neon"))]
fn step_blocks(
    blocks: &mut [Block],
    sums: &[u16],
    first: usize,
    (classifier, edge_classifier, faint_step): (&Classifier, &Classifier, f32),
    (rate, trend_rate): (f32, f32),
) {
    let lanes = sums.len() / 3;
    for (k, block) in blocks.iter_mut().enumerate() {
        if u64::from_ne_bytes(block.alive) == 0 {
            block.off = [0; BLOCK];
            block.edge = [0; BLOCK];
            block.bright_edge = [0; BLOCK];
            block.faint_edge = [0; BLOCK];
            continue;
        }
        let base = (first + k) * BLOCK;
        // The row's pixels, each averaged with its left and right
        // neighbours (as [`smoothed`]).
        let mut pixel = [[0f32; BLOCK]; 3];
        for c in 0..3 {
            #[allow(clippy::expect_used, reason = "the sums hold whole blocks per channel")]
            let sum: &[u16; BLOCK] = sums[c * lanes + base..c * lanes + base + BLOCK]
                .try_into()
                .expect("a whole block");
            for i in 0..BLOCK {
                pixel[c][i] = sum[i] as f32 * (1.0 / 3.0);
                block.predicted[c][i] = block.level[c][i] + block.trend[c][i];
            }
        }
        let mut floor = [0u32; BLOCK];
        let mut close = [0u32; BLOCK];
        let mut steady = [0u32; BLOCK];
        let mut faint_steady = [0u32; BLOCK];
        for i in 0..BLOCK {
            let q = [
                block.predicted[0][i],
                block.predicted[1][i],
                block.predicted[2][i],
            ];
            let p = [pixel[0][i], pixel[1][i], pixel[2][i]];
            let masks = classifier.masks(&p, &q, edge_classifier, faint_step);
            (floor[i], close[i], steady[i], faint_steady[i]) =
                (masks.floor, masks.close, masks.steady, masks.faint_steady);
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
        // (A loop of its own: in the one above, the compiler leaves the
        // flags scalar.)
        for i in 0..BLOCK {
            let faint_close = (close[i] & faint_steady[i]) as u8;
            block.faint_edge[i] =
                block.steady[i] & (faint_close == 0) as u8 & block.faint_steady[i] & block.alive[i];
            block.faint_steady[i] = faint_close;
        }
        block.trend_before = block.trend;
        // Weights 1 (take the pixel in) or 0 (coast, the trend fading):
        // the choice as arithmetic, which gives the same values as
        // `FloorTrack::step` and vectorises.
        let take = floor.map(|f| f as f32);
        for c in 0..3 {
            for i in 0..BLOCK {
                let (level, trend) = (block.level[c][i], block.trend[c][i]);
                let pred = block.predicted[c][i];
                let taken = pred + (take[i] * rate) * (pixel[c][i] - pred);
                block.trend[c][i] = trend + trend_rate * (take[i] * (taken - level) - trend);
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
            // Room for the few thousand candidates of a typical image
            // (about ten a column), so that the arena seldom grows: each
            // growth copies every node.
            nodes: Vec::with_capacity(16 * width),
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

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Coasting n rows from level `l` with trend `t` reaches
    /// `l + t (1 - (1 - r)^n) / r`: never more than `t / r` from `l`.
    /// Taking a pixel in is Holt's update.
    #[test]
    fn coasting_fades_the_trend_and_taking_in_is_holts_update() {
        let (r, rate) = (0.1f32, 0.25f32);
        let mut track = FloorTrack {
            level: [100.0, 50.0, 10.0],
            trend: [2.0, -1.0, 0.0],
        };
        for _ in 0..40 {
            track.step(&[0.0; 3], false, rate, r);
        }
        for c in 0..3 {
            let (l, t) = ([100.0f64, 50.0, 10.0][c], [2.0f64, -1.0, 0.0][c]);
            let want = l + t * (1.0 - 0.9f64.powi(40)) / 0.1;
            assert!(
                (track.level[c] as f64 - want).abs() < 1e-3,
                "{c}: {} {want}",
                track.level[c]
            );
            assert!((track.trend[c] as f64 - t * 0.9f64.powi(40)).abs() < 1e-5);
            assert!((track.level[c] as f64 - l).abs() <= t.abs() / 0.1);
        }
        let mut t = FloorTrack {
            level: [100.0; 3],
            trend: [2.0; 3],
        };
        t.step(&[110.0; 3], true, rate, r);
        // Predicted 102, taken 102 + 0.25 × 8 = 104, trend 2 + 0.1 × (4 - 2).
        assert_eq!((t.level[0], t.trend[0]), (104.0, 2.2));
    }

    /// The lock-step lanes coast and take pixels in with exactly the
    /// arithmetic of [`FloorTrack::step`], and [`Lanes::coasted`] is the
    /// track coasted over the row.
    #[test]
    fn lanes_step_as_floor_tracks_do() {
        let classifier = Classifier {
            noise: 3.0,
            brightness_step: 0.18,
            chroma_step: 0.05,
        };
        let edge = classifier.scaled_both(0.5);
        let (rate, trend_rate) = (0.25, 0.1);
        let track = FloorTrack {
            level: [100.0, 93.0, 85.0],
            trend: [1.5, 1.25, -0.5],
        };
        // Column 0 sees floor, column 1 a bright speck.
        let row: Vec<u8> = [[101u8, 95, 85], [101, 95, 85], [240, 240, 240], [240, 240, 240]].concat();
        let mut lanes = Lanes::new(4);
        lanes.start(0, track);
        lanes.start(2, track);
        lanes.step(&row, 0, (&classifier, &edge, 0.06), (rate, trend_rate), 0..4);
        assert_eq!(lanes.off_columns(0..4).collect::<Vec<_>>(), [2]);
        for (u, floor) in [(0, true), (2, false)] {
            let p = smoothed(&row, 4, u as u32, 0);
            let mut want = track;
            want.step(&p, floor, rate, trend_rate);
            let block = &lanes.blocks[0];
            let got = FloorTrack {
                level: std::array::from_fn(|c| block.level[c][u]),
                trend: std::array::from_fn(|c| block.trend[c][u]),
            };
            assert_eq!((got.level, got.trend), (want.level, want.trend), "column {u}");
            assert_eq!(lanes.trend_before(u), track.trend);
            let mut coasted = track;
            coasted.step(&p, false, rate, trend_rate);
            let c = lanes.coasted(u, trend_rate);
            assert_eq!((c.level, c.trend), (coasted.level, coasted.trend), "column {u}");
        }
    }

    #[test]
    fn loaded_rows_are_the_smoothed_pixels() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        // Widths that fill whole blocks, leave a partial one, or fit in one.
        for width in [3usize, 8, 13, 64, 77] {
            let px: Vec<u8> = (0..width * 3).map(|_| rng.random()).collect();
            let blocks = width.div_ceil(BLOCK);
            let mut planar = vec![0u8; 3 * (width + 2)];
            let mut sums = vec![0u16; 3 * blocks * BLOCK];
            for _ in 0..10 {
                let a = rng.random_range(0..width);
                let b = rng.random_range(a + 1..=width);
                sums.fill(0);
                load_row(&px, a..b, &mut planar, &mut sums);
                for u in 0..blocks * BLOCK {
                    for c in 0..3 {
                        let got = sums[c * blocks * BLOCK + u];
                        if (a..b).contains(&u) {
                            let want = smoothed(&px, width as u32, u as u32, 0)[c] * 3.0;
                            assert_eq!(got as f32, want.round(), "width {width}, column {u}");
                        } else {
                            assert_eq!(got, 0, "width {width}: column {u} outside {a}..{b} written");
                        }
                    }
                }
            }
        }
    }
}
