//! A visual compass: the turn between two frames from what lies above
//! the floor.
//!
//! As the robot turns, the room above the floor slides across the view.
//! A frame is reduced to a *bearing profile*: the mean brightness of the
//! rows above the horizon, per bearing (the lens's bending undone),
//! differenced along the bearings so that a change of exposure does not
//! count. The turn between two frames is the shift of bearing that lines
//! their profiles up best (normalised correlation, refined to a fraction
//! of a step). The floor's boundary plays no part, so the compass holds
//! where the boundary is hard to find; a sideways move of `s` shifts a
//! wall `d` away by about `s / d` radians, the compass's error.

use pirouette_camera::PinholeModel;

/// Bearing step of a profile, degrees.
pub const STEP_DEG: f64 = 0.1;

/// A turn whose profiles correlate below this is not trusted.
pub const MIN_CORRELATION: f64 = 0.5;

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

/// The bearing profile of an image seen through `camera` (brightness:
/// the mean of the three channels).
pub fn bearing_profile(image: &image::RgbImage, camera: &PinholeModel) -> Option<BearingProfile> {
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
        let sum: u32 = (top..bottom)
            .map(|v| image.get_pixel(u, v).0.iter().map(|&c| u32::from(c)).sum::<u32>())
            .sum();
        let mean = f64::from(sum) / (3.0 * f64::from(bottom - top));
        columns.push((r[1].atan2(r[0]).to_degrees(), mean));
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
/// `None` when no shift within `±max_turn_deg` overlaps enough (half the
/// shorter profile).
pub fn profile_turn(a: &BearingProfile, b: &BearingProfile, max_turn_deg: f64) -> Option<(f64, f64)> {
    let max_shift = (max_turn_deg / STEP_DEG).round() as i64;
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
        let (turn, score) = profile_turn(&a, &b, 15.0).unwrap();
        assert!((turn - 3.37).abs() < 0.01, "{turn}");
        assert!(score > 0.99);
        let (back, _) = profile_turn(&b, &a, 15.0).unwrap();
        assert!((back + 3.37).abs() < 0.01, "{back}");
    }
}
