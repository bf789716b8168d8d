//! The lock-step scan against scanning each column on its own.

use super::*;
use crate::scan::Candidate;

/// The oracle for the lock-step scan: each column scanned on its own,
/// every candidate decided on the spot by following the floor over its
/// run (the plain form of what the lock-step scan does with deferred
/// candidates).
///
/// Returns the boundary and the nearest undecided base as the obstacle's
/// base it would be, for [`settle`](super::super::rows::settle).
fn column_by_column(
    ex: &RopExtractor,
    px: &[u8],
    u: u32,
    sigma: f32,
    seeds: &[Seed],
) -> (ColumnBoundary, Option<ColumnBoundary>) {
    let mut first: Option<ColumnBoundary> = None;
    let b = column_alone(ex, px, u, sigma, seeds, &mut first);
    (b, first)
}

/// [`column_by_column`]'s boundary; `first` takes the nearest undecided
/// base.
fn column_alone(
    ex: &RopExtractor,
    px: &[u8],
    u: u32,
    sigma: f32,
    seeds: &[Seed],
    first: &mut Option<ColumnBoundary>,
) -> ColumnBoundary {
    let (m, n) = (ex.width, ex.height);
    let top = ex.top_floor[u as usize];
    if top >= n {
        return ColumnBoundary::NoFloor;
    }
    let pix = |v: u32| smoothed(px, m, u, v);
    let seed_rows = SEED_ROWS.min(n - top);
    let classifier = ex.classifier(sigma);
    // The seeds are the scan's (tested on their own below).
    let FloorTrack { level, trend } = match seeds[u as usize] {
        Seed::NoFloor => return ColumnBoundary::NoFloor,
        Seed::Clear { top_row } => return ColumnBoundary::Clear { top_row },
        Seed::Track(t) => t,
    };
    let (rate, trend_rate) = (ex.config.adapt_rate, ex.config.trend_rate);
    let edge = classifier.scaled(ex.config.edge_fraction);
    let both = classifier.scaled_both(ex.config.edge_fraction);
    let faint = classifier.scaled_both(ex.config.faint_step_fraction);
    let grey_sigma = grey_noise_sigma(px, m, n, Median::Plain);
    let mut track = FloorTrack { level, trend };
    let (mut close_below, mut steady_below, mut faint_below) = (true, true, true);
    // The nearest undecided base so far.
    let mut undecided: Option<u32> = None;
    // A base at row `v`: the obstacle, unless the floor shows again above
    // it (then undecided, and the scan goes on).
    let mut base = |v: u32, pred: [f32; 3], trend: [f32; 3], lo: u32, edge: bool| {
        let c = Candidate {
            row: v,
            lo,
            off_before: 0,
            floor: pred,
            trend,
            edge,
        };
        let b = ex.cues(px).refine(u, v, pred, trend);
        if ex.cues(px).floor_resumes(u, &c, &classifier) {
            undecided.get_or_insert(v);
            first.get_or_insert(b);
            return None;
        }
        match b {
            ColumnBoundary::Obstacle { row, colour, .. } => Some(ColumnBoundary::Obstacle {
                row,
                colour,
                undecided,
            }),
            other => Some(other),
        }
    };
    let mut v = n - seed_rows - 1;
    loop {
        let p = pix(v);
        let pred = track.predict();
        let masks = classifier.masks(&p, &pred, &both, faint.brightness_step);
        let (floor, close) = (masks.floor != 0, masks.close != 0);
        let steady = close && masks.steady != 0;
        let faint_steady = close && masks.faint_steady != 0;
        if !floor {
            let run = ex.run_rows[(v * m + u) as usize].max(1) as u32;
            let lo = (v + 1).saturating_sub(run);
            let mut ahead = track;
            let off = (lo..=v)
                .rev()
                .filter(|&w| {
                    let q = pix(w);
                    let f = classifier.is_floor(&q, &ahead.predict());
                    ahead.step(&q, f, rate, trend_rate);
                    !f
                })
                .count();
            if off as f32 >= ex.config.run_fraction * (v - lo + 1) as f32
                && ex.cues(px).column_confirms(u, v, &pred, &classifier)
            {
                if let Some(b) = base(v, pred, track.trend, lo, false) {
                    return b;
                }
            }
        } else if !close && close_below {
            let mut coasted = track;
            coasted.step(&p, false, rate, trend_rate);
            if ex.cues(px).edge_confirms(u, v, coasted, &edge) {
                if let Some(b) = base(v, pred, track.trend, v, true) {
                    return b;
                }
            }
        } else if (close
            && !steady
            && steady_below
            && ex.config.texture_ratio > 0.0
            && ex.cues(px).bright_edge_confirms(
                u,
                v,
                (&both, ex.config.texture_ratio),
                grey_sigma,
                (&pred, &classifier),
            ))
            || (steady
                && !faint_steady
                && faint_below
                && ex.config.faint_steps()
                && ex.cues(px).bright_edge_confirms(
                    u,
                    v,
                    (&faint, ex.config.faint_texture_ratio),
                    grey_sigma,
                    (&pred, &classifier),
                ))
        {
            if let Some(b) = base(v, pred, track.trend, v, true) {
                return b;
            }
        }
        track.step(&p, floor, rate, trend_rate);
        close_below = close;
        steady_below = steady;
        faint_below = faint_steady;
        if v == top {
            return match undecided {
                Some(row) => ColumnBoundary::Undecided { row },
                None => ColumnBoundary::Clear { top_row: top },
            };
        }
        v -= 1;
    }
}

