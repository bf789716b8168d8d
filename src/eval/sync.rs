//! A truth's clock against a camera's frames, found from the images.
//!
//! Where a recording's frame stamps were made up or kept another clock
//! than its ground truth (`truth_clock: from_images` in the rig), the
//! frames' truth is unknown until the two clocks are tied. The images
//! tie them: as the robot turns, the room above the floor slides across
//! the view. Each frame is reduced to a *bearing profile*: the mean
//! brightness of the rows above the horizon, per bearing (the lens's
//! bending undone), differenced along the bearings so that a change of
//! exposure does not count. The turn between two frames a few apart is
//! the shift of bearing that lines their profiles up best (normalised
//! correlation, refined to a fraction of a step). A move of a few
//! centimetres shifts walls metres away by a small fraction of that.
//!
//! The truth's time is taken as `t₀ + offset + rate · (t − t₀)` of a
//! frame's stamp `t`; the offset and rate chosen are those under which
//! the truth's turns between the same pairs of frames agree best with
//! the images' (each pair's disagreement counted up to 3°, so that pairs
//! the images misjudge do not pull), searched over ±2 s and ±2 % on a
//! grid, then refined.

use anyhow::{bail, Context, Result};
use pirouette_camera::PinholeModel;
use pirouette_geom::wrap_angle;
use pirouette_io::{Dataset, PoseSpec, TruthTrack};
use rayon::prelude::*;
use serde::Serialize;

/// Bearing step of a profile, degrees.
const STEP_DEG: f64 = 0.1;
/// Frames apart in a pair: at a robot's usual turning rate a few degrees,
/// well above the profile's noise, well inside the view.
pub const PAIR_GAP: usize = 5;
/// The largest turn sought between the frames of a pair, degrees.
const MAX_TURN_DEG: f64 = 15.0;
/// A pair's disagreement counts up to this, degrees.
const CAP_DEG: f64 = 3.0;
/// Pairs whose best correlation is below this are left out.
const MIN_CORRELATION: f64 = 0.5;
/// The offsets and rates searched.
const MAX_OFFSET_S: f64 = 2.0;
const MAX_RATE_ERROR: f64 = 0.02;

/// The clock found ([`find_clock`]).
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Clock {
    /// The truth's time at the first frame's stamp, less that stamp,
    /// seconds.
    pub offset_s: f64,
    /// The truth's seconds per second of the stamps.
    pub rate: f64,
    /// Pairs of frames whose images gave a turn.
    pub pairs: usize,
    /// The median disagreement of those pairs' turns with the truth's
    /// under this clock, degrees.
    pub residual_median_deg: f64,
    /// Chosen frames whose time falls just outside the truth's span
    /// (within [`SPAN_SLACK_S`]), given the truth at its nearer end.
    pub frames_at_span_end: usize,
}

/// How far outside the truth's span a frame's time may fall and take the
/// truth at the span's end, seconds.
pub const SPAN_SLACK_S: f64 = 0.5;

impl Clock {
    /// The truth's time of a frame stamped `t`, the first frame's stamp
    /// being `t0`.
    pub fn truth_time(&self, t0: f64, t: f64) -> f64 {
        t0 + self.offset_s + self.rate * (t - t0)
    }
}

/// A frame's bearing profile: differenced mean brightness above the
/// horizon, on bearings `STEP_DEG` apart from `first_deg` (left of the
/// view, decreasing to the right); `None` where the camera sees no sky
/// band (the horizon above the image).
#[derive(Debug, Clone, PartialEq)]
pub struct BearingProfile {
    /// The bearing of the first value, degrees (left positive).
    pub first_deg: f64,
    /// The values, one per `STEP_DEG` to the right.
    pub values: Vec<f64>,
}

