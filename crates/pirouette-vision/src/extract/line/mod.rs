//! The line cue: the base of a smooth surface on a grained floor, found
//! where the floor's grain ends along a line many columns long.
//!
//! A light wall over a floor of its own brightness and nearly its hue
//! differs from the floor in its grain alone, and without a step at its
//! base the column-wise cues have nothing to start from. One column
//! measures grain too noisily to tell a wall from the floor's own smoother
//! patches, but a straight base is a straight line in the image, so the
//! grain (the spread of the texture cue's band-pass, beyond what the
//! sensor noise gives it) is pooled along lines of a few slopes over
//! `2·line_columns + 1` columns. A candidate base is one where
//!
//! - the floor below it is grained over its first 4 rows, its first 12
//!   and the 12 after (grain that fades with distance, a grained strip
//!   under a smooth patch near the camera, or the rim of a flat bright
//!   speck on a smooth floor is not a base);
//! - the surface above it, over as many rows as an obstacle of the least
//!   height spans there, is smooth: its grain within about two standard
//!   errors of the noise's own;
//! - the ratio of the two is at most `texture_ratio`.
//!
//! Under dim light the floor's grain near the soft limit stands barely
//! above the noise and rarely ends clearly enough; there a wall's base
//! also steps in brightness, a step the column-wise texture test cannot
//! judge when both sides are as smooth as the noise. Where the mean grey
//! of the rows just above and just below a candidate, pooled along the
//! line, differs by at least the faint step (a third of the brightness
//! tolerance), floor grain as strong as the noise is enough, the surface
//! above is judged over at least as many rows as the texture cue
//! compares, and the ratio allowed is the texture cue's own for the step:
//! `texture_ratio` at a full step, `faint_texture_ratio` at a faint one. A
//! shade on the floor steps as much but keeps the grain above.
//!
//! A base is a line (see [`chain`]): the candidates of neighbouring
//! columns, chained row to row across short gaps and the columns the scan
//! settled, must hold at least the pooled window. Within a column the base
//! is put where the brightness steps most, or without a step where the
//! whole spread, noise included, falls most.
//!
//! Only columns whose scan found no base within the soft range limit are
//! searched, and only the rows the scan took for floor, so the cue can
//! only bring a column's boundary nearer. The grain is sampled every other
//! column.

mod chain;

use super::decide::mean_of;
use super::texture::{band_pass, band_pass_noise, TEXTURE_HALF};
use super::RopExtractor;
use crate::scan::smoothed;
use crate::ColumnBoundary;
use chain::{lines, on_the_line, Run};
use pirouette_profile::ColourTag;

/// Rows of floor below a candidate base whose grain is pooled.
const FLOOR_ROWS: i32 = 12;

/// Rows just below a candidate base that must carry the floor's grain too.
const STEP_ROWS: i32 = 4;

/// The fewest rows above a candidate base (a wall near the image's top
/// shows only a few).
const MIN_ABOVE_ROWS: i32 = 3;

/// The most rows above a candidate base that are pooled: an obstacle of the
/// least height near the camera spans more, and its lowest rows are enough
/// to tell it from the floor.
const MAX_ABOVE_ROWS: i32 = 64;

/// Slopes of the lines tried, rows per column: a base seen across the
/// image at up to about 30° from the image rows. Neighbours differ by a
/// quarter of a row a column: a line between two is met within a row at
/// the window's ends, well within the bands of rows compared.
const SLOPES: [f32; 5] = [-0.5, -0.25, 0.0, 0.25, 0.5];

/// How far the floor's grain below a candidate base must stand above the
/// noise's part of the band-pass (beyond it, as a multiple of it): a floor
/// whose grain the noise hides, smooth at the band-pass's scale, has no
/// grain to end at a wall's base.
const GRAIN_OVER_NOISE: f32 = 1.5;

/// How far the floor's grain below a candidate base must stand above the
/// noise's part where a step of brightness runs along the line there too:
/// as much as the noise's own. Such grain doubles the band-pass's
/// variance, several standard errors of a variance pooled over the
/// window's samples and 6 rows (each about a fifth of the noise's).
const STEP_GRAIN_OVER_NOISE: f32 = 1.0;

/// The fewest rows above a candidate base that are pooled where a step of
/// brightness stands in for strong grain: as many as the texture cue
/// compares.
const TALL_ROWS: i32 = 6;

