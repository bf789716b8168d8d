//! Where each column's scan starts: a line through its own bottom rows,
//! its trend pooled with its neighbours', and a speck in the seed rows
//! replaced from both sides.

use crate::scan::{smoothed, Classifier, FloorTrack};

/// Rows of the seed at the bottom of each column.
pub(super) const SEED_ROWS: u32 = 6;

/// How far a column's seed is compared with its neighbours', columns: past
/// a speck of lint six pixels wide widened by the three-pixel smoothing.
const SEED_NEIGHBOUR: usize = 8;

/// How far out, columns, a seed is compared with seeds on both sides
/// after its nearest neighbours (see [`seeds`]).
const WIDE_SPECK_SCALES: [usize; 2] = [2 * SEED_NEIGHBOUR, 4 * SEED_NEIGHBOUR];

/// Every how many columns the neighbours' seed trends are sampled for
/// [`pooled_trends`]: two apart, the three-pixel means share one pixel in
/// three instead of two.
const TREND_STEP: usize = 2;

/// The seeds with each column's trend replaced by the median, channel by
/// channel, of the trends of the seeds within [`SEED_NEIGHBOUR`] columns
/// (every [`TREND_STEP`]th, its own included), and its level moved along
/// its own seed line to match.
///
/// A line through a column's own [`SEED_ROWS`] rows knows its slope only to
/// about 0.3 σ a row, and the track coasts along that slope wherever it
/// leaves the floor: 1.5 σ of error, common among a few hundred columns,
/// takes it past the noise allowance within ten rows, and every row above
/// then reads as an obstacle. The floor's brightening up the image
/// (vignetting, the fall-off of the light) changes slowly across columns,
/// so the neighbours measure the same slope; the median of nine keeps it
/// when a speck of lint spoils a few of them.
fn pooled_trends(own: &[Seed]) -> Vec<Seed> {
    // The top seed row's offset from the seed rows' mean.
    let lever = (SEED_ROWS - 1) as f32 / 2.0;
    let slopes: Vec<Option<[f32; 3]>> = own
        .iter()
        .map(|s| match s {
            Seed::Track(t) => Some(t.trend),
            _ => None,
        })
        .collect();
    (0..own.len())
        .map(|u| {
            let Seed::Track(t) = own[u] else {
                return own[u];
            };
            let lo = u.saturating_sub(SEED_NEIGHBOUR);
            let hi = (u + SEED_NEIGHBOUR).min(own.len() - 1);
            // Sampled on the same parity as `u`, so that `u` is among them.
            let first = lo + (u - lo) % TREND_STEP;
            let mut trends = [[0f32; 3]; 2 * SEED_NEIGHBOUR / TREND_STEP + 1];
            let mut k = 0;
            for slope in slopes[first..=hi].iter().step_by(TREND_STEP).flatten() {
                trends[k] = *slope;
                k += 1;
            }
            // Fewer than nine near the image's edges and beside columns
            // without floor.
            let median = if k == trends.len() {
                median_of_nine(trends)
            } else {
                std::array::from_fn(|c| {
                    let mut vals = [0f32; 2 * SEED_NEIGHBOUR / TREND_STEP + 1];
                    for (v, tr) in vals.iter_mut().zip(&trends[..k]) {
                        *v = tr[c];
                    }
                    small_median(&mut vals[..k])
                })
            };
            Seed::Track(FloorTrack {
                level: std::array::from_fn(|c| t.level[c] + (median[c] - t.trend[c]) * lever),
                trend: median,
            })
        })
        .collect()
}

/// The median of nine values, channel by channel, by the 19
/// compare-exchanges of the classic median-of-nine network: branch-free
/// minima and maxima, a fraction of a sort's cost.
fn median_of_nine(mut p: [[f32; 3]; 9]) -> [f32; 3] {
    const NETWORK: [(usize, usize); 19] = [
        (1, 2),
        (4, 5),
        (7, 8),
        (0, 1),
        (3, 4),
        (6, 7),
        (1, 2),
        (4, 5),
        (7, 8),
        (0, 3),
        (5, 8),
        (4, 7),
        (3, 6),
        (1, 4),
        (2, 5),
        (4, 7),
        (4, 2),
        (6, 4),
        (4, 2),
    ];
    for (a, b) in NETWORK {
        let (x, y) = (p[a], p[b]);
        p[a] = std::array::from_fn(|c| if x[c] > y[c] { y[c] } else { x[c] });
        p[b] = std::array::from_fn(|c| if x[c] > y[c] { x[c] } else { y[c] });
    }
    p[4]
}

