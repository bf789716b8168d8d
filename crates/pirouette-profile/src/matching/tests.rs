//! Tests of `matching`.

use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The cost curve's vectorised sums against the definitions summed one
/// pair at a time: unseen bins, open floor (seen all the way or only
/// up to a reach), colours present and absent, an intermittent cue's
/// ranges in one bin of a pair, in both or in neither,
/// a profile length that is not a whole number of blocks, and shifts
/// that run off both ends. The curve rescaled to another noise from the
/// kept gaps equals a new pass.
#[test]
fn cost_curve_matches_the_definitions_pair_by_pair() {
    let mut rng = ChaCha8Rng::seed_from_u64(12345);
    let mut next = move || rng.random::<f32>();
    let mut random_cells = |n: usize| -> Vec<Cell> {
        (0..n)
            .map(|_| {
                let kind = next();
                let inv = if kind < 0.15 {
                    f32::NAN
                } else if kind < 0.4 {
                    0.0
                } else {
                    1.0 + 3.0 * next()
                };
                let chroma = (inv > 0.0 && next() < 0.6).then(|| [0.3 + 0.1 * next(), 0.3 + 0.1 * next()]);
                // Open floor seen all the way, or only up to a reach.
                let inv_hi = if inv == 0.0 && next() < 0.5 {
                    1.0 + 3.0 * next()
                } else {
                    inv
                };
                // The intermittent cue's range in some seen bins: the
                // bin's own obstacle or a nearer one.
                let inv_c = if !inv.is_nan() && next() < 0.3 {
                    inv.max(1.0) + next()
                } else {
                    f32::NAN
                };
                Cell {
                    inv,
                    inv_hi,
                    chroma,
                    inv_c,
                }
            })
            .collect()
    };
    let (a, b) = (random_cells(45), random_cells(61));
    let config = MatchConfig::default();
    let (offset, k_lo, k_hi, sigma) = (3i64, -20i64, 25i64, 0.02f32);
    let a_len = a.len().div_ceil(LANES) as i64 * LANES as i64;
    let (sa, sb) = (
        Signals::new(&a, 0..a_len),
        Signals::new(&b, offset + k_lo..offset + k_hi + a_len),
    );
    let mut gaps = Vec::new();
    let curve = cost_curve(&sa, &sb, k_lo, k_hi, sigma, &config, &mut gaps);
    // The curve at another noise, from the kept gaps, is the one a new
    // pass over the profiles gives, to the last bit.
    let other = cost_curve(&sa, &sb, k_lo, k_hi, 0.05, &config, &mut Vec::new());
    let rescaled = curve.clone().rescaled(&gaps, 0.05, &config);
    assert_eq!(rescaled.cost, other.cost);
    assert_eq!(rescaled.informative, other.informative);
    let rho = |e: f64| (e * e).min(9.0);
    let mut checked = 0;
    for (j, k) in (k_lo..=k_hi).enumerate() {
        let (mut range, mut colour) = (0f64, 0f64);
        let (mut seen, mut info, mut coloured) = (0, 0, 0);
        for (i, ca) in a.iter().enumerate() {
            let Some(cb) = usize::try_from(i as i64 + offset + k).ok().and_then(|t| b.get(t)) else {
                continue;
            };
            if ca.inv.is_nan() || cb.inv.is_nan() {
                continue;
            }
            seen += 1;
            if !(ca.inv_c.is_nan() || cb.inv_c.is_nan()) {
                // Both have the intermittent cue's range: compared.
                info += 1;
                range += rho((ca.inv_c - cb.inv_c).abs() as f64 / sigma as f64);
            } else if (ca.inv > 0.0 && ca.inv >= cb.inv_hi) || (cb.inv > 0.0 && cb.inv >= ca.inv_hi) {
                info += 1;
                // The distance between the bins' intervals of inverse
                // range.
                let d = (ca.inv.max(cb.inv) - ca.inv_hi.min(cb.inv_hi)).max(0.0);
                range += rho(d as f64 / sigma as f64);
            }
            if let (Some(x), Some(y)) = (ca.chroma, cb.chroma) {
                coloured += 1;
                let e = ((x[0] - y[0]).abs().max((x[1] - y[1]).abs())) as f64 / config.chroma_sigma as f64;
                colour += rho(e);
            }
        }
        assert_eq!(curve.overlap[j], seen, "shift {k}");
        assert_eq!(curve.informative[j], info, "shift {k}");
        assert_eq!(curve.colour_pairs[j], coloured, "shift {k}");
        if seen == 0 {
            assert!(curve.cost[j].is_infinite(), "shift {k}: nothing seen in common");
            continue;
        }
        let expect = if info == 0 {
            0.0
        } else {
            (range + config.colour_weight as f64 * colour) / info as f64
        };
        assert!(
            (curve.cost[j] - expect).abs() <= 1e-5 * expect.max(1.0),
            "shift {k}: {} vs {expect}",
            curve.cost[j]
        );
        checked += 1;
    }
    assert!(checked > 30, "{checked} shifts compared");
}

