//! The ROP type.

use serde::{Deserialize, Serialize};

/// Errors building a profile.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ProfileError {
    /// The bin width is not a positive finite angle.
    #[error("bin width {bin_width_rad} rad is not a positive finite angle")]
    BadBinWidth {
        /// The rejected width.
        bin_width_rad: f64,
    },
    /// The bearing interval is empty or not finite.
    #[error("bearing interval [{start_rad}, {end_rad}] rad is empty or not finite")]
    BadInterval {
        /// Start of the interval.
        start_rad: f64,
        /// End of the interval.
        end_rad: f64,
    },
    /// The soft range limit is not a positive number.
    #[error("max range {max_range_m} m is not positive")]
    BadMaxRange {
        /// The rejected limit.
        max_range_m: f32,
    },
}

/// An obstacle colour normalised for lighting: the chromaticity scaled so
/// that the brightest channel is 255. Two views of one surface under
/// brighter or dimmer light give the same tag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ColourTag(pub [u8; 3]);

impl ColourTag {
    /// The tag of a linear RGB colour (any scale); `None` for black.
    pub fn from_rgb(rgb: [f32; 3]) -> Option<Self> {
        let max = rgb[0].max(rgb[1]).max(rgb[2]);
        if max.is_nan() || max <= 0.0 {
            return None;
        }
        let s = 255.0 / max;
        Some(ColourTag(
            rgb.map(|c| (c.max(0.0) * s).round().clamp(0.0, 255.0) as u8),
        ))
    }

    /// Chromaticity `(r, g)` with `r + g + b = 1`.
    pub fn chromaticity(&self) -> [f32; 2] {
        let [r, g, b] = self.0.map(f32::from);
        let sum = (r + g + b).max(1.0);
        [r / sum, g / sum]
    }
}

/// A Radial Obstacle Profile.
///
/// Bin `i` covers bearings `[start + i·w, start + (i+1)·w)` (radians,
/// counter-clockwise from the robot's forward axis). Each bin holds the range
/// to the nearest obstacle seen in it:
/// - a finite range (which may exceed `max_range_m`: kept for matching, but
///   never evidence of an obstacle; see [`Rop::reliable`]);
/// - `+∞`: the bin was seen and no obstacle was found in sight;
/// - NaN: the bin was not seen at all.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Rop {
    /// Bearing of the start of bin 0, radians.
    pub bearing_start_rad: f64,
    /// Width of every bin, radians.
    pub bin_width_rad: f64,
    /// Range per bin, metres (finite, `+∞` or NaN as above).
    pub range_m: Vec<f32>,
    /// Colour tag per bin, where an obstacle was seen.
    pub colour: Vec<Option<ColourTag>>,
    /// The soft range limit, metres.
    pub max_range_m: f32,
    /// How far along each bin the floor was seen, metres: `+∞` (as built
    /// by [`Rop::empty`]) where as far as the range says; shorter where a
    /// bin with nothing in sight was seen only nearer (at the sides of a
    /// camera's view, where only the near floor lies, or up to a mark on
    /// the floor that one view cannot tell from a low obstacle), or where
    /// an obstacle was seen beyond such a mark. Read it with
    /// [`Rop::free_reach`].
    #[serde(default)]
    pub free_m: Vec<f32>,
}

impl Rop {
    /// An empty profile (every bin unseen) whose bins are centred on
    /// multiples of `bin_width_rad` and cover `[min_bearing_rad,
    /// max_bearing_rad]`.
    pub fn covering(
        min_bearing_rad: f64,
        max_bearing_rad: f64,
        bin_width_rad: f64,
        max_range_m: f32,
    ) -> Result<Self, ProfileError> {
        if !(bin_width_rad.is_finite() && bin_width_rad > 0.0) {
            return Err(ProfileError::BadBinWidth { bin_width_rad });
        }
        if !(min_bearing_rad.is_finite() && max_bearing_rad.is_finite()) || max_bearing_rad < min_bearing_rad
        {
            return Err(ProfileError::BadInterval {
                start_rad: min_bearing_rad,
                end_rad: max_bearing_rad,
            });
        }
        if max_range_m.is_nan() || max_range_m <= 0.0 {
            return Err(ProfileError::BadMaxRange { max_range_m });
        }
        let first = (min_bearing_rad / bin_width_rad + 0.5).floor();
        let last = (max_bearing_rad / bin_width_rad + 0.5).floor();
        let bins = (last - first) as usize + 1;
        Ok(Self::empty(
            (first - 0.5) * bin_width_rad,
            bin_width_rad,
            bins,
            max_range_m,
        ))
    }

    /// A profile of `bins` unseen bins starting at `bearing_start_rad`.
    pub fn empty(bearing_start_rad: f64, bin_width_rad: f64, bins: usize, max_range_m: f32) -> Self {
        Self {
            bearing_start_rad,
            bin_width_rad,
            range_m: vec![f32::NAN; bins],
            colour: vec![None; bins],
            max_range_m,
            free_m: vec![f32::INFINITY; bins],
        }
    }

