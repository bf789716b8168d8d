//! Deciding candidate obstacle bases: the cues that confirm a pixel off the
//! floor or a sharp step as an obstacle's base, and the boundary's sub-pixel
//! row and colour.

use super::seed::small_median;
use super::texture::{texture_energy, TEXTURE_MIN_ROWS, TEXTURE_ROWS};
use super::RopExtractor;
use crate::config::VisionConfig;
use crate::scan::{smoothed, Candidate, Classifier, FloorTrack, SQRT_3};
use crate::ColumnBoundary;
use pirouette_camera::FloorTable;
use pirouette_profile::ColourTag;

/// Rows each side of a boundary used to measure floor and obstacle levels.
const LEVEL_OFFSET: u32 = 3;

/// Consecutive rows that must be floor again above a base for the floor
/// to show again there (as many as [`Cues::column_confirms`] reads).
const RESUME_ROWS: u32 = 3;

/// One image as the cues that decide obstacle bases read it: its pixels
/// and size, the rows an obstacle of the least height spans at each
/// pixel, and the settings.
#[derive(Clone, Copy)]
pub(super) struct Cues<'a> {
    px: &'a [u8],
    width: u32,
    height: u32,
    run_rows: &'a [u16],
    config: &'a VisionConfig,
    table: &'a FloorTable,
    top_floor: &'a [u32],
}

impl<'a> Cues<'a> {
    /// The cues of image `px` (RGB, row-major) as `ex` sees it.
    pub(super) fn new(ex: &'a RopExtractor, px: &'a [u8]) -> Self {
        Self {
            px,
            width: ex.width,
            height: ex.height,
            run_rows: &ex.run_rows,
            config: &ex.config,
            table: &ex.table,
            top_floor: &ex.top_floor,
        }
    }

    /// Whether the floor shows again above the base of candidate `c` in
    /// column `u` within [`VisionConfig::mark_depth_m`] along the floor:
    /// [`RESUME_ROWS`] consecutive rows that are floor again, the first of
    /// them no farther than the depth beyond the base. A row is floor again
    /// when it is floor by the scan's test (`classifier`) against the floor
    /// followed from the base's prediction (as [`Cues::edge_confirms`]
    /// follows it) and nearer that floor's colour than the mean colour of
    /// the rows that made it a base (the run above it): the face of an
    /// obstacle close to the floor's colour, whose base only a sharp step
    /// found, stays the obstacle. A base whose floor does not show again
    /// before the column's last floor row, or the depth, is decided.
    pub(super) fn floor_resumes(&self, u: u32, c: &Candidate, classifier: &Classifier) -> bool {
        let depth = self.config.mark_depth_m;
        if depth <= 0.0 || c.row == 0 {
            return false;
        }
        let Some(base) = self.table.floor(u, c.row) else {
            return false;
        };
        let limit = base.norm() + f64::from(depth);
        let top = self.top_floor[u as usize];
        let (px, m) = (self.px, self.width);
        // The colour above the base: the mean over the run an obstacle of
        // the least height would span there, the rows that made it a base.
        let run = self.run_rows[(c.row * m + u) as usize].max(1) as u32;
        let Some(patch) = mean_of((c.row.saturating_sub(run).max(top)..c.row).map(|w| smoothed(px, m, u, w)))
        else {
            return false;
        };
        let mut track = FloorTrack {
            level: c.floor,
            trend: c.trend,
        };
        // The base's own row was predicted as `c.floor`: coast over it.
        track.step(&c.floor, false, self.config.adapt_rate, self.config.trend_rate);
        let mut run = 0u32;
        for w in (top..c.row).rev() {
            if run == 0 && self.table.floor(u, w).is_none_or(|p| p.norm() > limit) {
                return false;
            }
            let q = smoothed(px, m, u, w);
            let pred = track.predict();
            let floor = classifier.is_floor(&q, &pred) && dist2(&q, &pred) < dist2(&q, &patch);
            track.step(&q, floor, self.config.adapt_rate, self.config.trend_rate);
            run = if floor { run + 1 } else { 0 };
            if run == RESUME_ROWS {
                return true;
            }
        }
        false
    }

