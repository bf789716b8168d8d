//! The vision front end's settings and errors.

use pirouette_profile::filter::OutlierFilter;

/// Errors of the vision front end.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum VisionError {
    /// The image does not have the camera's size.
    #[error("image is {found_width}x{found_height}, the camera is {width}x{height}")]
    WrongSize {
        /// The camera's width.
        width: u32,
        /// The camera's height.
        height: u32,
        /// The image's width.
        found_width: u32,
        /// The image's height.
        found_height: u32,
    },
    /// The settings cannot be used.
    #[error("vision settings: {problem}")]
    BadConfig {
        /// What is wrong.
        problem: String,
    },
}

/// The most columns each side the line cue may pool
/// ([`VisionConfig::line_columns`]): a window wider than most images.
pub(crate) const MAX_LINE_COLUMNS: u32 = 512;

/// Settings of floor segmentation and profile building.
#[derive(Debug, Clone, PartialEq)]
pub struct VisionConfig {
    /// Width of the profile's bins, radians.
    pub bin_width_rad: f64,
    /// The lowest obstacle to detect, metres. Anything flatter (lint,
    /// reflections, scratches) is floor.
    pub min_obstacle_height_m: f64,
    /// The smallest relative brightness step, against the floor predicted
    /// from below, that counts as leaving the floor when the chromaticity
    /// stays the same.
    pub min_brightness_step: f32,
    /// The smallest relative change of chromaticity (any channel's share,
    /// after removing the brightness step) that counts as leaving the floor.
    pub min_chroma_step: f32,
    /// Steps must also exceed this many standard deviations of the image's
    /// own noise (measured per image).
    pub noise_sigmas: f32,
    /// Where a column's colour changes within one row (a sharp step), this
    /// fraction of the chromaticity step is enough to leave the floor; 1
    /// turns the edge cue off.
    pub edge_fraction: f32,
    /// Where a column's brightness alone steps by more than `edge_fraction`
    /// of its tolerance within one row, the step is an obstacle's base when
    /// the texture just above it, beyond the sensor noise, is at most this
    /// share of the floor's just below it (and the run above stays that far
    /// off the floor, as a plateau); 0 turns the texture cue off.
    pub texture_ratio: f32,
    /// Where brightness alone steps by more than this fraction of its
    /// tolerance within one row, but not by `edge_fraction` of it (a faint
    /// step), the step is an obstacle's base when it passes the texture
    /// cue's tests with the tolerances scaled by this fraction and the
    /// stricter ratio `faint_texture_ratio`. At or above `edge_fraction`
    /// the faint cue is empty.
    pub faint_step_fraction: f32,
    /// The texture ratio a faint step must meet (see
    /// `faint_step_fraction`); 0 turns the faint cue off, and so does
    /// turning the texture cue off.
    pub faint_texture_ratio: f32,
    /// Columns each side of a column over which the line cue pools the
    /// floor's grain along a candidate base's line: where the scan found no
    /// base within the soft limit, it finds a smooth surface of the
    /// floor's own brightness and hue by the grain ending along a line,
    /// with the texture cue's ratio. 0 turns it off, and so does turning
    /// the texture cue off.
    pub line_columns: u32,
    /// How fast the floor reference's level follows the floor up a column,
    /// per row.
    pub adapt_rate: f32,
    /// How fast the floor reference's trend (change per row) follows; over
    /// rows not floor the trend fades at the same rate, so coasting moves
    /// the reference by at most `trend / trend_rate`.
    pub trend_rate: f32,
    /// Share of non-floor rows needed over a candidate obstacle's expected
    /// height.
    pub run_fraction: f32,
    /// The deepest mark on the floor, metres along the floor: where the
    /// floor shows again above an obstacle's base within this depth (a
    /// strip of tape, a stain, a flat cable, or an obstacle too low for one
    /// view to tell from them), the base is undecided. The floor is known
    /// only up to it, and the scan goes on above it. 0 turns this off:
    /// every base is decided as an obstacle.
    pub mark_depth_m: f32,
    /// Outlier filter over the profile's bins.
    pub filter: OutlierFilter,
}

