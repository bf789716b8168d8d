//! How far the paper's camera model and the pinhole model disagree.

use pirouette_camera::{CameraModel, IpmModel, PinholeModel};
use serde::Serialize;

/// Disagreement over one band of image rows.
#[derive(Debug, Clone, Serialize)]
pub struct BandDisagreement {
    /// First row of the band.
    pub v_start: u32,
    /// One past the last row of the band.
    pub v_end: u32,
    /// Median pinhole range over the band's floor pixels, metres.
    pub median_range_m: f64,
    /// Median distance between the two models' floor points, metres.
    pub median_gap_m: f64,
    /// Largest distance between the two models' floor points, metres.
    pub max_gap_m: f64,
    /// Median of (paper range − pinhole range) / pinhole range.
    pub median_range_bias: f64,
    /// Pixels compared.
    pub pixels: usize,
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Compares the two models over every pixel where both see floor within
/// `range_limit_m` of the robot, in bands of `band_rows` rows.
pub fn compare(
    paper: &IpmModel,
    pinhole: &PinholeModel,
    band_rows: u32,
    range_limit_m: f64,
) -> Vec<BandDisagreement> {
    let mut out = Vec::new();
    let n = pinhole.height;
    let band_rows = band_rows.max(1);
    for v_start in (0..n).step_by(band_rows as usize) {
        let v_end = (v_start + band_rows).min(n);
        let (mut ranges, mut gaps, mut biases) = (Vec::new(), Vec::new(), Vec::new());
        for v in v_start..v_end {
            for u in 0..pinhole.width {
                let (Some(a), Some(b)) = (
                    pinhole.pixel_to_floor(u as f64, v as f64),
                    paper.pixel_to_floor(u as f64, v as f64),
                ) else {
                    continue;
                };
                if a.norm() > range_limit_m {
                    continue;
                }
                ranges.push(a.norm());
                gaps.push(a.distance(b));
                biases.push((b.norm() - a.norm()) / a.norm());
            }
        }
        if gaps.is_empty() {
            continue;
        }
        let max_gap_m = gaps.iter().copied().fold(0.0, f64::max);
        out.push(BandDisagreement {
            v_start,
            v_end,
            median_range_m: median(&mut ranges),
            median_gap_m: median(&mut gaps),
            max_gap_m,
            median_range_bias: median(&mut biases),
            pixels: gaps.len(),
        });
    }
    out
}
