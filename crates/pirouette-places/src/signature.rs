//! A place's signature: the DCT of its 360° sweep, a rotation-invariant key
//! and colour tags per sector.

use crate::PlacesError;
use pirouette_profile::Rop;
use rustdct::{Dct2, DctPlanner};
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};
use std::sync::Arc;

/// Length of the rotation-invariant key: the mean of the conditioned
/// profile and the amplitudes of its first eleven harmonics (periods of
/// 360° down to about 33°). A k-d tree keeps its edge over a linear scan
/// only in few dimensions.
pub const KEY_DIMS: usize = 12;

/// How a sweep becomes a signature.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SignatureConfig {
    /// DCT coefficients kept (the paper's K).
    pub coefficients: usize,
    /// Samples round the circle that the sweep is resampled to before the
    /// transforms.
    pub samples: usize,
    /// Angular sectors of the colour tags.
    pub sectors: usize,
    /// The least share of the circle a sweep must have seen to be a place
    /// or a query.
    pub min_coverage: f64,
}

impl Default for SignatureConfig {
    /// K = 24 as in the paper; 360 samples (1° each, finer than any
    /// profile feature 24 coefficients keep); 16 colour sectors of 22.5°;
    /// three quarters of the circle seen.
    fn default() -> Self {
        Self {
            coefficients: 24,
            samples: 360,
            sectors: 16,
            min_coverage: 0.75,
        }
    }
}

/// The most samples round the circle (a tenth of a degree each).
pub const MAX_SAMPLES: usize = 3600;

impl SignatureConfig {
    /// Refuses settings that cannot make a signature.
    pub fn check(&self) -> Result<(), PlacesError> {
        let bad = |problem: String| Err(PlacesError::BadConfig { problem });
        if !(2 * KEY_DIMS..=MAX_SAMPLES).contains(&self.samples) {
            return bad(format!(
                "samples {} outside {}..={MAX_SAMPLES}",
                self.samples,
                2 * KEY_DIMS
            ));
        }
        if !(1..=self.samples).contains(&self.coefficients) {
            return bad(format!(
                "coefficients {} outside 1..={}",
                self.coefficients, self.samples
            ));
        }
        if !(1..=32).contains(&self.sectors) {
            return bad(format!("sectors {} outside 1..=32", self.sectors));
        }
        if !(self.min_coverage > 0.0 && self.min_coverage <= 1.0) {
            return bad(format!("min coverage {} outside (0, 1]", self.min_coverage));
        }
        Ok(())
    }

    /// Bytes of one signature as the index stores it: the key and the DCT
    /// as `f32`, the sectors-seen mask, two bytes per colour sector.
    pub fn signature_bytes(&self) -> usize {
        4 * (KEY_DIMS + self.coefficients) + 4 + 2 * self.sectors
    }

    /// Samples of a profile rebuilt from the DCT for the shift search:
    /// four per half-period of the finest coefficient kept.
    pub fn rebuilt_samples(&self) -> usize {
        (4 * self.coefficients).clamp(16, self.samples)
    }
}

/// Colour tags per angular sector, normalised for lighting.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ColourSectors {
    /// Bit `j` set where sector `j` holds a tag.
    pub seen: u32,
    /// Per sector, the median log-chromaticity `(ln R/G, ln B/G)` of its
    /// obstacles less the sweep's mean, in steps of 1/32 about 128 (so
    /// ±4 in all); `[0, 0]` where the sector holds no tag.
    pub chroma: Vec<[u8; 2]>,
}

/// A place's signature.
///
/// Stored in [`SignatureConfig::signature_bytes`] bytes: 180 with the
/// defaults (48 of key, 96 of DCT, 4 + 32 of colour).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Signature {
    /// The rotation-invariant key (metres): the mean and the first
    /// harmonics' amplitudes of the conditioned profile.
    pub key: [f32; KEY_DIMS],
    /// The first K orthonormal DCT-II coefficients of the conditioned
    /// profile (metres).
    pub dct: Vec<f32>,
    /// Colour tags.
    pub colour: ColourSectors,
}

/// The transforms of one [`SignatureConfig`], planned once.
#[derive(Clone)]
pub struct Transforms {
    config: SignatureConfig,
    dct2: Arc<dyn Dct2<f64>>,
    /// `(cos, sin)` of `2π·m·j/n` for the key's harmonics, `m`-major.
    harmonics: Vec<(f64, f64)>,
    /// The DCT basis at the rebuilt samples: `basis[r·K + k]`.
    basis: Vec<f32>,
    fft: Arc<dyn Fft<f32>>,
    ifft: Arc<dyn Fft<f32>>,
}