/// A 360° scene of ranges around the robot, seen through a 60° view.
fn scene_range(bearing: f64) -> f32 {
    let d = bearing.to_degrees().rem_euclid(360.0);
    match d {
        d if (20.0..35.0).contains(&d) => 0.35,
        d if (45.0..50.0).contains(&d) => 0.5,
        d if (170.0..175.0).contains(&d) => 0.4,
        d if (250.0..262.0).contains(&d) => 0.55,
        d if (115.0..118.0).contains(&d) => 0.45,
        d if (80.0..140.0).contains(&d) => 0.6 + 0.002 * (d - 80.0) as f32,
        d if (200.0..210.0).contains(&d) => 0.25,
        d if (300.0..330.0).contains(&d) => 1.4,
        _ => f32::INFINITY,
    }
}

fn view(heading_deg: f64, bin_deg: f64) -> Rop {
    let w = bin_deg.to_radians();
    let mut rop = Rop::covering(-30f64.to_radians(), 30f64.to_radians(), w, 0.9).unwrap();
    for i in 0..rop.len() {
        // Sample the scene at sub-bin resolution: nearest over the bin.
        let r = (0..5)
            .map(|s| {
                scene_range(
                    heading_deg.to_radians()
                        + rop.bearing_start_rad
                        + (i as f64 + (s as f64 + 0.5) / 5.0) * w,
                )
            })
            .fold(f32::INFINITY, f32::min);
        rop.range_m[i] = r;
    }
    rop
}

