//! Tests of `extract`.

use super::*;
use crate::scan::{smoothed, FloorTrack};
use pirouette_camera::PinholeModel;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn cam() -> PinholeModel {
    PinholeModel {
        width: 320,
        height: 240,
        fx: 277.1281,
        fy: 277.1281,
        cx: 159.5,
        cy: 119.5,
        height_m: 0.1,
        tilt_rad: 25f64.to_radians(),
        mount_forward_m: 0.0,
        mount_left_m: 0.0,
        distortion: Default::default(),
    }
}

/// Dark floor below row `edge` (exact sub-pixel edge), white wall above.
fn wall_image(edge: f32) -> image::RgbImage {
    image::RgbImage::from_fn(320, 240, |_, v| {
        // Share of the pixel [v−½, v+½] above the edge.
        let a = (edge - (v as f32 - 0.5)).clamp(0.0, 1.0);
        let val = 30.0 + a * (220.0 - 30.0);
        image::Rgb([val as u8, val as u8, val as u8])
    })
}

mod lock_step;
mod marks;

/// Of the columns of `img` scanned with `config`: those whose boundary
/// lies within `tolerance` rows of `row`, and those that see no
/// obstacle.
fn base_and_clear(config: VisionConfig, img: &image::RgbImage, row: f32, tolerance: f32) -> (usize, usize) {
    let b = RopExtractor::new(&cam(), 0.9, config).boundaries(img).unwrap();
    let at_base = b
        .iter()
        .filter(|c| matches!(c, ColumnBoundary::Obstacle { row: r, .. } if (r - row).abs() < tolerance))
        .count();
    let clear = b
        .iter()
        .filter(|c| matches!(c, ColumnBoundary::Clear { .. }))
        .count();
    (at_base, clear)
}

/// A wall 12 % brighter than the floor and 3.5 % off in chromaticity
/// lies inside the floor's tolerances, (12/18)² + (3.5/5)² = 0.93: its
/// sharp base is found by the edge cue and only by it. The same colour
/// reached gradually, or a sharp step of brightness alone, stays floor.
#[test]
fn edge_cue_finds_sharp_steps_of_chromaticity_only() {
    let floor = [100.0f32, 95.0, 85.0];
    let wall = [115.9f32, 105.7, 92.0];
    let bright = floor.map(|x| x * 1.12);
    let image = |top: [f32; 3], ramp_rows: f32| {
        image::RgbImage::from_fn(320, 240, |_, v| {
            // Wall colour above row 60, blended over `ramp_rows` below.
            let a = ((60.0 + ramp_rows - v as f32) / ramp_rows.max(1.0)).clamp(0.0, 1.0);
            let a = if ramp_rows == 0.0 {
                (v < 60) as u8 as f32
            } else {
                a
            };
            image::Rgb(std::array::from_fn(|c| {
                (floor[c] + a * (top[c] - floor[c])).round() as u8
            }))
        })
    };
    let scan = |img: &image::RgbImage, edge_fraction: f32| {
        let config = VisionConfig {
            edge_fraction,
            ..VisionConfig::default()
        };
        base_and_clear(config, img, 59.5, 0.6)
    };
    let sharp = image(wall, 0.0);
    assert_eq!(scan(&sharp, 0.5), (320, 0), "the wall's base, every column");
    assert_eq!(
        scan(&sharp, 1.0),
        (0, 320),
        "without the edge cue the wall is floor"
    );
    assert_eq!(
        scan(&image(wall, 40.0), 0.5),
        (0, 320),
        "a gradual change is followed"
    );
    assert_eq!(
        scan(&image(bright, 0.0), 0.5),
        (0, 320),
        "a step of brightness alone is lighting"
    );
}

/// A grained floor (cells of 2 × 2 pixels, ±8 %) meeting at row 60
/// either a smooth surface of the floor's own hue, `shade` times as
/// bright, or (`grained_above`) the same shade with the floor's grain
/// on it (a seam, a tonal patch).
fn shaded_floor(shade: f32, grained_above: bool, grain: f32) -> image::RgbImage {
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let grain: Vec<f32> = (0..160 * 120)
        .map(|_| 1.0 - grain + 2.0 * grain * rng.random::<f32>())
        .collect();
    let noise: Vec<f32> = (0..320 * 240)
        .map(|_| 4.0 * (rng.random::<f32>() - 0.5))
        .collect();
    let floor = [100.0f32, 95.0, 85.0];
    image::RgbImage::from_fn(320, 240, |u, v| {
        let g = grain[(v / 2 * 160 + u / 2) as usize];
        let (shade, g) = if v < 60 {
            (shade, if grained_above { g } else { 1.0 })
        } else {
            (1.0, g)
        };
        let n = noise[(v * 320 + u) as usize];
        image::Rgb(floor.map(|c| (c * shade * g + n).round().clamp(0.0, 255.0) as u8))
    })
}