impl Default for VisionConfig {
    /// - `bin_width_rad`: 1°, the paper's choice;
    /// - `min_obstacle_height_m`: 2 cm, well above a speck's thickness and
    ///   below the lowest obstacle a small robot must avoid;
    /// - `min_brightness_step`: 18 %. Shading, soft shadows and the tonal
    ///   patches of one floor material change brightness but hardly
    ///   chromaticity, by up to about a tenth across an edge; a different
    ///   surface of the same hue must differ by more to be seen;
    /// - `min_chroma_step`: 5 %: a change of material shows in
    ///   chromaticity, which lighting leaves nearly unchanged;
    /// - `noise_sigmas`: 5, so noise alone almost never crosses it;
    /// - `edge_fraction`: 0.5. Lighting (shade, the floor's tonal patches)
    ///   changes brightness and hardly chromaticity, a change of material
    ///   changes both; where the change happens within one row (a wall's
    ///   base is that sharp, the floor track follows gradual changes), half
    ///   the chromaticity step is trusted as material. The run above must
    ///   still stay that far off the floor, and the brightness tolerance
    ///   and the noise allowance are unchanged;
    /// - `texture_ratio`: 0.6. Shading, seams and tonal patches change a
    ///   floor's brightness but leave its texture: the same grain lies on
    ///   both sides of the step. A smooth surface that meets a textured
    ///   floor (a painted wall in shade, as grey as the floor) has less
    ///   texture above its base than the floor below. The texture windows
    ///   hold about 30 independent samples a side, whose medians are known
    ///   to about 14 %: 0.6 lies three standard errors of the ratio below
    ///   one. It finds most such walls, but near the soft limit only in
    ///   stretches: good evidence for a map, which fuses every sighting,
    ///   but not for matching two views, where a wall seen in one and
    ///   missed in the next reads as a contradiction. Turns are therefore
    ///   verified on profiles without it ([`VisionConfig::for_matching`]);
    /// - `faint_step_fraction`: a third (6 % with the default tolerance).
    ///   A wall's base blurred over two rows, or a wall only a little darker
    ///   than the floor, steps by less than half the tolerance within a
    ///   row; the floor's own grain moves a three-pixel mean by 2-5 % a
    ///   row, so a third is the least step that stands out of it;
    /// - `faint_texture_ratio`: a third. A faint step says little by itself
    ///   that a surface ends there, so the texture drop must say it: a
    ///   third lies five standard errors of the ratio below one (as the
    ///   noise test's five standard deviations), where 0.6 lies three;
    /// - `line_columns`: 8, a window of 17 columns (about 3° of view at
    ///   320 pixels across): wide enough that the floor's own smooth
    ///   patches seldom fill it, narrow enough for a wall seen between two
    ///   obstacles. The line cue finds the bases of light walls that the
    ///   column cues miss near the soft limit, but like the texture cue in
    ///   stretches, so it adds walls to maps and is off where views are
    ///   compared ([`VisionConfig::for_comparing`]);
    /// - `adapt_rate`: 0.25 per row (a memory of about four rows);
    /// - `trend_rate`: 0.1 per row: the brightness trend of the floor
    ///   (vignetting, light fall-off) changes slowly. A trend learnt over
    ///   about ten rows is trusted for about as many: coasting over a speck
    ///   or a strip of tape, the reference moves by at most ten rows' worth
    ///   of it, where a floor that brightens fast at the image's bottom and
    ///   then levels off would leave a steady trend far above the floor;
    /// - `run_fraction`: 0.75, tolerating noise inside an obstacle;
    /// - `mark_depth_m`: 0, off. At 25 cm (deeper than tape, cables and
    ///   most stains) the scoreboard's renders lost as much as they
    ///   gained: fewer free bins given a range, but a lower map F1 on some
    ///   rooms and larger heading errors of some place answers
    ///   (`BENCHMARKS.md`). An obstacle of height `H` at range `r`, seen
    ///   from a camera at height `h`, hides the floor behind it out to
    ///   `r·h/(h − H)` (all of it when `H ≥ h`), so only obstacles lower
    ///   than `h·d/(r + d)` show the floor again within the depth `d`: a
    ///   ninth of `h` at 2 m for 25 cm;
    /// - `filter`: the robust 3-bin median.
    fn default() -> Self {
        Self {
            bin_width_rad: 1f64.to_radians(),
            min_obstacle_height_m: 0.02,
            min_brightness_step: 0.18,
            min_chroma_step: 0.05,
            noise_sigmas: 5.0,
            edge_fraction: 0.5,
            texture_ratio: 0.6,
            faint_step_fraction: 1.0 / 3.0,
            faint_texture_ratio: 1.0 / 3.0,
            line_columns: 8,
            adapt_rate: 0.25,
            trend_rate: 0.1,
            run_fraction: 0.75,
            mark_depth_m: 0.0,
            filter: OutlierFilter::Median3,
        }
    }
}