/// The lock-step scan finds exactly what scanning each column on its
/// own finds, on images with a blotchy, grained floor that brightens
/// upwards, noise, specks, and walls and boxes of many heights and
/// contrasts (some close to the floor's colour, some smooth and of the
/// floor's own hue), with the texture cue off, on without its faint
/// steps, and on.
#[test]
fn lock_step_scan_equals_the_column_by_column_oracle() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut rand = move || rng.random::<f32>();
    let mut compared = 0;
    let mut undecided = 0;
    let mut texture_found = 0;
    let mut faint_found = 0;
    for width in [320u32, 75] {
        let c = PinholeModel {
            width,
            cx: (width as f64 - 1.0) / 2.0,
            ..cam()
        };
        let textured = RopExtractor::new(&c, 0.9, VisionConfig::default());
        let no_faint = RopExtractor::new(
            &c,
            0.9,
            VisionConfig {
                faint_texture_ratio: 0.0,
                ..VisionConfig::default()
            },
        );
        let plain = RopExtractor::new(
            &c,
            0.9,
            VisionConfig::default()
                .for_matching()
                .expect("the cue is on by default"),
        );
        let marked = RopExtractor::new(
            &c,
            0.9,
            VisionConfig {
                mark_depth_m: 0.25,
                ..VisionConfig::default()
            },
        );
        for _ in 0..4 {
            // Obstacles: (first column, last column, base row, colour);
            // every other one smooth grey of the floor's hue.
            let boxes: Vec<(u32, u32, f32, [f32; 3])> = (0..6)
                .map(|k| {
                    let a = (rand() * width as f32) as u32;
                    let w = 3 + (rand() * 80.0) as u32;
                    let contrast = 0.8 + 0.5 * rand();
                    let colour = if k % 2 == 0 {
                        [90.0 * contrast, 85.0, 80.0 / contrast]
                    } else {
                        let shade = 0.8 + 0.1 * rand();
                        [70.0 * shade, 66.0 * shade, 60.0 * shade]
                    };
                    (a, a + w, 20.0 + 200.0 * rand(), colour)
                })
                .collect();
            let blotch: Vec<f32> = (0..64).map(|_| 0.9 + 0.2 * rand()).collect();
            // Grain in cells of 2 × 2 pixels.
            let grain: Vec<f32> = (0..(width as usize / 2 + 1) * 120)
                .map(|_| 0.94 + 0.12 * rand())
                .collect();
            let mut img = image::RgbImage::new(width, 240);
            for (u, v, p) in img.enumerate_pixels_mut() {
                let wall = boxes
                    .iter()
                    .filter(|b| (b.0..=b.1).contains(&u) && (v as f32) < b.2)
                    .max_by(|x, y| x.2.total_cmp(&y.2));
                let mut rgb = match wall {
                    Some(b) => b.3,
                    None => {
                        let k = blotch[((u / 40) * 8 + v / 30) as usize % 64]
                            * grain[(v / 2) as usize * (width as usize / 2 + 1) + (u / 2) as usize];
                        let lift = 1.0 + 0.004 * (239 - v) as f32;
                        [70.0 * k * lift, 66.0 * k * lift, 60.0 * k * lift]
                    }
                };
                if rand() < 0.002 {
                    rgb = [240.0; 3];
                }
                *p = image::Rgb(rgb.map(|x| (x + 6.0 * (rand() - 0.5)).clamp(0.0, 255.0) as u8));
            }
            let px = img.as_raw();
            let sigma = noise_sigma(px, width, 240);
            let without = plain.boundaries(&img).unwrap();
            let strong_only = no_faint.boundaries(&img).unwrap();
            for ex in [&plain, &no_faint, &textured, &marked] {
                let lock_step = ex.boundaries(&img).unwrap();
                let seeds = super::super::seed::seeds(
                    px,
                    (ex.width, ex.height),
                    &ex.top_floor,
                    &ex.classifier(sigma),
                );
                let (mut oracle, bases): (Vec<_>, Vec<_>) = (0..width)
                    .map(|u| column_by_column(ex, px, u, sigma, &seeds))
                    .unzip();
                super::super::rows::settle(&mut oracle, &bases);
                for (u, (found, expected)) in lock_step.iter().zip(&oracle).enumerate() {
                    assert_eq!(
                        found, expected,
                        "width {width} column {u}, texture ratio {}",
                        ex.config.texture_ratio
                    );
                }
                compared += lock_step
                    .iter()
                    .filter(|b| matches!(b, ColumnBoundary::Obstacle { .. }))
                    .count();
                undecided += (lock_step.iter())
                    .filter(|b| {
                        matches!(
                            b,
                            ColumnBoundary::Undecided { .. }
                                | ColumnBoundary::Obstacle {
                                    undecided: Some(_),
                                    ..
                                }
                        )
                    })
                    .count();
            }
            let with = textured.boundaries(&img).unwrap();
            texture_found += with.iter().zip(&without).filter(|(a, b)| a != b).count();
            faint_found += with.iter().zip(&strong_only).filter(|(a, b)| a != b).count();
        }
    }
    assert!(compared > 1000, "only {compared} obstacle columns compared");
    assert!(undecided > 20, "only {undecided} columns with an undecided base");
    assert!(
        texture_found > 50,
        "the texture cue changed only {texture_found} columns"
    );
    assert!(faint_found > 10, "faint steps changed only {faint_found} columns");
}