    /// Whether a candidate whose run has been scanned, `off` of its rows
    /// not floor, is the base of an obstacle, and if so the boundary: the
    /// run above it must be as tall as an obstacle would be there, and the
    /// column itself must show it.
    pub(super) fn decide(
        &self,
        u: u32,
        c: &Candidate,
        off: u32,
        classifier: &Classifier,
    ) -> Option<ColumnBoundary> {
        if c.edge {
            return Some(self.refine(u, c.row, c.floor, c.trend));
        }
        let span = c.row - c.lo + 1;
        // The column itself, not just its neighbours averaged into it, must
        // show the obstacle: beside an obstacle's side edge a third of an
        // obstacle pixel is enough to trip the test.
        (off as f32 >= self.config.run_fraction * span as f32
            && self.column_confirms(u, c.row, &c.floor, classifier))
        .then(|| self.refine(u, c.row, c.floor, c.trend))
    }

    /// Whether a sharp step at row `v` of column `u` (a floor pixel no
    /// longer close to the floor, above one that was) is an obstacle's base:
    /// following the floor from `coasted` (the track after coasting over
    /// row `v`) with the edge test's tolerances, the run above must stay off
    /// the floor as an obstacle's would, and the column itself must show it.
    pub(super) fn edge_confirms(&self, u: u32, v: u32, coasted: FloorTrack, edge: &Classifier) -> bool {
        let px = self.px;
        let run = self.run_rows[(v * self.width + u) as usize].max(1) as u32;
        let lo = (v + 1).saturating_sub(run);
        let mut ahead = coasted;
        let mut off = 1u32;
        for w in (lo..v).rev() {
            let q = smoothed(px, self.width, u, w);
            let close = edge.is_floor(&q, &ahead.predict());
            ahead.step(&q, close, self.config.adapt_rate, self.config.trend_rate);
            off += (!close) as u32;
        }
        let pred: [f32; 3] = std::array::from_fn(|c| coasted.level[c]);
        off as f32 >= self.config.run_fraction * (v - lo + 1) as f32
            && self.column_confirms(u, v, &pred, edge)
    }