/// A smooth wall of the floor's own hue, 14 % darker, over a grained
/// floor: no colour test can tell it from shade, but its base is found
/// by the texture cue and only by it. Not in every column: where the
/// grain just below softens the step, it is no longer sharp within one
/// row (the cue's known weakness, a wall seen in stretches); never
/// anywhere but at the base, or one cell of grain below it where a dark
/// cell there steps faintly into the wall. The same step with the
/// floor's grain above it (a seam, a tonal patch) stays floor but in a
/// few columns.
#[test]
fn texture_cue_finds_smooth_walls_of_the_floors_hue() {
    let scan = |img: &image::RgbImage, texture_ratio: f32| {
        let config = VisionConfig {
            texture_ratio,
            ..VisionConfig::default()
        };
        base_and_clear(config, img, 60.0, 2.0)
    };
    let wall = shaded_floor(0.86, false, 0.08);
    let (found, clear) = scan(&wall, 0.6);
    assert!(found >= 240, "the wall's base in {found} of 320 columns");
    assert_eq!(found + clear, 320, "a boundary away from the wall's base");
    let (without, _) = scan(&wall, 0.0);
    assert!(
        without <= 10,
        "without the cue the wall is floor: {without} columns"
    );
    // Each column's windows hold about 30 independent samples a side:
    // by chance a few columns of a seam still pass (11 of 320 here).
    let (seam, _) = scan(&shaded_floor(0.86, true, 0.08), 0.6);
    assert!(seam <= 16, "a step with grain on both sides: {seam} columns");
}

/// A smooth wall only 8 % darker than a finely grained floor (±4 %)
/// steps by less than half the brightness tolerance: the faint cue
/// finds its base (in 186 of 320 columns here, 7 without it) where the
/// texture above drops to a third of the floor's. The same step with
/// the grain on both sides stays floor but in a few columns (9 here).
#[test]
fn faint_steps_of_smooth_walls_are_found_by_their_texture() {
    let scan = |img: &image::RgbImage, faint_texture_ratio: f32| {
        let config = VisionConfig {
            faint_texture_ratio,
            ..VisionConfig::default()
        };
        base_and_clear(config, img, 60.0, 2.0)
    };
    let wall = shaded_floor(0.92, false, 0.04);
    let (found, clear) = scan(&wall, VisionConfig::default().faint_texture_ratio);
    assert!(found >= 150, "the wall's base in {found} of 320 columns");
    assert_eq!(found + clear, 320, "a boundary away from the wall's base");
    let (without, _) = scan(&wall, 0.0);
    assert!(
        without <= 10,
        "without faint steps the wall is floor: {without} columns"
    );
    let (seam, _) = scan(
        &shaded_floor(0.92, true, 0.04),
        VisionConfig::default().faint_texture_ratio,
    );
    assert!(
        seam <= 14,
        "a faint step with grain on both sides: {seam} columns"
    );
}

/// The boundaries of `img` with the line cue's window `line_columns` (0:
/// the cue off), every other setting the default.
fn line_boundaries(img: &image::RgbImage, line_columns: u32) -> Vec<ColumnBoundary> {
    let config = VisionConfig {
        line_columns,
        ..VisionConfig::default()
    };
    RopExtractor::new(&cam(), 0.9, config).boundaries(img).unwrap()
}

/// A floor of mottled grain (cells of 3 × 3 pixels, ±10 %) under sensor
/// noise (±2 levels) whose grain ends at row 60, below a smooth surface of
/// the floor's own colour and brightness (`wall`), or runs on to the top.
fn mottled_floor(wall: bool) -> image::RgbImage {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let grain: Vec<f32> = (0..107 * 80).map(|_| 0.9 + 0.2 * rng.random::<f32>()).collect();
    let noise: Vec<f32> = (0..320 * 240)
        .map(|_| 4.0 * (rng.random::<f32>() - 0.5))
        .collect();
    let floor = [100.0f32, 95.0, 85.0];
    image::RgbImage::from_fn(320, 240, |u, v| {
        let g = if wall && v < 60 {
            1.0
        } else {
            grain[(v / 3 * 107 + u / 3) as usize]
        };
        let n = noise[(v * 320 + u) as usize];
        image::Rgb(floor.map(|c| (c * g + n).round().clamp(0.0, 255.0) as u8))
    })
}