/// The median (the upper one of an even count) of a handful of values
/// that are not NaN, by insertion sort: for the nine of [`pooled_trends`] a
/// few dozen comparisons, far fewer than a general selection makes.
pub(super) fn small_median(vals: &mut [f32]) -> f32 {
    for i in 1..vals.len() {
        let x = vals[i];
        let mut j = i;
        while j > 0 && vals[j - 1] > x {
            vals[j] = vals[j - 1];
            j -= 1;
        }
        vals[j] = x;
    }
    vals[vals.len() / 2]
}

/// The seed of median brightness (channel sum of its level) among the
/// tracks of `seeds`, the upper one of an even count; `None` without any.
fn median_seed(seeds: &[Seed]) -> Option<FloorTrack> {
    let mut tracks: Vec<(f32, FloorTrack)> = seeds
        .iter()
        .filter_map(|s| match s {
            Seed::Track(t) => Some((t.level.iter().sum(), *t)),
            _ => None,
        })
        .collect();
    if tracks.is_empty() {
        return None;
    }
    let mid = tracks.len() / 2;
    tracks.select_nth_unstable_by(mid, |a, b| a.0.total_cmp(&b.0));
    Some(tracks[mid].1)
}

/// Where a column's scan starts.
#[derive(Debug, Clone, Copy)]
pub(super) enum Seed {
    /// No floor in the column.
    NoFloor,
    /// The column's floor ends within its seed rows.
    Clear { top_row: u32 },
    /// The floor to follow up from the row above the seed.
    Track(FloorTrack),
}

/// Each column's start: a line through its own bottom rows, unless that
/// seed is not floor against its neighbours' on both sides: then a
/// speck of lint or a reflection lies in its seed rows, and the column
/// starts from their mean instead. The neighbours are the seeds
/// [`SEED_NEIGHBOUR`] columns either side; near the image's edge the
/// missing side is the line through the two inward ones (that far and
/// twice as far), so that the dark corners of vignetting pass. A clean
/// column next to a speck still agrees with its other side.
///
/// Lint close to the camera is wider than that reach: the neighbours lie
/// on it too and agree, or straddle its edge and disagree with each
/// other. The seed is then compared with seeds farther out
/// ([`WIDE_SPECK_SCALES`]), on both sides only, that agree with each
/// other; where they do not (a dark floor darkening into a vignetted
/// corner changes by more than the tolerance that far) and the seed is
/// not floor to the midpoint between them, with the median seed of the
/// window between them, when that is floor to one of them.
/// A real obstacle at the bottom narrower than twice the
/// farthest scale is then followed as one from the row above the seed,
/// where before its colour was taken for the floor's.
pub(super) fn seeds(
    px: &[u8],
    (width, height): (u32, u32),
    top_floor: &[u32],
    classifier: &Classifier,
) -> Vec<Seed> {
    let own = pooled_trends(&own_seeds(px, (width, height), top_floor));
    (0..own.len()).map(|u| unspecked(&own, u, classifier)).collect()
}

/// Each column's seed from its own bottom rows alone (`top_floor`: each
/// column's topmost floor row, the image's height where it has none).
fn own_seeds(px: &[u8], (width, n): (u32, u32), top_floor: &[u32]) -> Vec<Seed> {
    (top_floor.iter().enumerate())
        .map(|(u, &top)| {
            if top >= n {
                return Seed::NoFloor;
            }
            let seed_rows = SEED_ROWS.min(n - top);
            if seed_rows == n - top {
                return Seed::Clear { top_row: top };
            }
            let mut rows = [[0f32; 3]; SEED_ROWS as usize];
            for (s, v) in rows.iter_mut().zip((n - seed_rows..n).rev()) {
                *s = smoothed(px, width, u as u32, v);
            }
            Seed::Track(FloorTrack::seed(&rows))
        })
        .collect()
}

/// Column `j`'s seed line, where it has one.
fn track_at(own: &[Seed], j: Option<usize>) -> Option<FloorTrack> {
    match j.and_then(|j| own.get(j)) {
        Some(Seed::Track(t)) => Some(*t),
        _ => None,
    }
}