/// The most grain beyond the noise, as a multiple of the noise's part,
/// that a smooth surface above a candidate base may show: a spread at most
/// 1.22 times the noise's, about two standard errors of a spread measured
/// over the fewest rows above.
const SMOOTH_OVER_NOISE: f32 = 0.7;

/// The standard deviation of the error of rounding to 8-bit levels.
const QUANTISATION_SIGMA: f32 = 0.29;

/// The most a base's row may change from one column to the next.
const MAX_ROW_STEP: i32 = 2;

/// The share of a pooled band's pixels that must lie in the image and
/// carry a band-pass value.
const MIN_COVER: f32 = 0.75;

/// A band-pass value beyond this many standard deviations of its noise
/// is clipped to it: a speck of lint counts as strong grain, not as all of
/// a window's.
const CLIP_SIGMAS: f32 = 3.0;

/// Image columns per sample of the grain: neighbouring columns share two
/// of the three pixels of the band-pass's narrow mean, so every other one
/// says nearly all that both do, at half the cost.
const STRIDE: usize = 2;

/// Per sample of rows `r0..height`, the fields pooled along lines: the
/// signed band-pass of the grey level (clipped), its square, the variance
/// noise alone gives it there, and whether it exists (columns within
/// `TEXTURE_HALF` of the image's sides have none); and the grey level,
/// read along a line only where a candidate needs it.
struct Grain {
    r0: i32,
    rows: i32,
    width: usize,
    /// Column-major (a sample's rows in turn), the fields of a sample
    /// together.
    fields: Vec<[f32; FIELDS]>,
    /// As `fields`, the band-pass's wide mean (a sum of the three
    /// channels), 0 where there is none.
    level: Vec<f32>,
}

/// Fields of [`Grain`].
const FIELDS: usize = 4;

impl Grain {
    /// The relative horizontal band-pass (a three-column mean against a
    /// `2·TEXTURE_HALF + 1`-column one, as the texture cue's) of every
    /// pixel in rows `r0..height`, and the variance grey noise of
    /// standard deviation `grey_sigma` gives it.
    fn of(px: &[u8], width: u32, height: u32, r0: u32, grey_sigma: f32) -> Self {
        let half = TEXTURE_HALF as usize;
        let rows = (height - r0) as usize;
        // Samples at every STRIDE-th image column.
        let m = (width as usize).div_ceil(STRIDE);
        let mut fields = vec![[0f32; FIELDS]; rows * m];
        let mut level = vec![0f32; rows * m];
        let mut prefix = vec![0u32; width as usize + 1];
        for (k, v) in (r0..height).enumerate() {
            let row = &px[(v * width) as usize * 3..((v + 1) * width) as usize * 3];
            for (u, p) in row.chunks_exact(3).enumerate() {
                prefix[u + 1] = prefix[u] + p[0] as u32 + p[1] as u32 + p[2] as u32;
            }
            for u in (half..(width as usize).saturating_sub(half)).filter(|u| u % STRIDE == 0) {
                let (pass, wide) = band_pass(&prefix, u);
                if wide > 0.0 {
                    let i = u / STRIDE * rows + k;
                    let noise = band_pass_noise(grey_sigma, wide);
                    let e = (pass / wide).clamp(-CLIP_SIGMAS * noise, CLIP_SIGMAS * noise);
                    fields[i] = [e, e * e, noise * noise, 1.0];
                    level[i] = wide;
                }
            }
        }
        Self {
            r0: r0 as i32,
            rows: rows as i32,
            width: m,
            fields,
            level,
        }
    }

    /// Takes sample `u`'s column of rows into `window` by `op` (or lets it
    /// go), its first row at `window[at]`.
    fn shift_in(&self, window: &mut [[f32; FIELDS]], u: usize, at: usize, op: Op) {
        let n = self.rows as usize;
        for (w, x) in window[at..at + n]
            .iter_mut()
            .zip(&self.fields[u * n..(u + 1) * n])
        {
            *w = op(*w, *x);
        }
    }
}

/// Sums of the band-pass along the lines of one slope: for every sheared
/// row `v'` and centre sample `c`, the sum over samples `c − h ..= c + h`
/// of those at rows `v' + shift(u)`, prefix-summed down `v'`, so that a
/// band of rows along a line is two look-ups.
struct Sheared {
    /// `round(slope · (u − width/2))` per sampled column `u`.
    shift: Vec<i32>,
    /// The first sheared row held.
    lo: i32,
    rows: i32,
    /// The image rows held, as [`Grain`]'s.
    image_rows: std::ops::Range<i32>,
    /// Column-major (`rows + 1` per centre), the prefix sums down the
    /// sheared rows of the window sums of [`Grain`]'s fields: for each
    /// centre, only over the sheared rows of its own image rows.
    sums: Vec<[f32; FIELDS]>,
}