/// A smooth wall of the floor's own brightness and hue over a grained
/// floor: no step of colour or brightness at its base (between rows 59
/// and 60), only the grain ending there. The line cue finds the base
/// within a row in all but the columns nearest the image's sides, where
/// the pooled window does not fit, and a few where it lies a few rows low
/// (a cell of grain smoother than the rest just below the base); it
/// changes no other column. Without
/// it the wall is floor. On the floor alone, grained all the way up, it
/// changes nothing.
#[test]
fn line_cue_finds_smooth_walls_by_the_grain_ending() {
    let within = |b: &ColumnBoundary, rows: f32| matches!(b, ColumnBoundary::Obstacle { row, .. } if (row - 59.5).abs() < rows);
    let at_base = |b: &ColumnBoundary| within(b, 1.5);
    let wall = mottled_floor(true);
    let (with, without) = (line_boundaries(&wall, 8), line_boundaries(&wall, 0));
    let found = with.iter().filter(|b| at_base(b)).count();
    assert!(found >= 270, "the wall's base in {found} of 320 columns");
    assert_eq!(
        without.iter().filter(|b| at_base(b)).count(),
        0,
        "without the line cue the wall is floor"
    );
    for (u, (a, b)) in with.iter().zip(&without).enumerate() {
        assert!(
            a == b || within(a, 5.5),
            "column {u}: {a:?} where the scan alone gives {b:?}"
        );
    }
    let floor = mottled_floor(false);
    assert_eq!(
        line_boundaries(&floor, 8),
        line_boundaries(&floor, 0),
        "a grained floor is floor"
    );
    let too_wide = VisionConfig {
        line_columns: 513,
        ..VisionConfig::default()
    };
    assert!(
        too_wide.validate().is_err(),
        "a window of 1,027 columns is refused"
    );
}

/// The profiles turns are verified on: every setting kept but the
/// texture cue, which is turned off; none where it is off already.
#[test]
fn matching_settings_drop_only_the_texture_cue() {
    let config = VisionConfig {
        bin_width_rad: 0.25f64.to_radians(),
        min_brightness_step: 0.2,
        ..VisionConfig::default()
    };
    assert!(config.texture_ratio > 0.0, "the cue is on by default");
    let matching = config.for_matching().expect("the cue was on");
    assert_eq!(
        matching,
        VisionConfig {
            texture_ratio: 0.0,
            ..config.clone()
        }
    );
    assert!(matching.validate().is_ok());
    assert_eq!(matching.for_matching(), None);
}

/// The profiles views are compared on: every setting kept but the
/// faint steps; none where they are off, or where the texture cue they
/// belong to is.
#[test]
fn comparing_settings_drop_only_the_faint_steps() {
    let config = VisionConfig {
        bin_width_rad: 0.25f64.to_radians(),
        min_brightness_step: 0.2,
        ..VisionConfig::default()
    };
    assert!(config.faint_steps(), "faint steps are on by default");
    let comparing = config.for_comparing().expect("faint steps were on");
    assert_eq!(
        comparing,
        VisionConfig {
            faint_texture_ratio: 0.0,
            line_columns: 0,
            ..config.clone()
        }
    );
    assert!(comparing.validate().is_ok());
    assert_eq!(comparing.for_comparing(), None);
    let matching = config.for_matching().expect("the texture cue was on");
    assert!(!matching.faint_steps(), "no faint steps without the texture cue");
    assert_eq!(matching.for_comparing(), None);
    // A faint fraction at or above the edge fraction leaves nothing
    // between them.
    let none_between = VisionConfig {
        faint_step_fraction: 0.5,
        ..config
    };
    assert!(!none_between.faint_steps());
}

#[test]
fn finds_sub_pixel_edge_of_a_wall() {
    let ex = RopExtractor::new(&cam(), 0.9, VisionConfig::default());
    for edge in [60.0, 60.3, 60.5, 100.8] {
        let b = ex.boundaries(&wall_image(edge)).unwrap();
        for col in &b {
            let ColumnBoundary::Obstacle { row, .. } = *col else {
                panic!("{col:?}")
            };
            assert!((row - edge).abs() < 0.05, "edge {edge}: found {row}");
        }
    }
}