    /// Number of bins.
    pub fn len(&self) -> usize {
        self.range_m.len()
    }

    /// True when there are no bins.
    pub fn is_empty(&self) -> bool {
        self.range_m.is_empty()
    }

    /// Bearing of the centre of bin `i`, radians.
    pub fn bin_centre_rad(&self, i: usize) -> f64 {
        self.bearing_start_rad + (i as f64 + 0.5) * self.bin_width_rad
    }

    /// The bin holding `bearing_rad`, if inside the profile. Bearings are
    /// compared directly (no wrapping), so a 360° profile should start at
    /// −π.
    pub fn bin_of(&self, bearing_rad: f64) -> Option<usize> {
        let k = ((bearing_rad - self.bearing_start_rad) / self.bin_width_rad).floor();
        (k >= 0.0 && (k as usize) < self.len()).then_some(k as usize)
    }

    /// Records an observation in bin of `bearing_rad`: keeps the nearest
    /// range, with its colour. Observations outside the profile are ignored.
    pub fn insert(&mut self, bearing_rad: f64, range_m: f32, colour: Option<ColourTag>) {
        if let Some(i) = self.bin_of(bearing_rad) {
            let old = self.range_m[i];
            if old.is_nan() || range_m < old {
                self.range_m[i] = range_m;
                self.colour[i] = if range_m.is_finite() { colour } else { None };
            }
        }
    }

    /// The range of bin `i` when it is evidence of an obstacle: finite and
    /// within the soft range limit.
    ///
    /// # Panics
    /// When `i >= self.len()`.
    pub fn reliable(&self, i: usize) -> Option<f32> {
        let r = self.range_m[i];
        (r.is_finite() && r <= self.max_range_m).then_some(r)
    }

    /// How far along bin `i` the floor was seen, metres (`+∞` when as far
    /// as its range says; see [`Rop::free_m`]).
    pub fn free_reach(&self, i: usize) -> f32 {
        self.free_m.get(i).copied().unwrap_or(f32::INFINITY)
    }

    /// The colour tag of bin `i` where its range is reliable.
    ///
    /// # Panics
    /// When `i >= self.len()`.
    pub fn reliable_colour(&self, i: usize) -> Option<ColourTag> {
        self.reliable(i).and(self.colour[i])
    }

    /// True when bin `i` was seen (finite range or `+∞`).
    ///
    /// # Panics
    /// When `i >= self.len()`.
    pub fn seen(&self, i: usize) -> bool {
        !self.range_m[i].is_nan()
    }

    /// Bin width in degrees, for the edges.
    pub fn bin_width_deg(&self) -> f64 {
        self.bin_width_rad.to_degrees()
    }

    /// Bearing of the start of bin 0 in degrees, for the edges.
    pub fn bearing_start_deg(&self) -> f64 {
        self.bearing_start_rad.to_degrees()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn covering_centres_bins_on_multiples() {
        let w = 1f64.to_radians();
        let rop = Rop::covering(-36.2f64.to_radians(), 36.2f64.to_radians(), w, 0.9).unwrap();
        assert!((rop.bearing_start_deg() + 36.5).abs() < 1e-9);
        assert_eq!(rop.len(), 73);
        assert!((rop.bin_centre_rad(36)).abs() < 1e-12);
    }

    #[test]
    fn insert_keeps_nearest_and_soft_limit_hides_far() {
        let mut rop = Rop::covering(-0.1, 0.1, 0.05, 0.9).unwrap();
        let i = rop.bin_of(0.0).unwrap();
        rop.insert(0.0, 0.5, Some(ColourTag([255, 0, 0])));
        rop.insert(0.01, 0.7, None);
        assert_eq!(rop.reliable(i), Some(0.5));
        assert_eq!(rop.reliable_colour(i), Some(ColourTag([255, 0, 0])));
        let j = rop.bin_of(0.06).unwrap();
        rop.insert(0.06, 1.3, None);
        assert!(rop.seen(j) && rop.reliable(j).is_none());
        let k = rop.bin_of(-0.06).unwrap();
        assert!(!rop.seen(k));
    }

    #[test]
    fn colour_tag_ignores_brightness() {
        let a = ColourTag::from_rgb([200.0, 40.0, 40.0]).unwrap();
        let b = ColourTag::from_rgb([100.0, 20.0, 20.0]).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.0, [255, 51, 51]);
        assert!(ColourTag::from_rgb([0.0; 3]).is_none());
    }

    #[test]
    fn bad_arguments_are_errors() {
        assert!(matches!(
            Rop::covering(0.0, 1.0, 0.0, 1.0),
            Err(ProfileError::BadBinWidth { .. })
        ));
        assert!(matches!(
            Rop::covering(1.0, 0.0, 0.1, 1.0),
            Err(ProfileError::BadInterval { .. })
        ));
        assert!(matches!(
            Rop::covering(0.0, 1.0, 0.1, -1.0),
            Err(ProfileError::BadMaxRange { .. })
        ));
    }
}