/// How a window takes a sample in or lets it go.
type Op = fn([f32; FIELDS], [f32; FIELDS]) -> [f32; FIELDS];

fn add(a: [f32; FIELDS], b: [f32; FIELDS]) -> [f32; FIELDS] {
    std::array::from_fn(|i| a[i] + b[i])
}

fn sub(a: [f32; FIELDS], b: [f32; FIELDS]) -> [f32; FIELDS] {
    std::array::from_fn(|i| a[i] - b[i])
}

impl Sheared {
    /// The sums along lines of `slope` over `2·h + 1` samples, for centre
    /// samples `centres` (the others are left zero). The window moves
    /// along the centres a sample at a time, taking in one sample's column
    /// of rows and letting one go, each at the sheared rows its image rows
    /// fall on.
    fn new(grain: &Grain, slope: f32, h: usize, centres: std::ops::Range<usize>) -> Self {
        let m = grain.width;
        let shift: Vec<i32> = (0..m)
            .map(|j| (slope * STRIDE as f32 * (j as f32 - m as f32 / 2.0)).round() as i32)
            .collect();
        let (lo_shift, hi_shift) = (
            shift.iter().copied().min().unwrap_or(0),
            shift.iter().copied().max().unwrap_or(0),
        );
        // Every sheared row that meets the held rows in some sample: image
        // row `r0 + r` of sample `u` is sheared row `r + hi_shift − shift(u)`.
        let lo = grain.r0 - hi_shift;
        let rows = grain.rows + hi_shift - lo_shift;
        let (n, stride) = (grain.rows as usize, rows as usize + 1);
        let mut sums = vec![[0f32; FIELDS]; stride * m];
        let mut window = vec![[0f32; FIELDS]; rows as usize];
        let at = |u: usize| (hi_shift - shift[u]) as usize;
        // Sample u's image rows fall on the sheared rows from at(u). The
        // window before the first centre: the samples it covers but its
        // last, and the one it lets go on its way in.
        for u in centres.start.saturating_sub(h + 1)..(centres.start + h).min(m) {
            grain.shift_in(&mut window, u, at(u), add);
        }
        for c in centres {
            if c + h < m {
                grain.shift_in(&mut window, c + h, at(c + h), add);
            }
            if c > h {
                grain.shift_in(&mut window, c - h - 1, at(c - h - 1), sub);
            }
            // Only the sheared rows of the centre's own image rows are
            // looked up.
            let out = &mut sums[c * stride..(c + 1) * stride];
            for k in at(c)..at(c) + n {
                out[k + 1] = add(out[k], window[k]);
            }
        }
        Self {
            shift,
            lo,
            rows,
            image_rows: grain.r0..grain.r0 + grain.rows,
            sums,
        }
    }

    /// The sums of [`Grain`]'s fields over image rows `a..b` at centre
    /// sample `c` along this slope's line, `None` beyond the rows held.
    fn band(&self, c: usize, a: i32, b: i32) -> Option<[f32; FIELDS]> {
        if a < self.image_rows.start || b > self.image_rows.end || a >= b {
            return None;
        }
        let (a, b) = (a - self.shift[c] - self.lo, b - self.shift[c] - self.lo);
        let at = c * (self.rows as usize + 1);
        Some(sub(self.sums[at + b as usize], self.sums[at + a as usize]))
    }

    /// The mean grey level (a sum of the three channels) of `grain` over
    /// image rows `a..b` at centre sample `c` along this slope's line
    /// over `2·h + 1` samples, `None` where too little of it was seen.
    /// Summed where asked: few candidates get so far.
    fn level(&self, grain: &Grain, h: usize, c: usize, a: i32, b: i32) -> Option<f32> {
        let (mut sum, mut seen) = (0f32, 0usize);
        let n = grain.rows as usize;
        for j in c.saturating_sub(h)..(c + h + 1).min(grain.width) {
            // Sample j's rows of the line, as indices into its column.
            let d = self.shift[j] - self.shift[c] - grain.r0;
            let (lo, hi) = ((a + d).clamp(0, grain.rows), (b + d).clamp(0, grain.rows));
            for &x in &grain.level[j * n + lo as usize..j * n + hi.max(lo) as usize] {
                sum += x;
                seen += (x > 0.0) as usize;
            }
        }
        let expected = (2 * h + 1) * (b - a).max(0) as usize;
        (seen > 0 && seen as f32 >= MIN_COVER * expected as f32).then(|| sum / seen as f32)
    }
}