/// A floor that darkens steadily toward the base of a darker wall (as
/// shading toward a wall does): the edge is still where the pixels put
/// it, not pulled down by the floor's own change across the window.
#[test]
fn sub_pixel_edge_holds_on_a_floor_that_darkens_toward_the_wall() {
    let ex = RopExtractor::new(&cam(), 0.9, VisionConfig::default());
    for edge in [60.3, 100.8] {
        let img = image::RgbImage::from_fn(320, 240, |_, v| {
            let a = (edge - (v as f32 - 0.5)).clamp(0.0, 1.0);
            // The floor's value at the pixel's centre: 0.8 a row darker
            // toward the wall (its mean over the pixel, the ramp being
            // linear).
            let floor = 100.0 + 0.8 * (v as f32 - edge);
            let val = a * 40.0 + (1.0 - a) * floor;
            image::Rgb([val as u8; 3])
        });
        for col in &ex.boundaries(&img).unwrap() {
            let ColumnBoundary::Obstacle { row, .. } = *col else {
                panic!("{col:?}")
            };
            assert!((row - edge).abs() < 0.05, "edge {edge}: found {row}");
        }
    }
}

#[test]
fn wall_range_matches_the_camera_model() {
    let c = cam();
    let ex = RopExtractor::new(&c, 0.9, VisionConfig::default());
    let rop = ex.rop(&wall_image(70.25)).unwrap();
    let i = rop.bin_of(0.0).unwrap();
    let expect = c.pixel_to_floor(159.5, 70.25).unwrap().x as f32;
    assert!(
        (rop.reliable(i).unwrap() - expect).abs() < 0.002,
        "{:?} vs {expect}",
        rop.reliable(i)
    );
}

/// At the sides of the view only the near floor is seen: a bin there
/// with nothing in sight is free only as far as the floor seen in it,
/// while the middle bins see free floor to the soft limit.
#[test]
fn side_bins_are_free_only_as_far_as_they_are_seen() {
    let c = cam();
    let ex = RopExtractor::new(&c, 0.9, VisionConfig::default());
    let rop = ex
        .rop(&image::RgbImage::from_pixel(320, 240, image::Rgb([40, 40, 45])))
        .unwrap();
    let middle = rop.bin_of(0.0).unwrap();
    assert_eq!(rop.free_reach(middle), f32::INFINITY);
    // The widest bearing the top image row sees on the floor: beyond it,
    // only nearer floor.
    let top_edge = c.pixel_to_floor(0.0, 0.0).unwrap();
    let beyond = rop
        .bin_of(top_edge.y.atan2(top_edge.x) + 2f64.to_radians())
        .unwrap();
    let reach = rop.free_reach(beyond);
    assert!(
        rop.seen(beyond) && reach > 0.1 && reach < 0.9,
        "side bin seen to {reach} m"
    );
}

/// A plain floor brightening 1 % per row upwards, 320 × 240.
fn brightening_floor() -> image::RgbImage {
    image::RgbImage::from_fn(320, 240, |_, v| {
        let val = 40.0 * (1.0 + 0.01 * (239 - v) as f32);
        image::Rgb([val as u8, val as u8, (val * 1.1) as u8])
    })
}

/// The columns of `img` that the default extractor does not find clear.
fn obstacle_columns(img: &image::RgbImage) -> Vec<usize> {
    let ex = RopExtractor::new(&cam(), 0.9, VisionConfig::default());
    let b = ex.boundaries(img).unwrap();
    (0..b.len())
        .filter(|&u| !matches!(b[u], ColumnBoundary::Clear { .. }))
        .collect()
}

#[test]
fn specks_and_gradients_are_floor() {
    // Floor brightening 1 % per row upwards, with small bright specks.
    let mut img = brightening_floor();
    for (cu, cv) in [(50u32, 200u32), (160, 150), (250, 90), (100, 40)] {
        for du in 0..4 {
            for dv in 0..4 {
                img.put_pixel(cu + du, cv + dv, image::Rgb([240, 240, 240]));
            }
        }
    }
    let ex = RopExtractor::new(&cam(), 0.9, VisionConfig::default());
    let b = ex.boundaries(&img).unwrap();
    assert!(
        b.iter().all(|c| matches!(c, ColumnBoundary::Clear { .. })),
        "{:?}",
        b.iter().find(|c| !matches!(c, ColumnBoundary::Clear { .. }))
    );
    let rop = ex.rop(&img).unwrap();
    assert!((0..rop.len()).all(|i| rop.reliable(i).is_none()));
}