    /// Whether a sharp step of brightness alone at row `v` of column `u` is
    /// an obstacle's base, judged with the tolerances of `both` and the
    /// texture ratio `ratio` (`(both, ratio)`). The floor's level is the
    /// median of the rows below the step, as they are: not the track's extrapolation, which a
    /// speck's flank bends, and not a mean, which a speck's glow lifts (a
    /// wall's base is a step between two plateaus; a speck's top edge only
    /// the far side of a peak). The run above must stay off that level
    /// with both tolerances scaled (`both`) as an obstacle's would, and the
    /// column itself must show it; and the texture above the step must
    /// drop below `ratio` of the floor's below it
    /// ([`VisionConfig::texture_ratio`](crate::VisionConfig::texture_ratio), or for a faint step
    /// [`VisionConfig::faint_texture_ratio`](crate::VisionConfig::faint_texture_ratio)),
    /// both counted beyond the sensor noise (`grey_sigma`, of one pixel's
    /// grey), and the floor's must stand out of that noise. That level must
    /// also be the floor the scan followed up to the step: floor by the
    /// scan's own test (`floor_test`) against the floor it predicted there
    /// (`followed`). Just above a speck or a strip of tape, the rows below
    /// are the speck, not the floor.
    pub(super) fn bright_edge_confirms(
        &self,
        u: u32,
        v: u32,
        (both, ratio): (&Classifier, f32),
        grey_sigma: f32,
        (followed, floor_test): (&[f32; 3], &Classifier),
    ) -> bool {
        let px = self.px;
        let (m, n) = (self.width, self.height);
        // The floor's level and texture are judged over two windows below
        // the step: nearer the image's bottom there is too little floor.
        if v + 2 + 2 * TEXTURE_ROWS > n {
            return false;
        }
        // Rows above the step and below it, leaving out the row of the
        // step and the one under it (the boundary may blur over both).
        let above = v.saturating_sub(TEXTURE_ROWS)..v;
        let below = v + 2..v + 2 + TEXTURE_ROWS;
        if above.len() < TEXTURE_MIN_ROWS {
            return false;
        }
        let level_rows = v + 2..v + 2 + 2 * TEXTURE_ROWS;
        let Some(floor) = median_of(level_rows.map(|w| smoothed(px, m, u, w))) else {
            return false;
        };
        if !floor_test.is_floor(&floor, followed) {
            return false;
        }
        let run = self.run_rows[(v * m + u) as usize].max(1) as u32;
        let lo = (v + 1).saturating_sub(run);
        // Rows off the floor, counted up from the step until the run can
        // no longer have enough of them.
        let needed = self.config.run_fraction * (v - lo + 1) as f32;
        let (mut off, mut left) = (0u32, v - lo + 1);
        for w in (lo..=v).rev() {
            if ((off + left) as f32) < needed {
                break;
            }
            left -= 1;
            off += !both.is_floor(&smoothed(px, m, u, w), &floor) as u32;
        }
        if (off as f32) < needed || !self.column_confirms(u, v, &floor, both) {
            return false;
        }
        // The run is a plateau too: its rows keep to their own median
        // colour, where a floor that brightens steadily drifts away.
        let Some(plateau) = median_of(
            (lo..=v)
                .take(2 * TEXTURE_ROWS as usize)
                .map(|w| smoothed(px, m, u, w)),
        ) else {
            return false;
        };
        let steady = (lo..=v)
            .take(2 * TEXTURE_ROWS as usize)
            .filter(|&w| both.is_floor(&smoothed(px, m, u, w), &plateau))
            .count();
        if (steady as f32) < self.config.run_fraction * (v - lo + 1).min(2 * TEXTURE_ROWS) as f32 {
            return false;
        }
        // The floor's texture: the lesser of two windows below, so that a
        // speck in one of them does not count as the floor's grain.
        let lower = v + 2 + TEXTURE_ROWS..v + 2 + 2 * TEXTURE_ROWS;
        let (Some(above), Some(mut below)) =
            (texture_energy(px, m, u, above), texture_energy(px, m, u, below))
        else {
            return false;
        };
        let s_above = above.beyond_noise(grey_sigma);
        // The lower window can only lessen the floor's texture: a step the
        // nearer one rejects is rejected.
        if s_above > ratio * below.beyond_noise(grey_sigma) {
            return false;
        }
        if let Some(t) = texture_energy(px, m, u, lower) {
            if t.beyond_noise(grey_sigma) < below.beyond_noise(grey_sigma) {
                below = t;
            }
        }
        let s_below = below.beyond_noise(grey_sigma);
        s_below >= below.noise(grey_sigma) && s_above <= ratio * s_below
    }

    /// Whether the raw pixels of column `u` just above row `v` (two of the
    /// three rows `v−1 ..= v−3`, or all that exist) leave the floor `pred`,
    /// with the noise allowance of a single pixel.
    pub(super) fn column_confirms(&self, u: u32, v: u32, pred: &[f32; 3], classifier: &Classifier) -> bool {
        let px = self.px;
        let single = Classifier {
            noise: classifier.noise * SQRT_3,
            ..*classifier
        };
        let rows = v.min(3) as usize;
        if rows == 0 {
            return true;
        }
        let off = (1..=rows as u32)
            .filter(|&k| {
                let i = ((v - k) * self.width + u) as usize * 3;
                !single.is_floor(&[px[i] as f32, px[i + 1] as f32, px[i + 2] as f32], pred)
            })
            .count();
        off * 3 >= rows * 2
    }