impl std::fmt::Debug for Transforms {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Transforms")
            .field("config", &self.config)
            .finish()
    }
}

impl Transforms {
    /// Plans the transforms of `config`.
    pub fn new(config: &SignatureConfig) -> Result<Self, PlacesError> {
        config.check()?;
        let n = config.samples;
        let k = config.coefficients;
        let dct2 = DctPlanner::new().plan_dct2(n);
        let harmonics = (0..KEY_DIMS)
            .flat_map(|m| (0..n).map(move |j| (TAU * (m * j) as f64 / n as f64).sin_cos()))
            .map(|(s, c)| (c, s))
            .collect();
        let r = config.rebuilt_samples();
        let mut basis = Vec::with_capacity(r * k);
        for ri in 0..r {
            // Rebuilt sample `ri` sits at the centre of its 1/r of the
            // circle, in the conditioned profile's sample index.
            let p = (ri as f64 + 0.5) * n as f64 / r as f64 - 0.5;
            for ki in 0..k {
                basis.push(
                    (dct_norm(ki, n) * (PI * ki as f64 * (2.0 * p + 1.0) / (2 * n) as f64).cos()) as f32,
                );
            }
        }
        let mut planner = FftPlanner::new();
        Ok(Self {
            config: config.clone(),
            dct2,
            harmonics,
            basis,
            fft: planner.plan_fft_forward(r),
            ifft: planner.plan_fft_inverse(r),
        })
    }

    /// The settings planned for.
    pub fn config(&self) -> &SignatureConfig {
        &self.config
    }

    /// The signature of a 360° sweep (bearings relative to its first
    /// frame's heading).
    ///
    /// The profile is conditioned first (see [`condition`]); a sweep that
    /// saw less than [`SignatureConfig::min_coverage`] of the circle is
    /// refused.
    pub fn signature(&self, sweep: &Rop) -> Result<Signature, PlacesError> {
        let values = condition(sweep, &self.config)?;
        let n = values.len();
        // The key: amplitudes of the first harmonics, which a rotation
        // (a circular shift of the samples) leaves alone.
        let mut key = [0f32; KEY_DIMS];
        for (m, slot) in key.iter_mut().enumerate() {
            let row = &self.harmonics[m * n..(m + 1) * n];
            let (re, im) = values
                .iter()
                .zip(row)
                .fold((0.0, 0.0), |(re, im), (v, (c, s))| (re + v * c, im - v * s));
            let scale = if m == 0 { 1.0 } else { 2.0 };
            *slot = (scale * re.hypot(im) / n as f64) as f32;
        }
        // The DCT, orthonormal, truncated to K.
        let mut buf = values;
        self.dct2.process_dct2(&mut buf);
        let dct = buf[..self.config.coefficients]
            .iter()
            .enumerate()
            .map(|(k, c)| (c * dct_norm(k, n)) as f32)
            .collect();
        Ok(Signature {
            key,
            dct,
            colour: colour_sectors(sweep, self.config.sectors),
        })
    }

    /// The profile rebuilt from K DCT coefficients at
    /// [`SignatureConfig::rebuilt_samples`] points round the circle.
    pub fn rebuild(&self, dct: &[f32], out: &mut Vec<f32>) {
        let k = self.config.coefficients;
        out.clear();
        out.extend(
            self.basis
                .chunks_exact(k)
                .map(|row| row.iter().zip(dct).map(|(b, c)| b * c).sum::<f32>()),
        );
    }

    /// The spectrum of a rebuilt profile, for [`Transforms::best_shifts`].
    pub fn spectrum(&self, rebuilt: &[f32]) -> Vec<Complex<f32>> {
        let mut spec: Vec<Complex<f32>> = rebuilt.iter().map(|&v| Complex::new(v, 0.0)).collect();
        self.fft.process(&mut spec);
        spec
    }