/// A floor half as bright in the bottom rows as higher up, brightening
/// fast and then levelling off (the dark bottom of a vignetted image),
/// crossed just above the seed rows by a strip of grey tape 16 rows
/// tall, half the rows a 2 cm obstacle would span there. A track
/// coasting over the tape along the steep trend it learnt below would
/// predict a floor far brighter than the one above it and never find
/// the floor again (every column then found the tape an obstacle).
/// Coasting, the trend fades at the rate it is learnt, so the floor
/// above the tape is floor.
#[test]
fn tape_where_the_floor_levels_off_is_floor() {
    let mut img = image::RgbImage::from_fn(320, 240, |_, v| {
        let l = 100.0 - 50.0 * (-((239 - v) as f32) / 10.0).exp();
        image::Rgb([l as u8, (l * 0.93) as u8, (l * 0.85) as u8])
    });
    let tape = 207..223;
    for u in 0..320 {
        for v in tape.clone() {
            img.put_pixel(u, v, image::Rgb([150, 150, 150]));
        }
    }
    let ex = RopExtractor::new(&cam(), 0.9, VisionConfig::default());
    let run = ex.run_rows[(tape.end as usize - 1) * 320 + 160];
    assert!(run as usize >= 2 * tape.len(), "{run}");
    let found = obstacle_columns(&img);
    assert!(
        found.is_empty(),
        "{} columns, first {:?}",
        found.len(),
        found.first()
    );
}

/// Just above a bright speck on a grained floor, a step of brightness
/// alone looks like a smooth wall's base when the rows below are taken
/// as the floor: the speck is level and far from the floor above, and
/// its edges are more "texture" than the grain. The rows below must be
/// the floor the scan followed up to the step; a speck is not.
#[test]
fn the_floor_below_a_brightness_step_is_the_floor_followed() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let floor = [100.0f32, 93.0, 85.0];
    let mut img = image::RgbImage::from_fn(320, 240, |_, _| {
        let g = rng.random_range(-4.0f32..4.0);
        image::Rgb(floor.map(|c| (c + g).round() as u8))
    });
    let speck = [150u8; 3];
    for u in 150..162 {
        for v in 205..220 {
            img.put_pixel(u, v, image::Rgb(speck));
        }
    }
    let ex = RopExtractor::new(&cam(), 0.9, VisionConfig::default());
    let px = img.as_raw();
    let classifier = ex.classifier(noise_sigma(px, 320, 240));
    let both = classifier.scaled_both(ex.config.edge_fraction);
    let grey_sigma = grey_noise_sigma(px, 320, 240, Median::Plain);
    let test = (&both, ex.config.texture_ratio);
    let speck_level = speck.map(|c| c as f32);
    // Following the floor, the step is no wall's base.
    assert!(!ex
        .cues(px)
        .bright_edge_confirms(156, 204, test, grey_sigma, (&floor, &classifier)));
    // Had the scan followed the speck, every other test would have
    // passed: the rows below are what rejects it.
    assert!(ex
        .cues(px)
        .bright_edge_confirms(156, 204, test, grey_sigma, (&speck_level, &classifier)));
}

/// A dark floor in plain noise (σ 2.5 levels a channel at a level of
/// 14, as in a dim field's bottom rows), brightening upwards: a seed's
/// slope fitted through its own six rows is off by 1.5 σ in some of
/// the 320 columns of every image, and a track coasting along it would
/// leave the floor for good. With the neighbours' slopes pooled, every
/// column sees the floor up to its top.
#[test]
fn noisy_dark_floors_are_floor() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let ex = RopExtractor::new(&cam(), 0.9, VisionConfig::default());
    for _ in 0..8 {
        let mut gauss = || {
            // Sum of twelve uniforms: near-normal, unit variance.
            (0..12).map(|_| rng.random::<f32>()).sum::<f32>() - 6.0
        };
        let img = image::RgbImage::from_fn(320, 240, |_, v| {
            let level = 14.0 * (1.0 + 0.004 * (239 - v) as f32);
            image::Rgb(std::array::from_fn(|c| {
                (level * [1.0, 1.05, 1.15][c] + 2.5 * gauss())
                    .round()
                    .clamp(0.0, 255.0) as u8
            }))
        });
        let b = ex.boundaries(&img).unwrap();
        let found: Vec<_> = b
            .iter()
            .enumerate()
            .filter(|(_, c)| !matches!(c, ColumnBoundary::Clear { .. }))
            .collect();
        assert!(found.is_empty(), "{found:?}");
    }
}