#[test]
fn recovers_turns_against_brute_force_truth() {
    let mut checked = 0;
    for measure in [Measure::Absolute, Measure::Squared, Measure::Robust, Measure::Dct] {
        let config = MatchConfig {
            measure,
            ..MatchConfig::default()
        };
        for (h, turn) in [
            (10.0, 30.0),
            (60.0, 27.3),
            (100.0, 32.6),
            (190.0, 30.0),
            (160.0, 25.0),
        ] {
            let est = match_turn(&view(h, 1.0), &view(h + turn, 1.0), 30f64.to_radians(), &config);
            assert!(!est.fallback, "{measure:?} h={h} turn={turn}: {est:?}");
            let err = (est.turn_rad.to_degrees() - turn).abs();
            assert!(
                err < 0.6,
                "{measure:?} h={h} turn={turn}: got {}",
                est.turn_rad.to_degrees()
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 20);
}

/// Walls round the robot beyond the reach of every cue but an
/// intermittent one, which finds them in each view in its own
/// stretches (seven bins in ten, at random): with nothing else in
/// sight the turn is open floor; compared where both views have them
/// and silent elsewhere, the walls verify it; the same stretches taken
/// as steady ranges (a wall in one view against nothing in the other
/// is a contradiction) verify it less surely.
#[test]
fn an_intermittent_cue_counts_where_both_views_have_it() {
    // Six-degree stretches of wall at ranges 0.55-0.8 m in an order
    // that does not repeat within a view.
    let wall = |bearing: f64| {
        let segment = (bearing.to_degrees().rem_euclid(360.0) / 6.0) as u32;
        0.55 + 0.05 * ((segment * 7 + segment / 6) % 6) as f32
    };
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let config = MatchConfig::default();
    let mut steady_confidence = 0.0;
    let mut intermittent_confidence = 0.0;
    for (h, turn) in [
        (10.0, 30.0),
        (60.0, 27.5),
        (100.0, 32.5),
        (190.0, 30.0),
        (160.0, 25.0),
    ] {
        // Open floor, the cue's stretches of wall, and the same stretches
        // as steady ranges.
        let mut views = |heading: f64| {
            let mut blank =
                Rop::covering(-30f64.to_radians(), 30f64.to_radians(), 0.25f64.to_radians(), 0.9).unwrap();
            blank.range_m.fill(f32::INFINITY);
            let cue: Vec<f32> = (0..blank.len())
                .map(|i| {
                    let r = wall(heading.to_radians() + blank.bin_centre_rad(i));
                    if rng.random::<f32>() < 0.7 {
                        r
                    } else {
                        f32::INFINITY
                    }
                })
                .collect();
            let mut steady = blank.clone();
            steady.range_m.clone_from(&cue);
            (blank, cue, steady)
        };
        let (before, after) = (views(h), views(h + turn));
        fn with_cue(v: &(Rop, Vec<f32>, Rop)) -> MatchView<'_> {
            MatchView {
                rop: &v.0,
                cue_m: &v.1,
            }
        }
        let cmd = 30f64.to_radians();
        let blank = match_turn(&before.0, &after.0, cmd, &config);
        assert!(blank.fallback, "h={h}: open floor verified {blank:?}");
        let est = match_turn(with_cue(&before), with_cue(&after), cmd, &config);
        assert!(!est.fallback, "h={h} turn={turn}: {est:?}");
        let err = (est.turn_rad.to_degrees() - turn).abs();
        assert!(err < 0.25, "h={h} turn={turn}: got {}", est.turn_rad.to_degrees());
        intermittent_confidence += est.confidence;
        let steady = match_turn(&before.2, &after.2, cmd, &config);
        steady_confidence += if steady.fallback { 0.0 } else { steady.confidence };
    }
    assert!(
        steady_confidence < intermittent_confidence,
        "steady {steady_confidence} against intermittent {intermittent_confidence} (sums of five)"
    );
}

/// A camera sees only the near floor at the sides of its view: there a
/// bin with nothing in sight says nothing of what lies farther.
fn view_with_short_sides(heading_deg: f64, bin_deg: f64, side_deg: f64, reach_m: f32) -> Rop {
    let mut rop = view(heading_deg, bin_deg);
    let side = (side_deg / bin_deg).round() as usize;
    let n = rop.len();
    for i in (0..side).chain(n - side..n) {
        if rop.range_m[i] > reach_m {
            rop.range_m[i] = f32::INFINITY;
            rop.free_m[i] = reach_m;
        }
    }
    rop
}

#[test]
fn open_floor_seen_only_near_does_not_contradict_far_walls() {
    // At the sides of each view, the floor is seen to 0.3 m only, and
    // the walls there (0.35-1.4 m) are out of sight in one view but in
    // the middle of the other.
    for (h, turn) in [(60.0, 27.3), (100.0, 32.6), (160.0, 25.0)] {
        let (before, after) = (
            view_with_short_sides(h, 0.25, 5.0, 0.3),
            view_with_short_sides(h + turn, 0.25, 5.0, 0.3),
        );
        let est = match_turn(&before, &after, 30f64.to_radians(), &MatchConfig::default());
        assert!(!est.fallback, "h={h} turn={turn}: {est:?}");
        let err = (est.turn_rad.to_degrees() - turn).abs();
        assert!(err < 0.3, "h={h} turn={turn}: got {}", est.turn_rad.to_degrees());
    }
}

#[test]
fn fine_bins_refine_below_a_degree() {
    let est = match_turn(
        &view(60.0, 0.2),
        &view(88.3, 0.2),
        30f64.to_radians(),
        &MatchConfig::default(),
    );
    assert!(!est.fallback, "{est:?}");
    assert!(
        (est.turn_rad.to_degrees() - 28.3).abs() < 0.15,
        "{}",
        est.turn_rad.to_degrees()
    );
}

/// A profile of 0.25° bins over a 60° view from `(x, y)` facing
/// `heading_deg`, ray-cast against wall segments (nearest over five
/// rays a bin), soft limit 0.9 m.
fn cast_view(walls: &[[f64; 4]], x: f64, y: f64, heading_deg: f64) -> Rop {
    let w = 0.25f64.to_radians();
    let mut rop = Rop::covering(-30f64.to_radians(), 30f64.to_radians(), w, 0.9).unwrap();
    for i in 0..rop.len() {
        rop.range_m[i] = (0..5)
            .filter_map(|k| {
                let b = heading_deg.to_radians()
                    + rop.bearing_start_rad
                    + (i as f64 + (k as f64 + 0.5) / 5.0) * w;
                let (dx, dy) = (b.cos(), b.sin());
                walls
                    .iter()
                    .filter_map(|&[x0, y0, x1, y1]| {
                        // Ray (x, y) + t·d against the segment.
                        let (ex, ey) = (x1 - x0, y1 - y0);
                        let den = dx * ey - dy * ex;
                        if den.abs() < 1e-12 {
                            return None;
                        }
                        let t = ((x0 - x) * ey - (y0 - y) * ex) / den;
                        let u = ((x0 - x) * dy - (y0 - y) * dx) / den;
                        (t > 0.0 && (0.0..=1.0).contains(&u)).then_some(t)
                    })
                    .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.min(t))))
            })
            .fold(f32::INFINITY, |m, t| m.min(t as f32));
    }
    rop
}

