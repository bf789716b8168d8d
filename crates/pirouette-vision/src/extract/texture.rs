//! The texture of a window of rows: the cue that tells a smooth wall from
//! the grain of the floor below it.

/// Rows each side of a sharp step whose texture is compared.
pub(super) const TEXTURE_ROWS: u32 = 6;

/// The fewest rows above a step for a texture comparison (a wall near the
/// image's top shows only a few).
pub(super) const TEXTURE_MIN_ROWS: usize = 3;

/// Half-width of the texture window, columns: the band-pass's wide mean
/// spans `2·TEXTURE_HALF + 1` columns, and the median is taken over so
/// many centres a row.
pub(super) const TEXTURE_HALF: u32 = 7;

/// The texture of a window of rows around one column (see
/// [`texture_energy`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct Texture {
    /// The median relative band-pass value.
    median_rel: f32,
    /// The window's mean grey level, as a sum of the three channels.
    level: f32,
}

/// The median of |x| for a zero-mean normal x of unit standard deviation.
const HALF_NORMAL_MEDIAN: f32 = 0.674_49;

impl Texture {
    /// The median relative band-pass value that sensor noise alone gives,
    /// for grey noise of standard deviation `grey_sigma` per pixel (see
    /// [`band_pass_noise`]).
    pub(super) fn noise(&self, grey_sigma: f32) -> f32 {
        HALF_NORMAL_MEDIAN * band_pass_noise(grey_sigma, self.level)
    }

    /// The texture beyond the noise: independent sources add in variance,
    /// and a median of |x| scales with the standard deviation.
    pub(super) fn beyond_noise(&self, grey_sigma: f32) -> f32 {
        let n = self.noise(grey_sigma);
        (self.median_rel * self.median_rel - n * n).max(0.0).sqrt()
    }
}

/// The standard deviation of the relative band-pass that grey noise of
/// standard deviation `grey_sigma` per pixel gives where the wide mean of
/// the channel sums is `level`: the band-pass weighs the three centre
/// pixels `1/3 − 1/N` and the other `N − 3` pixels `−1/N` (`N =
/// 2·TEXTURE_HALF + 1`).
pub(super) fn band_pass_noise(grey_sigma: f32, level: f32) -> f32 {
    let n = (2 * TEXTURE_HALF + 1) as f32;
    let gain = (3.0 * (1.0 / 3.0 - 1.0 / n).powi(2) + (n - 3.0) / (n * n)).sqrt();
    // Grey is a third of the channel sum the values are relative to.
    gain * 3.0 * grey_sigma / level.max(1.0)
}

/// The band-pass at column `c` of a row whose channel sums are
/// prefix-summed in `prefix` (`prefix[k]`, the sum over the columns before
/// `k`): the three-column mean less the `2·TEXTURE_HALF + 1`-column mean,
/// and the wider mean. `c` must lie `TEXTURE_HALF` columns inside the row.
pub(super) fn band_pass(prefix: &[u32], c: usize) -> (f32, f32) {
    let half = TEXTURE_HALF as usize;
    let narrow = (prefix[c + 2] - prefix[c - 1]) as f32 / 3.0;
    let wide = (prefix[c + half + 1] - prefix[c - half]) as f32 / (2 * half + 1) as f32;
    (narrow - wide, wide)
}

/// The texture of rows `rows` around column `u`: over `2·TEXTURE_HALF + 1`
/// window centres a row, the median absolute difference between a pixel's
/// three-column mean of grey and its `2·TEXTURE_HALF + 1`-column mean,
/// relative to that wider mean. A horizontal band-pass: it ignores the
/// smooth brightness changes of shading and perspective, keeps the grain
/// and mottle of a floor, and on a smooth surface measures only the sensor
/// noise. Relative, so that a shadow, which darkens the grain with the
/// floor, leaves it unchanged; a median, so that a speck in the window
/// counts little. `None` where the image is too narrow or the rows too
/// many.
pub(super) fn texture_energy(px: &[u8], width: u32, u: u32, rows: std::ops::Range<u32>) -> Option<Texture> {
    const SPAN: usize = (4 * TEXTURE_HALF + 1) as usize;
    const CENTRES: usize = (2 * TEXTURE_HALF + 1) as usize;
    const MOST: usize = CENTRES * TEXTURE_ROWS as usize;
    let half = TEXTURE_HALF as usize;
    if (width as usize) < SPAN || rows.len() > TEXTURE_ROWS as usize {
        return None;
    }
    // The window's leftmost column, kept inside the image.
    let first = (u as usize).saturating_sub(2 * half).min(width as usize - SPAN);
    // Each relative value's bit pattern: the values are finite and not
    // negative, so their patterns sort as they do, and an integer
    // selection is cheaper than one by `total_cmp`.
    let mut keys = [0u32; MOST];
    let (mut count, mut level) = (0, 0f32);
    for v in rows {
        let row = &px[(v * width) as usize * 3..((v + 1) * width) as usize * 3];
        // Prefix sums of grey (channel sums) over the window's columns.
        let mut prefix = [0u32; SPAN + 1];
        let window = &row[first * 3..(first + SPAN) * 3];
        for (k, p) in window.chunks_exact(3).enumerate() {
            prefix[k + 1] = prefix[k] + p[0] as u32 + p[1] as u32 + p[2] as u32;
        }
        for c in half..half + CENTRES {
            let (pass, wide) = band_pass(&prefix, c);
            if wide > 0.0 {
                keys[count] = (pass.abs() / wide).to_bits();
                level += wide;
                count += 1;
            }
        }
    }
    if count == 0 {
        return None;
    }
    let (_, median, _) = keys[..count].select_nth_unstable(count / 2);
    Some(Texture {
        median_rel: f32::from_bits(*median),
        level: level / count as f32,
    })
}