/// The bearing profile of a grey image seen through `camera`.
pub fn bearing_profile(image: &image::GrayImage, camera: &PinholeModel) -> Option<BearingProfile> {
    let (w, h) = image.dimensions();
    // The horizon: the row whose rays are level, on the principal column.
    let horizon = (0..h).find(|&v| camera.ray(camera.cx, v as f64).is_none_or(|r| r[2] <= 0.0))?;
    let bottom = horizon.saturating_sub(2);
    let top = bottom.saturating_sub(h * 3 / 10);
    if bottom < top + 8 {
        return None;
    }
    let v_mid = (top + bottom) as f64 / 2.0;
    // Each column's mean over the band, and its bearing.
    let mut columns: Vec<(f64, f64)> = Vec::with_capacity(w as usize);
    for u in 0..w {
        let Some(r) = camera.ray(u as f64, v_mid) else {
            continue;
        };
        let sum: f64 = (top..bottom).map(|v| f64::from(image.get_pixel(u, v)[0])).sum();
        columns.push((r[1].atan2(r[0]).to_degrees(), sum / f64::from(bottom - top)));
    }
    // Bearings fall to the right; the grid covers the columns' span.
    columns.sort_by(|a, b| b.0.total_cmp(&a.0));
    let (left, right) = (columns.first()?.0, columns.last()?.0);
    let first_deg = (left / STEP_DEG).floor() * STEP_DEG;
    let n = ((first_deg - right) / STEP_DEG).floor() as usize;
    if n < 32 {
        return None;
    }
    let mut resampled = Vec::with_capacity(n);
    let mut j = 0;
    for i in 0..n {
        let b = first_deg - i as f64 * STEP_DEG;
        while j + 2 < columns.len() && columns[j + 1].0 > b {
            j += 1;
        }
        let ((b0, m0), (b1, m1)) = (columns[j], columns[j + 1]);
        let f = if b0 == b1 {
            0.0
        } else {
            ((b0 - b) / (b0 - b1)).clamp(0.0, 1.0)
        };
        resampled.push(m0 + f * (m1 - m0));
    }
    let values = resampled.windows(2).map(|p| p[1] - p[0]).collect();
    Some(BearingProfile { first_deg, values })
}

/// The turn from `a`'s frame to `b`'s, degrees (left positive), and the
/// correlation of the profiles lined up by it: `b(β) ≈ a(β + turn)`.
/// `None` when no shift within the search overlaps enough.
pub fn profile_turn(a: &BearingProfile, b: &BearingProfile) -> Option<(f64, f64)> {
    let max_shift = (MAX_TURN_DEG / STEP_DEG).round() as i64;
    // b's value i is at bearing b.first − i·step; a's at that bearing
    // plus the turn is index i + (a.first − b.first)/step − s.
    let base = ((a.first_deg - b.first_deg) / STEP_DEG).round() as i64;
    let min_overlap = a.values.len().min(b.values.len()) / 2;
    let ncc = |s: i64| -> Option<f64> {
        let offset = base - s;
        let (mut n, mut sa, mut sb, mut saa, mut sbb, mut sab) = (0usize, 0.0, 0.0, 0.0, 0.0, 0.0);
        for (i, &y) in b.values.iter().enumerate() {
            let k = i as i64 + offset;
            if k < 0 || k as usize >= a.values.len() {
                continue;
            }
            let x = a.values[k as usize];
            n += 1;
            sa += x;
            sb += y;
            saa += x * x;
            sbb += y * y;
            sab += x * y;
        }
        if n < min_overlap.max(16) {
            return None;
        }
        let nf = n as f64;
        let cov = sab - sa * sb / nf;
        let var = (saa - sa * sa / nf) * (sbb - sb * sb / nf);
        (var > 0.0).then(|| cov / var.sqrt())
    };
    let scores: Vec<(i64, f64)> = (-max_shift..=max_shift)
        .filter_map(|s| Some((s, ncc(s)?)))
        .collect();
    let &(best, score) = scores.iter().max_by(|x, y| x.1.total_cmp(&y.1))?;
    // A parabola through the best and its neighbours.
    let at = |s: i64| scores.iter().find(|x| x.0 == s).map(|x| x.1);
    let frac = match (at(best - 1), at(best + 1)) {
        (Some(l), Some(r)) if l + r - 2.0 * score < 0.0 => {
            (0.5 * (l - r) / (l + r - 2.0 * score)).clamp(-0.5, 0.5)
        }
        _ => 0.0,
    };
    Some(((best as f64 + frac) * STEP_DEG, score))
}

