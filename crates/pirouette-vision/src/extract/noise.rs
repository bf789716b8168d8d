//! The image's noise, measured in its bottom rows: the scale of every
//! floor test's allowance.

use crate::scan::smoothed;

/// Standard deviation of one pixel's grey (the mean of its channels); never
/// below the quantisation of a mean of three 8-bit values.
pub(super) fn grey_noise_sigma(px: &[u8], width: u32, height: u32) -> f32 {
    second_difference_sigma(width, height, 0.29 / 3f32.sqrt(), |u, v| {
        let i = (v * width + u) as usize * 3;
        [(px[i] as f32 + px[i + 1] as f32 + px[i + 2] as f32) / 3.0]
    })
}

/// Standard deviation of the noise of a 3-pixel average along the scan
/// direction, per channel; never below the 8-bit quantisation step's.
pub(super) fn noise_sigma(px: &[u8], width: u32, height: u32) -> f32 {
    second_difference_sigma(width, height, 0.29, |u, v| smoothed(px, width, u, v))
}

/// The noise's standard deviation in some values per pixel (`values(u,
/// v)`, one or more), from their vertical second differences in the
/// bottom rows (which cancel steady brightness trends), robustly: a second
/// difference of independent values has variance 6σ², and 1.4826 times
/// the median absolute value is σ for normal noise. Never below `least`;
/// 1 where the image has no such rows.
fn second_difference_sigma<const K: usize>(
    width: u32,
    height: u32,
    least: f32,
    values: impl Fn(u32, u32) -> [f32; K],
) -> f32 {
    const ROWS: u32 = 16;
    let mut d2 = Vec::with_capacity(2048);
    let top = height.saturating_sub(ROWS).max(1);
    for v in (top..height - 1).step_by(2) {
        for u in (width / 4..3 * width / 4).step_by(3) {
            let (a, b, c) = (values(u, v - 1), values(u, v), values(u, v + 1));
            for k in 0..K {
                d2.push((a[k] - 2.0 * b[k] + c[k]).abs());
            }
        }
    }
    if d2.is_empty() {
        return 1.0;
    }
    let mid = d2.len() / 2;
    let (_, med, _) = d2.select_nth_unstable_by(mid, f32::total_cmp);
    (1.4826 * *med / 6f32.sqrt()).max(least)
}