    /// The rotations of a query relative to a stored place that best line
    /// up their rebuilt profiles (`query[r] ≈ stored[r + s]`): the
    /// deepest `count` local minima of the RMS difference over the
    /// circular shifts, each radians in `(-π, π]` with the RMS difference
    /// there (metres), best first. The query is given by its rebuilt
    /// profile and [`Transforms::spectrum`]; the differences at every
    /// shift come from one circular cross-correlation, and each minimum is
    /// refined by a parabola through it and its neighbours.
    pub fn best_shifts(
        &self,
        query: &[f32],
        query_spectrum: &[Complex<f32>],
        stored: &[f32],
        count: usize,
    ) -> Vec<(f64, f32)> {
        let r = query.len();
        let mut spec = self.spectrum(stored);
        for (s, q) in spec.iter_mut().zip(query_spectrum) {
            *s *= q.conj();
        }
        self.ifft.process(&mut spec);
        let energy: f32 =
            query.iter().map(|v| v * v).sum::<f32>() + stored.iter().map(|v| v * v).sum::<f32>();
        // Sum of squared differences at each shift.
        let ssd: Vec<f32> = spec
            .iter()
            .map(|c| (energy - 2.0 * c.re / r as f32).max(0.0))
            .collect();
        let at = |s: usize| ssd[s % r];
        let mut minima: Vec<usize> = (0..r)
            .filter(|&s| at(s) <= at(s + r - 1) && at(s) < at(s + 1))
            .collect();
        minima.sort_by(|&a, &b| at(a).total_cmp(&at(b)).then(a.cmp(&b)));
        minima.truncate(count);
        minima
            .into_iter()
            .map(|best| {
                let (lo, mid, hi) = (at(best + r - 1), at(best), at(best + 1));
                let curvature = lo - 2.0 * mid + hi;
                let offset = if curvature > 0.0 {
                    (0.5 * (lo - hi) / curvature).clamp(-0.5, 0.5)
                } else {
                    0.0
                };
                let rotation = pirouette_geom::wrap_angle((best as f64 + f64::from(offset)) * TAU / r as f64);
                (rotation, (mid / r as f32).sqrt())
            })
            .collect()
    }
}

/// The orthonormal scale of DCT-II coefficient `k` of `n` samples.
fn dct_norm(k: usize, n: usize) -> f64 {
    if k == 0 {
        (1.0 / n as f64).sqrt()
    } else {
        (2.0 / n as f64).sqrt()
    }
}

/// A sweep as `config.samples` values round the circle, sample `j`
/// covering bearings `[j, j+1)·360°/n` from the first frame's heading.
///
/// Each sample holds the nearest range of the bins it overlaps, clamped to
/// the sweep's soft range limit: a bin with no obstacle within range
/// (`+∞`, or a range beyond the limit) enters as the limit, so that open
/// floor reads as far. Bins never seen (NaN) do not enter; a sample none
/// of whose bins was seen is unseen, and unseen samples are filled by
/// linear interpolation round the circle between the seen samples on
/// either side. A sweep that saw less than `config.min_coverage` of the
/// samples is refused.
pub fn condition(sweep: &Rop, config: &SignatureConfig) -> Result<Vec<f64>, PlacesError> {
    let n = config.samples;
    let limit = sweep.max_range_m;
    if !(limit.is_finite() && limit > 0.0) {
        return Err(PlacesError::BadProfile {
            problem: format!("soft range limit {limit} m"),
        });
    }
    let step = TAU / n as f64;
    let mut values = vec![f64::NAN; n];
    for i in 0..sweep.len() {
        let range = sweep.range_m[i];
        if range.is_nan() {
            continue;
        }
        let v = f64::from(range.clamp(0.0, limit));
        let lo = (sweep.bearing_start_rad + i as f64 * sweep.bin_width_rad).rem_euclid(TAU) / step;
        let span = (sweep.bin_width_rad / step).max(0.0);
        // Every sample the bin overlaps (at least the one its start is in).
        let first = lo.floor() as usize;
        let count = ((lo + span).ceil() as usize).saturating_sub(first).clamp(1, n);
        for j in first..first + count {
            let slot = &mut values[j % n];
            if slot.is_nan() || v < *slot {
                *slot = v;
            }
        }
    }
    let seen = values.iter().filter(|v| !v.is_nan()).count();
    let coverage = seen as f64 / n as f64;
    if coverage < config.min_coverage {
        return Err(PlacesError::IncompleteSweep {
            coverage,
            needed: config.min_coverage,
        });
    }
    fill_unseen(&mut values);
    Ok(values)
}

/// Fills NaN samples by linear interpolation round the circle between
/// the nearest seen samples on either side (at least one is seen).
fn fill_unseen(values: &mut [f64]) {
    let n = values.len();
    let Some(start) = values.iter().position(|v| !v.is_nan()) else {
        return;
    };
    // Walk once round from a seen sample, filling each gap as it ends.
    let mut last = start;
    for step in 1..=n {
        let j = (start + step) % n;
        if values[j].is_nan() {
            continue;
        }
        let gap = (j + n - last) % n;
        let gap = if gap == 0 { n } else { gap };
        for g in 1..gap {
            let t = g as f64 / gap as f64;
            values[(last + g) % n] = values[last] * (1.0 - t) + values[j] * t;
        }
        last = j;
    }
}

/// The least tagged bins for a sector to hold a tag.
const MIN_SECTOR_TAGS: usize = 3;