#[test]
fn specks_in_the_seed_rows_are_floor() {
    // The floor of `specks_and_gradients_are_floor`, with bright specks
    // 3 to 6 pixels wide in the bottom rows, where each column seeds
    // its floor, one at the image's edge.
    let mut img = brightening_floor();
    for (cu, cv, side) in [(60u32, 235u32, 4u32), (150, 234, 6), (230, 236, 3), (316, 235, 4)] {
        for du in 0..side {
            for dv in 0..side.min(240 - cv) {
                img.put_pixel(cu + du, cv + dv, image::Rgb([240, 240, 240]));
            }
        }
    }
    let found = obstacle_columns(&img);
    assert!(found.is_empty(), "obstacles in columns {found:?}");
}

/// Lint close to the camera: a flat bright blob 24 columns wide and 12
/// rows tall across the bottom rows, as wide as the seeds' nearest
/// neighbours' reach and more, so that those neighbours lie on it too.
/// Only seeds farther out on both sides show the floor; without them the
/// blob was taken for the floor and the floor above it for an obstacle.
#[test]
fn wide_specks_in_the_seed_rows_are_floor() {
    let mut img = brightening_floor();
    for u in 140..164 {
        for v in 228..240 {
            img.put_pixel(u, v, image::Rgb([200, 200, 195]));
        }
    }
    let found = obstacle_columns(&img);
    assert!(found.is_empty(), "obstacles in columns {found:?}");
}

/// The lint of `wide_specks_in_the_seed_rows_are_floor` near the right
/// edge of a dark floor that also darkens towards that corner
/// (vignetting), by more than the brightness tolerance between the
/// seeds that far out on either side: they disagree with each other,
/// but the median seed of the window between them is the floor's.
#[test]
fn wide_specks_in_a_vignetted_corner_are_floor() {
    let mut img = image::RgbImage::from_fn(320, 240, |u, v| {
        let val = (40.0 - 0.1 * u as f32) * (1.0 + 0.01 * (239 - v) as f32);
        image::Rgb([val as u8, val as u8, (val * 1.1) as u8])
    });
    for u in 250..274 {
        for v in 228..240 {
            img.put_pixel(u, v, image::Rgb([200, 200, 195]));
        }
    }
    let found = obstacle_columns(&img);
    assert!(found.is_empty(), "obstacles in columns {found:?}");
}

#[test]
fn uniform_images_give_empty_profiles_and_wrong_sizes_errors() {
    let ex = RopExtractor::new(&cam(), 0.9, VisionConfig::default());
    for val in [0u8, 128, 255] {
        let rop = ex
            .rop(&image::RgbImage::from_pixel(320, 240, image::Rgb([val; 3])))
            .unwrap();
        assert!((0..rop.len()).all(|i| rop.reliable(i).is_none() && rop.seen(i)));
    }
    assert!(matches!(
        ex.rop(&image::RgbImage::new(10, 10)),
        Err(VisionError::WrongSize { .. })
    ));
    assert!(RopExtractor::try_new(
        &cam(),
        0.9,
        VisionConfig {
            bin_width_rad: 0.0,
            ..Default::default()
        }
    )
    .is_err());
}

#[test]
fn fine_bins_are_filled_between_columns() {
    let cfg = VisionConfig {
        bin_width_rad: 0.2f64.to_radians(),
        ..Default::default()
    };
    let ex = RopExtractor::new(&cam(), 0.9, cfg);
    let rop = ex.rop(&wall_image(40.0)).unwrap();
    let lo = rop.bin_of(-25f64.to_radians()).unwrap();
    let hi = rop.bin_of(25f64.to_radians()).unwrap();
    assert!((lo..=hi).all(|i| rop.reliable(i).is_some()));
}