    /// Sub-pixel row and colour of a boundary first detected at row `v`:
    /// the share of obstacle in each row of a window around `v`, from the
    /// levels of floor below and obstacle above, locates the edge without
    /// blurring it. The floor's level is carried from the rows it is
    /// measured in up to each row of the window along `trend`, the floor
    /// track's change per row there: floor that darkens toward a wall's
    /// base (or brightens toward the horizon) would otherwise count as a
    /// share of the obstacle and put the edge low, the range short.
    pub(super) fn refine(&self, u: u32, v: u32, floor_ref: [f32; 3], trend: [f32; 3]) -> ColumnBoundary {
        let px = self.px;
        let (m, n) = (self.width, self.height);
        let pix = |w: u32| smoothed(px, m, u, w);
        let above = (1..=2).filter_map(|k| v.checked_sub(LEVEL_OFFSET + k - 1));
        let obstacle = mean_of(above.map(pix)).unwrap_or_else(|| pix(v.saturating_sub(1)));
        let below = (LEVEL_OFFSET..LEVEL_OFFSET + 2).map(|k| v + k).filter(|&w| w < n);
        let floor = mean_of(below.clone().map(pix)).unwrap_or(floor_ref);
        // The row the floor's level stands for: the mean of the rows it was
        // measured in, or the detected row itself, where the track's
        // prediction stands in for them (at the image's bottom).
        let level_row = match below.clone().count() {
            0 => v as f32,
            k => below.map(|w| w as f32).sum::<f32>() / k as f32,
        };
        let diff = [
            obstacle[0] - floor[0],
            obstacle[1] - floor[1],
            obstacle[2] - floor[2],
        ];
        let norm2: f32 = diff.iter().map(|d| d * d).sum();
        let colour = ColourTag::from_rgb(obstacle);
        if norm2 < 1.0 {
            return ColumnBoundary::Obstacle {
                row: v as f32 + 0.5,
                colour,
                undecided: None,
            };
        }
        // Window rows v−2 ..= v+2; the obstacle is on top.
        let mut floor_share = 0.0;
        let lo = v.saturating_sub(2);
        let hi = (v + 2).min(n - 1);
        for w in lo..=hi {
            let p = pix(w);
            let up = level_row - w as f32;
            let f = [
                floor[0] + trend[0] * up,
                floor[1] + trend[1] * up,
                floor[2] + trend[2] * up,
            ];
            let d = [obstacle[0] - f[0], obstacle[1] - f[1], obstacle[2] - f[2]];
            let nd: f32 = d.iter().map(|x| x * x).sum();
            let a = if nd < 1.0 {
                0.5
            } else {
                ((p[0] - f[0]) * d[0] + (p[1] - f[1]) * d[1] + (p[2] - f[2]) * d[2]) / nd
            };
            floor_share += 1.0 - a.clamp(0.0, 1.0);
        }
        let row = hi as f32 + 0.5 - floor_share;
        ColumnBoundary::Obstacle {
            row: row.clamp(lo as f32 - 0.5, hi as f32 + 0.5),
            colour,
            undecided: None,
        }
    }
}

/// The squared distance between two colours.
fn dist2(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    (0..3).map(|c| (a[c] - b[c]) * (a[c] - b[c])).sum()
}

/// The mean of some colours, `None` when there are none.
pub(super) fn mean_of(it: impl Iterator<Item = [f32; 3]>) -> Option<[f32; 3]> {
    let (mut s, mut k) = ([0f32; 3], 0);
    for p in it {
        for (acc, x) in s.iter_mut().zip(p) {
            *acc += x;
        }
        k += 1;
    }
    (k > 0).then(|| s.map(|x| x / k as f32))
}

/// The per-channel median of at most `2·TEXTURE_ROWS` colours, `None` when
/// there are none.
fn median_of(it: impl Iterator<Item = [f32; 3]>) -> Option<[f32; 3]> {
    const MOST: usize = 2 * TEXTURE_ROWS as usize;
    let mut channels = [[0f32; MOST]; 3];
    let mut k = 0;
    for p in it.take(MOST) {
        for (channel, x) in channels.iter_mut().zip(p) {
            channel[k] = x;
        }
        k += 1;
    }
    (k > 0).then(|| channels.map(|mut channel| small_median(&mut channel[..k])))
}