/// The pooled grain of a band of `pixels` from its field sums: the
/// band-pass's standard deviation (a steady curvature of the light, such
/// as vignetting, moves the band-pass's mean and is not grain), `None`
/// where too little of the band was seen.
fn beyond_noise(sums: [f32; FIELDS], pixels: f32) -> Option<Spread> {
    let [e, e2, noise2, cover] = sums;
    (cover >= MIN_COVER * pixels).then(|| {
        let mean = e / cover;
        let var = (e2 / cover - mean * mean).max(0.0);
        let noise2 = noise2 / cover;
        Spread {
            beyond2: (var - noise2).max(0.0),
            noise2,
            var,
        }
    })
}

/// The spread of a band's band-pass values, as variances (their square
/// roots are taken only where a candidate passes).
#[derive(Debug, Clone, Copy)]
struct Spread {
    /// Beyond the noise's.
    beyond2: f32,
    /// The noise's alone.
    noise2: f32,
    /// All of it.
    var: f32,
}

impl Spread {
    /// Whether the spread beyond the noise's is at least `k` times the
    /// noise's.
    fn beyond_at_least(&self, k: f32) -> bool {
        self.beyond2 >= k * k * self.noise2
    }

    /// Whether the spread beyond the noise's is at most `k` times the
    /// noise's.
    fn beyond_at_most(&self, k: f32) -> bool {
        self.beyond2 <= k * k * self.noise2
    }
}

/// Where the line cue searches a column: candidate bases from row `first`
/// down.
#[derive(Debug, Clone, Copy)]
struct Searched {
    first: i32,
    /// Under a base the scan found beyond the soft limit: the smooth
    /// surface above a candidate, all the rows of it, must lie below that
    /// base too, or the cue would find the same base again a few rows low
    /// where the far floor under it has lost its grain.
    under_base: bool,
}

/// Where the line cue searches column `u`, whose scan gave `b`: below the
/// base found, or below the last floor row. Columns whose scan found a base
/// within the soft range limit, or an undecided one, are not searched.
fn searched(ex: &RopExtractor, u: usize, b: &ColumnBoundary) -> Option<Searched> {
    match *b {
        // Below an undecided base the floor is not known to be clear.
        ColumnBoundary::Obstacle {
            undecided: Some(_), ..
        }
        | ColumnBoundary::Undecided { .. } => None,
        ColumnBoundary::Obstacle { row, .. } => {
            let p = ex.table.floor_at_row(u as u32, row.min((ex.height - 1) as f32))?;
            // Two rows clear of the base found.
            (p.norm() as f32 > ex.max_range_m).then_some(Searched {
                first: row.ceil() as i32 + 3,
                under_base: true,
            })
        }
        ColumnBoundary::Clear { top_row } => Some(Searched {
            first: top_row as i32 + 1,
            under_base: false,
        }),
        ColumnBoundary::NoFloor => None,
    }
}

/// The boundary at a base the line cue found between rows `v − 1` (the
/// surface's lowest) and `v` (the floor's topmost) of column `u`: there is
/// no step of colour to place it closer, and the surface's colour is that
/// of the two rows above its lowest.
fn base_at(px: &[u8], width: u32, u: u32, v: u32) -> ColumnBoundary {
    // Candidates lie at least MIN_ABOVE_ROWS (3) rows down the image.
    let colour = mean_of((v.saturating_sub(3)..v.saturating_sub(1)).map(|w| smoothed(px, width, u, w)))
        .and_then(ColourTag::from_rgb);
    ColumnBoundary::Obstacle {
        row: v as f32 - 0.5,
        colour,
        undecided: None,
    }
}