/// Steps of a stored log-chromaticity per unit (1/32 each).
const CHROMA_STEPS: f64 = 32.0;

/// Each bin's colour as its log-chromaticity `(ln R/G, ln B/G)` less the
/// sweep's mean: a change of brightness leaves it alone, and a change of
/// the light's colour (each channel scaled by its own gain), which shifts
/// every bin's alike, is divided out with the mean. `None` where a bin has
/// no reliable colour tag.
pub fn relative_chroma(sweep: &Rop) -> Vec<Option<[f64; 2]>> {
    let raw: Vec<Option<[f64; 2]>> = (0..sweep.len())
        .map(|i| {
            let tag = sweep.reliable_colour(i)?;
            let [r, g, b] = tag.0.map(|c| f64::from(c.max(1)).ln());
            Some([r - g, b - g])
        })
        .collect();
    let tagged = raw.iter().flatten().count().max(1) as f64;
    let mean = raw
        .iter()
        .flatten()
        .fold([0.0; 2], |m, uv| [m[0] + uv[0] / tagged, m[1] + uv[1] / tagged]);
    raw.into_iter()
        .map(|uv| uv.map(|[u, v]| [u - mean[0], v - mean[1]]))
        .collect()
}

/// A relative log-chromaticity in one byte per component: steps of 1/32
/// about 128 (±4 in all).
pub fn quantise_chroma(uv: [f64; 2]) -> [u8; 2] {
    uv.map(|c| (128.0 + c * CHROMA_STEPS).round().clamp(0.0, 255.0) as u8)
}

/// The relative log-chromaticity of [`quantise_chroma`]'s bytes.
pub fn dequantise_chroma(q: [u8; 2]) -> [f64; 2] {
    q.map(|c| (f64::from(c) - 128.0) / CHROMA_STEPS)
}

/// Colour tags per sector: the median of the [`relative_chroma`] of its
/// bins.
fn colour_sectors(sweep: &Rop, sectors: usize) -> ColourSectors {
    let mut per_sector: Vec<(Vec<f64>, Vec<f64>)> = vec![(Vec::new(), Vec::new()); sectors];
    for (i, uv) in relative_chroma(sweep).into_iter().enumerate() {
        if let Some([u, v]) = uv {
            let sector = (sweep.bin_centre_rad(i).rem_euclid(TAU) / TAU * sectors as f64) as usize % sectors;
            per_sector[sector].0.push(u);
            per_sector[sector].1.push(v);
        }
    }
    let mut seen = 0u32;
    let chroma = per_sector
        .into_iter()
        .enumerate()
        .map(|(j, (mut u, mut v))| {
            if u.len() < MIN_SECTOR_TAGS {
                return [0, 0];
            }
            seen |= 1 << j;
            quantise_chroma([median(&mut u), median(&mut v)])
        })
        .collect();
    ColourSectors { seen, chroma }
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// The mean log-chromaticity difference (`|Δ ln R/G| + |Δ ln B/G|`) between a
/// query's colour sectors and a stored place's (its mask of sectors seen
/// and its tags) at a rotation of the query
/// by `rotation_rad` relative to it, over the query's tagged sectors: each
/// against the nearest in colour of the two stored sectors it overlaps at
/// that rotation and their neighbours (so that neither a rotation between
/// sector edges nor the change of bearings between two spots a few
/// decimetres apart splits a surface's colour across a boundary); `None`
/// where fewer than `min_shared` sectors can be compared.
pub fn colour_distance(
    query: &ColourSectors,
    stored_seen: u32,
    stored: &[[u8; 2]],
    rotation_rad: f64,
    min_shared: usize,
) -> Option<f32> {
    let n = query.chroma.len();
    if n == 0 || stored.len() != n {
        return None;
    }
    // Query sector `j` lies over stored sectors `j + shift` and the next;
    // one more either side allows for the bearings' change between two
    // spots a few decimetres apart.
    let shift = (rotation_rad.rem_euclid(TAU) / TAU * n as f64).floor() as usize + n - 1;
    let (mut sum, mut shared) = (0u32, 0usize);
    for j in (0..n).filter(|j| query.seen >> j & 1 == 1) {
        let a = query.chroma[j];
        let nearest = (0..4)
            .map(|o| (j + shift + o) % n)
            .filter(|s| stored_seen >> s & 1 == 1)
            .map(|s| u32::from(a[0].abs_diff(stored[s][0])) + u32::from(a[1].abs_diff(stored[s][1])))
            .min();
        if let Some(d) = nearest {
            sum += d;
            shared += 1;
        }
    }
    (shared >= min_shared.max(1)).then(|| sum as f32 / CHROMA_STEPS as f32 / shared as f32)
}