/// `a + f·(b − a)` channel by channel, for level and trend.
fn line(a: FloorTrack, b: FloorTrack, f: f32) -> FloorTrack {
    FloorTrack {
        level: std::array::from_fn(|c| a.level[c] + f * (b.level[c] - a.level[c])),
        trend: std::array::from_fn(|c| a.trend[c] + f * (b.trend[c] - a.trend[c])),
    }
}

/// Column `u`'s seed, or where a speck lies in its seed rows, the floor's
/// from its neighbours (see [`seeds`]).
fn unspecked(own: &[Seed], u: usize, classifier: &Classifier) -> Seed {
    let Seed::Track(t) = own[u] else {
        return own[u];
    };
    let Some((sides, both)) = near_sides(own, u) else {
        return own[u];
    };
    // Two sides that disagree with each other cannot both be floor: the
    // edge of a wider speck, to be judged from farther out.
    let sides_agree = || !both || classifier.is_floor(&sides[0].level, &sides[1].level);
    if !sides.iter().any(|s| classifier.is_floor(&t.level, &s.level)) && sides_agree() {
        return Seed::Track(line(sides[0], sides[1], 0.5));
    }
    wide_speck(own, u, &t, classifier).unwrap_or(own[u])
}

/// The seeds [`SEED_NEIGHBOUR`] columns either side of column `u`, or near
/// the image's edge one side and the line through the two inward seeds;
/// whether both sides are seeds of their own.
fn near_sides(own: &[Seed], u: usize) -> Option<([FloorTrack; 2], bool)> {
    let k = SEED_NEIGHBOUR;
    let far = |j: Option<usize>, near: FloorTrack| track_at(own, j).map(|f| line(near, f, -1.0));
    match (track_at(own, u.checked_sub(k)), track_at(own, Some(u + k))) {
        (Some(l), Some(r)) => Some(([l, r], true)),
        (None, Some(r)) => far(Some(u + 2 * k), r).map(|e| ([e, r], false)),
        (Some(l), None) => far(u.checked_sub(2 * k), l).map(|e| ([l, e], false)),
        (None, None) => None,
    }
}

/// The floor's seed for column `u` (seed line `t`) under a wider speck
/// (lint close to the camera spans tens of columns): from seeds farther
/// out on both sides ([`WIDE_SPECK_SCALES`]) that agree with each other
/// but not with this one.
fn wide_speck(own: &[Seed], u: usize, t: &FloorTrack, classifier: &Classifier) -> Option<Seed> {
    for scale in WIDE_SPECK_SCALES {
        // Both sides only: near the image's edge a line extrapolated that
        // far misses the dark corners of vignetting.
        let (Some(l), Some(r)) = (
            track_at(own, u.checked_sub(scale)),
            track_at(own, Some(u + scale)),
        ) else {
            break;
        };
        // (The floor's usual case, agreeing with `l`, first.)
        if classifier.is_floor(&t.level, &l.level) || classifier.is_floor(&t.level, &r.level) {
            continue;
        }
        if classifier.is_floor(&l.level, &r.level) {
            return Some(Seed::Track(line(l, r, 0.5)));
        }
        // Sides that disagree with each other: the floor may darken across
        // the window into a vignetted corner by more than the tolerance. A
        // seed on the line between them is that floor. Otherwise the
        // window's median seed (by brightness) is the floor's where the
        // speck covers less than half of it; it must be floor to one side
        // at least (not a column on the speck's edge).
        if classifier.is_floor(&t.level, &line(l, r, 0.5).level) {
            continue;
        }
        if let Some(m) = median_seed(&own[u - scale..=u + scale]) {
            if !classifier.is_floor(&t.level, &m.level)
                && (classifier.is_floor(&m.level, &l.level) || classifier.is_floor(&m.level, &r.level))
            {
                return Some(Seed::Track(m));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn small_medians_are_the_middle_of_the_sorted_values() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..2000 {
            let p: [[f32; 3]; 9] =
                std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-2.0..2.0)));
            let sorted_mid = |k: usize, c: usize| {
                let mut v: Vec<f32> = p[..k].iter().map(|x| x[c]).collect();
                v.sort_by(f32::total_cmp);
                v[k / 2]
            };
            let net = median_of_nine(p);
            for c in 0..3 {
                assert_eq!(net[c], sorted_mid(9, c));
                for k in 1..=9 {
                    let mut v: Vec<f32> = p[..k].iter().map(|x| x[c]).collect();
                    assert_eq!(small_median(&mut v), sorted_mid(k, c));
                }
            }
        }
    }
}
