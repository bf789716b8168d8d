//! A truth's clock against a camera's frames, found from the images.
//!
//! Where a recording's frame stamps were made up or kept another clock
//! than its ground truth (`truth_clock: from_images` in the rig), the
//! frames' truth is unknown until the two clocks are tied. The images
//! tie them: the visual compass ([`pirouette_vision::compass`]) gives the
//! turn between every frame and the one five after it.
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
use pirouette_vision::compass::{bearing_profile, profile_turn, BearingProfile};
use rayon::prelude::*;
use serde::Serialize;

/// Frames apart in a pair: at a robot's usual turning rate a few degrees,
/// well above the profile's noise, well inside the view.
pub const PAIR_GAP: usize = 5;
/// The largest turn sought between the frames of a pair, degrees.
const MAX_TURN_DEG: f64 = 15.0;
/// A pair's disagreement counts up to this, degrees.
const CAP_DEG: f64 = 3.0;
/// Pairs whose best correlation is below this are left out.
const MIN_CORRELATION: f64 = pirouette_vision::compass::MIN_CORRELATION;
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
                .to_rgb8();
            Ok(bearing_profile(&img, camera))
        })
        .collect::<Result<_>>()?;
    // The images' turn over each pair.
    let pairs: Vec<(usize, f64)> = (0..frames.len() - PAIR_GAP)
        .into_par_iter()
        .filter_map(|k| {
            let (a, b) = (profiles[k].as_ref()?, profiles[k + PAIR_GAP].as_ref()?);
            let (turn, score) = profile_turn(a, b, MAX_TURN_DEG)?;
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