#[test]
fn a_turn_that_moves_the_robot_is_refined_with_the_shift() {
    // A wall slanting across the view at 0.45-0.8 m that ends at 29°,
    // and a post at 0.3 m.
    let walls = [
        [0.6, -0.5, 0.4, 0.22],
        [0.22, 0.05, 0.25, 0.05],
        [0.25, 0.05, 0.25, 0.08],
        [0.25, 0.08, 0.22, 0.08],
        [0.22, 0.08, 0.22, 0.05],
    ];
    // The robot turns 28° and its centre moves 3 mm (toward the wall
    // and sideways), as a turn about a point 6 mm off the centre does.
    let before = cast_view(&walls, 0.0, 0.0, 10.0);
    let after = cast_view(&walls, 0.0025, -0.0018, 38.0);
    // Ray-cast bins share no errors with their neighbours: each is an
    // independent sample.
    let config = MatchConfig {
        correlation_rad: before.bin_width_rad,
        ..MatchConfig::default()
    };
    let plain = MatchConfig {
        turn_shift_m: 0.0,
        ..config.clone()
    };
    let alone = match_turn(&before, &after, 30f64.to_radians(), &plain);
    let with_shift = match_turn(&before, &after, 30f64.to_radians(), &config);
    assert!(
        !alone.fallback && !with_shift.fallback,
        "{alone:?} {with_shift:?}"
    );
    let err = |e: &TurnEstimate| (e.turn_rad.to_degrees() - 28.0).abs();
    assert!(
        err(&with_shift) < 0.2,
        "refined: {}",
        with_shift.turn_rad.to_degrees()
    );
    assert!(
        err(&alone) > 4.0 * err(&with_shift),
        "alone {} refined {}",
        alone.turn_rad.to_degrees(),
        with_shift.turn_rad.to_degrees()
    );
}

#[test]
fn open_floor_falls_back_to_the_command() {
    let mut a = Rop::covering(-0.5, 0.5, 1f64.to_radians(), 0.9).unwrap();
    a.range_m.iter_mut().for_each(|r| *r = f32::INFINITY);
    let est = match_turn(&a, &a.clone(), 0.5, &MatchConfig::default());
    assert!(est.fallback && est.evidence == Evidence::Aperture);
    assert_eq!(est.turn_rad, 0.5);
}