/// Columns are scanned side by side in blocks; each must find its own
/// edge, whatever its neighbours do and however the width splits into
/// blocks.
#[test]
fn every_column_finds_its_own_edge() {
    for width in [320u32, 37, 9] {
        let c = PinholeModel {
            width,
            cx: (width as f64 - 1.0) / 2.0,
            ..cam()
        };
        // A staircase of walls three columns wide: group g = u/3 has
        // its edge at row 40 + 9 (g mod 7), groups g mod 7 = 6 see floor
        // only.
        let edge = |u: u32| {
            let g = u / 3 % 7;
            (g != 6).then_some(40.0 + 9.0 * g as f32)
        };
        let img = image::RgbImage::from_fn(width, 240, |u, v| match edge(u) {
            Some(e) if (v as f32) < e => image::Rgb([220, 220, 220]),
            _ => image::Rgb([30, 30, 30]),
        });
        let ex = RopExtractor::new(&c, 0.9, VisionConfig::default());
        let b = ex.boundaries(&img).unwrap();
        assert_eq!(b.len(), width as usize);
        let mut checked = 0;
        for (u, col) in b.iter().enumerate() {
            let u = u as u32;
            // The smoothing across three columns blurs a column whose
            // neighbour's wall stands on another row: checked are the
            // others.
            let neighbours_agree = [u.saturating_sub(1), (u + 1).min(width - 1)]
                .iter()
                .all(|&w| edge(w) == edge(u));
            if !neighbours_agree {
                continue;
            }
            checked += 1;
            match (edge(u), *col) {
                (Some(e), ColumnBoundary::Obstacle { row, .. }) => {
                    assert!(
                        (row - (e - 0.5)).abs() < 0.05,
                        "width {width} column {u}: {row} vs {e}"
                    )
                }
                (None, ColumnBoundary::Clear { top_row }) => {
                    assert_eq!(top_row, ex.top_floor[u as usize])
                }
                (e, found) => panic!("width {width} column {u}: edge {e:?}, found {found:?}"),
            }
        }
        assert!(
            checked >= width as usize / 3,
            "width {width}: {checked} columns checked"
        );
    }
}