impl VisionConfig {
    /// Whether faint steps of brightness alone are tested (see
    /// [`VisionConfig::faint_step_fraction`]): a part of the texture cue.
    pub fn faint_steps(&self) -> bool {
        self.texture_ratio > 0.0
            && self.faint_texture_ratio > 0.0
            && self.faint_step_fraction < self.edge_fraction
    }

    /// Whether the line cue is on (see [`VisionConfig::line_columns`]): a
    /// part of the texture cue.
    pub fn line_cue(&self) -> bool {
        self.texture_ratio > 0.0 && self.line_columns > 0
    }

    /// The settings of the profiles that two views are compared on (a
    /// sweep registered against the map of the others, the intermittent
    /// cue of turn matching): these with faint steps and the line cue off,
    /// or `None` where they are off already. Both find faint walls in
    /// stretches, as the texture cue does but more so: evidence for a map,
    /// which fuses every sighting, but where two views are compared a wall
    /// found in one and missed in the other reads as a contradiction.
    pub fn for_comparing(&self) -> Option<Self> {
        (self.faint_steps() || self.line_cue()).then(|| Self {
            faint_texture_ratio: 0.0,
            line_columns: 0,
            ..self.clone()
        })
    }

    /// The settings of the profiles that verify turns: these with the
    /// texture cue off (its faint steps too), or `None` where it already
    /// is. Turn matching compares two views bin by bin and needs a detector that sees the
    /// same wall in both; the texture cue finds faint walls only in
    /// stretches near the soft limit, so its walls come and go between
    /// views. Every other cue is kept.
    pub fn for_matching(&self) -> Option<Self> {
        (self.texture_ratio > 0.0).then(|| Self {
            texture_ratio: 0.0,
            ..self.clone()
        })
    }

    /// Whether the settings can be used: every field within the range its
    /// doc gives.
    pub fn validate(&self) -> Result<(), VisionError> {
        let bad = |p: &str| Err(VisionError::BadConfig { problem: p.into() });
        if !(self.bin_width_rad.is_finite() && self.bin_width_rad > 0.0) {
            return bad("bin width must be positive");
        }
        if !(self.min_obstacle_height_m.is_finite() && self.min_obstacle_height_m >= 0.0) {
            return bad("min obstacle height must be non-negative");
        }
        let unit = |x: f32| x > 0.0 && x <= 1.0;
        if !(unit(self.adapt_rate)
            && unit(self.trend_rate)
            && unit(self.run_fraction)
            && unit(self.edge_fraction)
            && unit(self.faint_step_fraction))
        {
            return bad("adapt rate, trend rate, run fraction, edge fraction and faint step fraction must be in (0, 1]");
        }
        if !(self.mark_depth_m.is_finite() && self.mark_depth_m >= 0.0) {
            return bad("mark depth must be non-negative");
        }
        if !(self.texture_ratio >= 0.0 && self.texture_ratio < 1.0) {
            return bad("texture ratio must be in [0, 1)");
        }
        if !(self.faint_texture_ratio >= 0.0 && self.faint_texture_ratio < 1.0) {
            return bad("faint texture ratio must be in [0, 1)");
        }
        if self.line_columns > MAX_LINE_COLUMNS {
            return Err(VisionError::BadConfig {
                problem: format!(
                    "line columns {} is more than {MAX_LINE_COLUMNS}: the line cue pools twice that many columns",
                    self.line_columns
                ),
            });
        }
        if !(self.min_brightness_step >= 0.0 && self.min_chroma_step >= 0.0 && self.noise_sigmas >= 0.0) {
            return bad("brightness and chroma steps and noise multiples must be non-negative");
        }
        Ok(())
    }
}