/// Two views that share a 12° sliver, with a clear profile in it: the
/// true shift matches exactly, but no shift three bins or more away
/// overlaps enough to be compared, so the basin's arms cannot be
/// weighed and the match is not trusted. With three bins more of
/// overlap each way it is.
#[test]
fn a_minimum_whose_basin_cannot_be_tested_is_not_trusted() {
    let w = 1f64.to_radians();
    let shared = |i: usize| 0.4 + 0.05 * (i as f32 * 1.7).sin() + 0.1 * (i % 4 == 0) as u8 as f32;
    let views = |seen: usize| {
        let mut before = Rop::covering(-0.5, 0.5, w, 0.9).unwrap();
        let mut after = before.clone();
        before.range_m.iter_mut().for_each(|r| *r = f32::NAN);
        after.range_m.iter_mut().for_each(|r| *r = f32::NAN);
        // After a turn by 20 bins, after's bin i sees before's i + 20.
        for i in 10..10 + seen {
            after.range_m[i] = shared(i);
            before.range_m[i + 20] = shared(i);
        }
        (before, after)
    };
    let turn = 20.0 * w;
    let (before, after) = views(12);
    let est = match_turn(&before, &after, turn, &MatchConfig::default());
    assert!(est.fallback, "{est:?}");
    assert_eq!(est.evidence, Evidence::Ambiguous);
    assert_eq!(est.confidence, 0.0);
    let (before, after) = views(18);
    let est = match_turn(&before, &after, turn, &MatchConfig::default());
    assert!(!est.fallback, "{est:?}");
    assert!((est.turn_rad - turn).abs() < 0.1 * w, "{est:?}");
}

#[test]
fn periodic_profiles_are_ambiguous() {
    let mut a = Rop::covering(-0.5, 0.5, 1f64.to_radians(), 0.9).unwrap();
    for i in 0..a.len() {
        a.range_m[i] = if (i / 4) % 2 == 0 { 0.4 } else { 0.8 };
    }
    let est = match_turn(&a, &a.clone(), 0.0, &MatchConfig::default());
    assert!(est.fallback && est.evidence == Evidence::Ambiguous, "{est:?}");
}

/// The FFT baseline finds a known turn between two 60° views of one
/// scene (sampled at bin centres, so to within a bin), at different bin widths and with some
/// bins unseen and some with no return; different bin widths are refused.
#[test]
fn fft_correlation_finds_a_known_turn() {
    let scene = |bearing: f64| -> f32 {
        let d = bearing.to_degrees().rem_euclid(360.0);
        if (d % 37.0) < 8.0 {
            0.35
        } else if (d % 53.0) < 5.0 {
            f32::INFINITY
        } else {
            (0.7 + 0.3 * (2.0 * bearing).sin()) as f32
        }
    };
    let view = |heading_deg: f64, bin_deg: f64| {
        let mut rop =
            Rop::covering(-30f64.to_radians(), 30f64.to_radians(), bin_deg.to_radians(), 0.9).expect("valid");
        for i in 0..rop.len() {
            rop.range_m[i] = scene(heading_deg.to_radians() + rop.bin_centre_rad(i));
        }
        rop.range_m[3] = f32::NAN;
        rop
    };
    let mut fft = fft::FftCorrelation::new();
    for bin_deg in [1.0, 0.25] {
        let (before, after) = (view(40.0, bin_deg), view(68.6, bin_deg));
        let turn = fft
            .match_turn(
                &before,
                &after,
                30f64.to_radians(),
                15f64.to_radians(),
                20f64.to_radians(),
            )
            .expect("a turn");
        assert!(
            (turn.to_degrees() - 28.6).abs() < bin_deg,
            "{bin_deg}°: {}",
            turn.to_degrees()
        );
    }
    let (before, after) = (view(40.0, 1.0), view(68.6, 0.5));
    assert!(fft.match_turn(&before, &after, 0.5, 0.3, 0.3).is_none());
}