/// The truth's clock against the stamps of `track`'s frames, from every
/// frame's image.
pub fn find_clock(track: &TruthTrack, camera: &PinholeModel) -> Result<Clock> {
    let frames = &track.frames;
    if frames.len() <= PAIR_GAP + 8 {
        bail!(
            "{} frames: too few to find the truth's clock from the images",
            frames.len()
        );
    }
    let profiles: Vec<Option<BearingProfile>> = frames
        .par_iter()
        .map(|(_, path)| -> Result<Option<BearingProfile>> {
            let img = image::open(path)
                .with_context(|| format!("{}: cannot decode image", path.display()))?
                .to_luma8();
            Ok(bearing_profile(&img, camera))
        })
        .collect::<Result<_>>()?;
    // The images' turn over each pair.
    let pairs: Vec<(usize, f64)> = (0..frames.len() - PAIR_GAP)
        .into_par_iter()
        .filter_map(|k| {
            let (a, b) = (profiles[k].as_ref()?, profiles[k + PAIR_GAP].as_ref()?);
            let (turn, score) = profile_turn(a, b)?;
            (score >= MIN_CORRELATION).then_some((k, turn))
        })
        .collect();
    if pairs.len() < 8 {
        bail!(
            "only {} of {} pairs of frames line up: the images do not show the turning",
            pairs.len(),
            frames.len() - PAIR_GAP
        );
    }
    let t0 = frames[0].0;
    let heading = |t: f64| track.at(t).map(|p| p.theta);
    // Per pair, the disagreement under a clock (capped; a pair outside
    // the truth's span counts the cap).
    let disagreements = |c: &Clock| -> Vec<f64> {
        pairs
            .iter()
            .map(|&(k, turn)| {
                let ta = c.truth_time(t0, frames[k].0);
                let tb = c.truth_time(t0, frames[k + PAIR_GAP].0);
                match (heading(ta), heading(tb)) {
                    (Some(a), Some(b)) => (wrap_angle(b - a).to_degrees() - turn).abs().min(CAP_DEG),
                    _ => CAP_DEG,
                }
            })
            .collect()
    };
    let cost = |c: &Clock| disagreements(c).iter().sum::<f64>();
    let search = |offsets: Vec<f64>, rates: Vec<f64>| -> Clock {
        let grid: Vec<Clock> = (offsets.iter())
            .flat_map(|&offset_s| {
                rates.iter().map(move |&rate| Clock {
                    offset_s,
                    rate,
                    pairs: 0,
                    residual_median_deg: 0.0,
                    frames_at_span_end: 0,
                })
            })
            .collect();
        grid.into_par_iter()
            .map(|c| (cost(&c), c))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, c)| c)
            .expect("a non-empty grid")
    };
    let steps = |centre: f64, half: f64, n: i32| -> Vec<f64> {
        (-n..=n)
            .map(|i| centre + half * f64::from(i) / f64::from(n))
            .collect()
    };
    let coarse = search(steps(0.0, MAX_OFFSET_S, 100), steps(1.0, MAX_RATE_ERROR, 10));
    let mut best = search(
        steps(coarse.offset_s, 0.02, 10),
        steps(coarse.rate, MAX_RATE_ERROR / 10.0, 10),
    );
    let mut d = disagreements(&best);
    d.sort_by(f64::total_cmp);
    best.pairs = pairs.len();
    best.residual_median_deg = d[d.len() / 2];
    Ok(best)
}

/// Puts the truth on the frames of a dataset whose truth keeps another
/// clock (`truth_clock: from_images`): the clock found from the images,
/// then each chosen frame's truth at its time. `None` (and nothing
/// changed) for other datasets.
pub fn put_truth_on_frames(ds: &mut Dataset) -> Result<Option<Clock>> {
    let Some(track) = ds.truth_track.clone() else {
        return Ok(None);
    };
    let camera = ds.manifest.camera.pinhole_model().with_context(|| {
        format!(
            "{}: finding the truth's clock needs the pinhole camera",
            ds.manifest_path().display()
        )
    })?;
    let mut clock = find_clock(&track, &camera).with_context(|| ds.manifest_path().display().to_string())?;
    let t0 = track.frames[0].0;
    let (first, last) = match (track.poses.first(), track.poses.last()) {
        (Some(a), Some(b)) => (a.0, b.0),
        _ => bail!("{}: the truth has no pose", ds.manifest_path().display()),
    };
    for (frame, &k) in ds.manifest.frames.iter_mut().zip(&track.chosen) {
        let t = clock.truth_time(t0, track.frames[k].0);
        let near = t.clamp(first, last);
        if near != t && (near - t).abs() <= SPAN_SLACK_S {
            clock.frames_at_span_end += 1;
        }
        let t = if (near - t).abs() <= SPAN_SLACK_S { near } else { t };
        frame.truth = track.at(t).map(PoseSpec::from);
    }
    Ok(Some(clock))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn profile(first_deg: f64, f: impl Fn(f64) -> f64, n: usize) -> BearingProfile {
        BearingProfile {
            first_deg,
            values: (0..n).map(|i| f(first_deg - i as f64 * STEP_DEG)).collect(),
        }
    }

    /// A pattern over bearings, turned by 3.37°: the turn found to a
    /// hundredth of a degree, whatever the grids' origins.
    #[test]
    fn a_turned_profile_gives_its_turn() {
        let pattern = |b: f64| (0.7 * b).sin() + 0.5 * (1.9 * b + 1.0).sin() + 0.3 * (0.23 * b * b).cos();
        let a = profile(28.0, pattern, 560);
        // b(β) = a(β + 3.37°): the scene slid right as the robot turned left.
        let b = profile(27.9, |x| pattern(x + 3.37), 560);
        let (turn, score) = profile_turn(&a, &b).unwrap();
        assert!((turn - 3.37).abs() < 0.01, "{turn}");
        assert!(score > 0.99);
        let (back, _) = profile_turn(&b, &a).unwrap();
        assert!((back + 3.37).abs() < 0.01, "{back}");
    }
}