/// Brings the boundaries `out` of image `px` nearer where the line cue
/// finds a smooth surface's base below them (see the module's doc).
pub(super) fn add_bases(ex: &RopExtractor, px: &[u8], grey_sigma: f32, out: &mut [ColumnBoundary]) {
    let (m, n) = (ex.width as usize, ex.height as i32);
    let starts: Vec<Option<Searched>> = out.iter().enumerate().map(|(u, b)| searched(ex, u, b)).collect();
    let Some(top) = starts.iter().flatten().map(|s| s.first).min() else {
        return;
    };
    // Samples (every STRIDE-th column): the rows searched from, and the
    // window's half-width in samples.
    let ms = m.div_ceil(STRIDE);
    let sample_starts: Vec<Option<Searched>> = (0..ms).map(|j| starts[j * STRIDE]).collect();
    let hs = (ex.config.line_columns as usize / STRIDE).max(1);
    let r0 = (top - MAX_ABOVE_ROWS).max(0);
    if r0 + MIN_ABOVE_ROWS + FLOOR_ROWS > n || ms < 2 * hs + 1 {
        return;
    }
    // Never below one 8-bit step's quantisation: on a smooth ramp of grey
    // the three channels step together, so their mean is no finer, and the
    // steps of a ramp are no grain.
    let grain = Grain::of(
        px,
        ex.width,
        ex.height,
        r0 as u32,
        grey_sigma.max(QUANTISATION_SIGMA),
    );
    let scores = Scores::of(ex, &grain, &sample_starts, hs);
    let runs: Vec<Vec<Run>> = sample_starts
        .iter()
        .enumerate()
        .map(|(c, s)| s.map_or_else(Vec::new, |s| scores.runs(c, s.first)))
        .collect();
    // Samples whose column the scan settled (a base within the limit, or no
    // floor) neither carry a line nor break one.
    let settled: Vec<bool> = sample_starts.iter().map(Option::is_none).collect();
    for chain in lines(runs, &settled, hs) {
        for (j, v) in on_the_line(&chain) {
            for u in j * STRIDE..((j + 1) * STRIDE).min(m) {
                if starts[u].is_some_and(|s| v >= s.first) {
                    out[u] = base_at(px, ex.width, u as u32, v as u32);
                }
            }
        }
    }
}

/// The candidate bases of every searched sample and row, scored over the
/// slopes.
struct Scores {
    /// The first row held.
    r0: i32,
    /// The last candidate row: two floor bands above the image's bottom.
    last_row: i32,
    /// Samples a row.
    samples: usize,
    /// Per row and sample: the least ratio of the grain above to the
    /// floor's below, as a share of the most the candidate's rule allows
    /// (at most 1 where the cue holds), over the slopes where the
    /// candidate's tests hold (infinite elsewhere).
    ratio: Vec<f32>,
    /// The least ratio of the whole spreads, noise included: where the
    /// noise hides the surface's grain (the ratio above is 0 for a few rows
    /// about the base) it still falls most where the grain ends.
    sharpness: Vec<f32>,
    /// The greatest relative step of brightness between the rows just
    /// above and just below, over the slopes where the candidate's tests
    /// hold.
    step: Vec<f32>,
    /// The least step of brightness that places a base.
    faint_step: f32,
}

