//! A sweep's profile kept compactly for metric refinement.

use pirouette_profile::Rop;
use serde::{Deserialize, Serialize};

/// A 360° profile at four bytes per bin: the range in millimetres, with
/// [`StoredProfile::UNSEEN`] for a bin never seen and
/// [`StoredProfile::NO_RETURN`] for one with no obstacle in sight. Ranges
/// round to the millimetre and are capped below 65.5 m. Each bin's colour
/// takes the other two bytes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StoredProfile {
    /// Bearing of the start of bin 0, radians.
    pub bearing_start_rad: f64,
    /// Width of every bin, radians.
    pub bin_width_rad: f64,
    /// The soft range limit, metres.
    pub max_range_m: f32,
    /// Range per bin.
    pub range_mm: Vec<u16>,
    /// Colour per bin, [`crate::relative_chroma`] quantised by
    /// [`crate::quantise_chroma`]; `[0, 0]` where a bin has none.
    pub chroma: Vec<[u8; 2]>,
}

impl StoredProfile {
    /// A bin never seen.
    pub const UNSEEN: u16 = 0;
    /// A bin seen with no obstacle in sight.
    pub const NO_RETURN: u16 = u16::MAX;

    /// The compact form of a profile (the floor's reach is not kept).
    pub fn from_rop(rop: &Rop) -> Self {
        let range_mm = rop
            .range_m
            .iter()
            .map(|&r| {
                if r.is_nan() {
                    Self::UNSEEN
                } else if r.is_infinite() {
                    Self::NO_RETURN
                } else {
                    (r * 1000.0).round().clamp(1.0, f32::from(Self::NO_RETURN - 1)) as u16
                }
            })
            .collect();
        let chroma = crate::relative_chroma(rop)
            .into_iter()
            .map(|uv| uv.map_or([0, 0], crate::quantise_chroma))
            .collect();
        Self {
            chroma,
            bearing_start_rad: rop.bearing_start_rad,
            bin_width_rad: rop.bin_width_rad,
            max_range_m: rop.max_range_m,
            range_mm,
        }
    }

    /// The profile back, at millimetre ranges, without colour (see
    /// [`StoredProfile::chroma_of`]); `None` where its settings make no
    /// profile.
    pub fn to_rop(&self) -> Option<Rop> {
        let usable = self.bearing_start_rad.is_finite()
            && self.bin_width_rad.is_finite()
            && self.bin_width_rad > 0.0
            && self.max_range_m.is_finite()
            && self.max_range_m > 0.0;
        if !usable || self.chroma.len() != self.range_mm.len() {
            return None;
        }
        let mut rop = Rop::empty(
            self.bearing_start_rad,
            self.bin_width_rad,
            self.range_mm.len(),
            self.max_range_m,
        );
        for (slot, &mm) in rop.range_m.iter_mut().zip(&self.range_mm) {
            *slot = match mm {
                Self::UNSEEN => f32::NAN,
                Self::NO_RETURN => f32::INFINITY,
                mm => f32::from(mm) / 1000.0,
            };
        }
        Some(rop)
    }
}

impl StoredProfile {
    /// Bin `i`'s relative log-chromaticity, where it has one.
    pub fn chroma_of(&self, i: usize) -> Option<[f64; 2]> {
        self.chroma
            .get(i)
            .filter(|&&q| q != [0, 0])
            .map(|&q| crate::dequantise_chroma(q))
    }
}