/// Images far smaller than the line cue's windows, and of noise alone:
/// every column gets a boundary within the image, none panics.
#[test]
fn small_and_noisy_images_give_boundaries_within_the_image() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for (w, h) in [(5u32, 4u32), (17, 13), (33, 25), (64, 48), (320, 24)] {
        let cam = PinholeModel {
            width: w,
            height: h,
            fx: 0.87 * w as f64,
            fy: 0.87 * w as f64,
            cx: (w as f64 - 1.0) / 2.0,
            cy: (h as f64 - 1.0) / 2.0,
            ..cam()
        };
        let ex = RopExtractor::new(&cam, 0.9, VisionConfig::default());
        let noise = image::RgbImage::from_fn(w, h, |_, _| image::Rgb(rng.random::<[u8; 3]>()));
        // A smooth wall over grain, as the line cue looks for.
        let wall = image::RgbImage::from_fn(w, h, |_, v| {
            let g = if v < h / 3 {
                1.0
            } else {
                0.9 + 0.2 * rng.random::<f32>()
            };
            image::Rgb([100.0f32, 95.0, 85.0].map(|c| (c * g) as u8))
        });
        for img in [noise, wall] {
            let b = ex.boundaries(&img).unwrap();
            assert_eq!(b.len(), w as usize);
            for c in &b {
                if let ColumnBoundary::Obstacle { row, .. } = c {
                    assert!(
                        (-0.5..=h as f32 - 0.5).contains(row),
                        "{w}x{h}: base at row {row}"
                    );
                }
            }
        }
    }
}

/// A dim floor of mottled grain (cells of 3 × 3 pixels, ±`grain`) under
/// sensor noise (±4 levels) meeting at row 60 a surface `shade` times as
/// bright, smooth or (`grained_above`) with the floor's grain on it.
fn dim_floor(shade: f32, grained_above: bool, grain: f32) -> image::RgbImage {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let cells: Vec<f32> = (0..107 * 80)
        .map(|_| 1.0 - grain + 2.0 * grain * rng.random::<f32>())
        .collect();
    let noise: Vec<f32> = (0..320 * 240 * 3)
        .map(|_| 8.0 * (rng.random::<f32>() - 0.5))
        .collect();
    let floor = [50.0f32, 47.0, 42.0];
    image::RgbImage::from_fn(320, 240, |u, v| {
        let g = cells[(v / 3 * 107 + u / 3) as usize];
        let (shade, g) = if v < 60 {
            (shade, if grained_above { g } else { 1.0 })
        } else {
            (1.0, g)
        };
        let i = ((v * 320 + u) * 3) as usize;
        image::Rgb(std::array::from_fn(|k| {
            (floor[k] * shade * g + noise[i + k]).round().clamp(0.0, 255.0) as u8
        }))
    })
}

/// On a dim floor whose grain (±6 %) stands barely above the noise, too
/// little for the grain alone to end at a base, a smooth wall 10 % or 20 %
/// darker steps in brightness along its base: the line cue finds the base
/// within two rows in at least 265 of 320 columns (272 and 295 here;
/// without the cue 5 and 204), and changes no column but there or a cell
/// of grain (3 rows) below (1 column here). The same
/// steps with the floor's grain above them (shade on the floor) change
/// nothing.
#[test]
fn line_cue_finds_dim_walls_by_a_step_and_the_grain_ending() {
    let within = |b: &ColumnBoundary, rows: f32| matches!(b, ColumnBoundary::Obstacle { row, .. } if (row - 60.0).abs() < rows);
    let at_base = |b: &ColumnBoundary| within(b, 2.0);
    for shade in [0.9, 0.8] {
        let wall = dim_floor(shade, false, 0.06);
        let (with, without) = (line_boundaries(&wall, 8), line_boundaries(&wall, 0));
        let found = with.iter().filter(|b| at_base(b)).count();
        let before = without.iter().filter(|b| at_base(b)).count();
        assert!(
            found >= 265 && found > before + 60,
            "shade {shade}: the base in {found} columns ({before} without the cue)"
        );
        for (u, (a, b)) in with.iter().zip(&without).enumerate() {
            assert!(
                a == b || within(a, 3.5),
                "shade {shade}, column {u}: {a:?} for {b:?}"
            );
        }
        let shadow = dim_floor(shade, true, 0.06);
        assert_eq!(
            line_boundaries(&shadow, 8),
            line_boundaries(&shadow, 0),
            "shade {shade} on the floor's grain"
        );
    }
}