impl Scores {
    /// Scores the rows below `starts` (per sample) over windows of
    /// `2·hs + 1` samples.
    fn of(ex: &RopExtractor, grain: &Grain, starts: &[Option<Searched>], hs: usize) -> Self {
        let (m, ms, r0) = (ex.width as usize, grain.width, grain.r0);
        let rows = grain.rows as usize;
        let mut scores = Self {
            r0,
            last_row: r0 + grain.rows - 2 * FLOOR_ROWS,
            samples: ms,
            ratio: vec![f32::INFINITY; rows * ms],
            sharpness: vec![f32::INFINITY; rows * ms],
            step: vec![0.0; rows * ms],
            faint_step: ex.config.faint_step_fraction * ex.config.min_brightness_step,
        };
        let first = starts.iter().position(Option::is_some).unwrap_or(0);
        let last = starts.iter().rposition(Option::is_some).unwrap_or(0);
        let width = (2 * hs + 1) as f32;
        let full_step = ex.config.min_brightness_step;
        let faint_step = ex.config.faint_step_fraction * full_step;
        for slope in SLOPES {
            let sheared = Sheared::new(grain, slope, hs, first..last + 1);
            let spread = |c: usize, a: i32, b: i32| {
                sheared
                    .band(c, a, b)
                    .and_then(|s| beyond_noise(s, width * (b - a) as f32))
            };
            for (c, searched) in starts.iter().enumerate() {
                let Some(searched) = *searched else { continue };
                for v in searched.first.max(r0 + MIN_ABOVE_ROWS)..=scores.last_row {
                    // Above, as many rows as an obstacle of the least height
                    // spans there must be smooth: their band-pass's spread
                    // within about two standard errors of the noise's own
                    // (tested first: on the floor it fails at once).
                    let run = ex.run_rows[(v as usize - 1) * m + c * STRIDE] as i32;
                    let k = run.clamp(MIN_ABOVE_ROWS, MAX_ABOVE_ROWS);
                    let k = match searched.under_base {
                        true if v - k < searched.first => continue,
                        true => k,
                        false => k.min(v - r0),
                    };
                    let Some(above) = spread(c, v - k, v).filter(|s| s.beyond_at_most(SMOOTH_OVER_NOISE))
                    else {
                        continue;
                    };
                    // The floor below must carry grain, and so must its
                    // rows just below the base (grain that fades with
                    // distance is not a base) and the rows beyond (a
                    // speck's rim is grain only where the speck lies): at
                    // least as much as the noise's for any rule (tested
                    // first: most rows fail here).
                    let grained =
                        |a: i32, b: i32| spread(c, a, b).filter(|s| s.beyond_at_least(STEP_GRAIN_OVER_NOISE));
                    let Some(near) = grained(v, v + STEP_ROWS) else {
                        continue;
                    };
                    let Some(below) = grained(v, v + FLOOR_ROWS) else {
                        continue;
                    };
                    let Some(far) = grained(v + FLOOR_ROWS, v + 2 * FLOOR_ROWS) else {
                        continue;
                    };
                    let (Some(lowest), Some(first)) = (
                        sheared.level(grain, hs, c, v - k.min(STEP_ROWS), v),
                        sheared.level(grain, hs, c, v, v + STEP_ROWS),
                    ) else {
                        continue;
                    };
                    let step = (lowest - first).abs() / first.max(1.0);
                    let strong = [near, below, far]
                        .iter()
                        .all(|s| s.beyond_at_least(GRAIN_OVER_NOISE));
                    // The most ratio allowed: the texture ratio on grain well
                    // beyond the noise; with a step of brightness along the
                    // line, on grain as strong as the noise, the texture ratio
                    // at a full step and the faint ratio at a faint one.
                    let (allowed, above) = if strong {
                        (ex.config.texture_ratio, above)
                    } else if step < faint_step {
                        continue;
                    } else {
                        let tall = k.max(TALL_ROWS);
                        if searched.under_base && v - tall < searched.first {
                            continue;
                        }
                        let Some(above) =
                            spread(c, v - tall, v).filter(|s| s.beyond_at_most(SMOOTH_OVER_NOISE))
                        else {
                            continue;
                        };
                        match step >= full_step {
                            true => (ex.config.texture_ratio, above),
                            false => (ex.config.faint_texture_ratio, above),
                        }
                    };
                    let i = (v - r0) as usize * ms + c;
                    let r = (above.beyond2 / below.beyond2.min(near.beyond2)).sqrt() / allowed;
                    scores.ratio[i] = scores.ratio[i].min(r);
                    scores.sharpness[i] = scores.sharpness[i].min((above.var / near.var).sqrt());
                    scores.step[i] = scores.step[i].max(step);
                }
            }
        }
        scores
    }

    /// The runs of rows of sample `c`, searched from row `start`, where the
    /// cue holds, each with the row its base is put at.
    fn runs(&self, c: usize, start: i32) -> Vec<Run> {
        let at = |v: i32| (v - self.r0) as usize * self.samples + c;
        let mut out: Vec<Run> = Vec::new();
        for v in start.max(self.r0 + MIN_ABOVE_ROWS)..=self.last_row {
            if self.ratio[at(v)] > 1.0 {
                continue;
            }
            match out.last_mut() {
                Some(r) if r.hi + 1 == v => {
                    r.hi = v;
                    let (a, b) = (at(v), at(r.sharpest));
                    // A step of brightness places the base where it is
                    // greatest; without one, where the spread falls most.
                    let sharper = match (self.step[a] >= self.faint_step, self.step[b] >= self.faint_step) {
                        (true, true) => self.step[a] > self.step[b],
                        (true, false) => true,
                        (false, true) => false,
                        (false, false) => self.sharpness[a] < self.sharpness[b],
                    };
                    if sharper {
                        r.sharpest = v;
                    }
                }
                _ => out.push(Run { hi: v, sharpest: v }),
            }
        }
        out
    }
}
