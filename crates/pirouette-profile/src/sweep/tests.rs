//! Tests of `sweep`.

use super::*;

/// A verified turn's standard deviation: the configured one for a
/// clearly distinct match, a third of the basin for one just distinct
/// enough (significance 3, confidence 0.5), a command's for a fallback.
#[test]
fn a_barely_distinct_match_pins_its_turn_less() {
    let config = SweepConfig::default();
    let turn = |confidence: f64, fallback: bool| TurnEstimate {
        turn_rad: 0.5,
        confidence,
        fallback,
        evidence: if fallback {
            Evidence::Ambiguous
        } else {
            Evidence::Range
        },
        overlap_bins: 100,
        candidate_rad: Some(0.5),
        shift: None,
    };
    let deg = |t: &TurnEstimate| config.turn_sigma_rad(t).to_degrees();
    // Significance inverts the confidence z / (z + 3).
    assert!((turn(0.5, false).significance() - 3.0).abs() < 1e-12);
    assert!((turn(0.9, false).significance() - 27.0).abs() < 1e-9);
    assert_eq!(turn(1.0, false).significance(), f64::INFINITY);
    assert!(
        (deg(&turn(0.5, false)) - 1.0).abs() < 1e-9,
        "{}",
        deg(&turn(0.5, false))
    );
    assert!((deg(&turn(0.6, false)) - 2.0 / 3.0).abs() < 1e-9);
    assert!((deg(&turn(0.9, false)) - 0.5).abs() < 1e-9);
    assert!((deg(&turn(1.0, false)) - 0.5).abs() < 1e-9);
    assert!((deg(&turn(0.3, true)) - 3.0).abs() < 1e-9);
    // A loop-fixed turn keeps its failed match's confidence.
    let fixed = TurnEstimate {
        fallback: false,
        evidence: Evidence::Loop,
        ..turn(0.05, true)
    };
    assert!((deg(&fixed) - 0.5).abs() < 1e-9);
}

/// A verified turn of 30.1° (distinct enough to count at
/// `verified_sigma_rad`, 0.5°).
fn verified_turn() -> TurnEstimate {
    TurnEstimate {
        turn_rad: 30.1f64.to_radians(),
        confidence: 1.0,
        fallback: false,
        evidence: Evidence::Range,
        overlap_bins: 100,
        candidate_rad: Some(30.1f64.to_radians()),
        shift: None,
    }
}

/// An ambiguous match of significance 2 (its best match counts at
/// 1.5°) that fell back to its command.
fn ambiguous_turn(command_deg: f64, candidate_deg: f64) -> TurnEstimate {
    TurnEstimate {
        turn_rad: command_deg.to_radians(),
        confidence: 0.4,
        fallback: true,
        evidence: Evidence::Ambiguous,
        candidate_rad: Some(candidate_deg.to_radians()),
        ..verified_turn()
    }
}

/// Eleven turns of 30° and a closing match of 30°, exact; verified
/// turns measured 0.1° long, `ambiguous` ones in their places. Spreads
/// the residual and checks the least squares: each turn where it
/// entered (for the ambiguous ones, in order, `entered`: angle and
/// variance, degrees and square degrees) minus its variance's share of
/// the residual. Returns the turns.
fn close_and_check(ambiguous: &[(usize, TurnEstimate)], entered: &[(f64, f64)]) -> Vec<Option<TurnEstimate>> {
    let config = SweepConfig::default();
    let closing = TurnEstimate {
        turn_rad: 30f64.to_radians(),
        ..verified_turn()
    };
    let mut turns = vec![Some(verified_turn()); 11];
    for &(k, t) in ambiguous {
        turns[k] = Some(t);
    }
    let (residual, applied) = spread_residual(&mut turns, &closing, &config);
    let verified = 11 - ambiguous.len();
    let expected = verified as f64 * 0.1 + entered.iter().map(|e| e.0 - 30.0).sum::<f64>();
    assert!(
        applied && (residual.to_degrees() - expected).abs() < 1e-9,
        "residual {residual}"
    );
    // Variances in square degrees: 0.25 for a verified turn and the
    // closing match.
    let total = 0.25 * (verified + 1) as f64 + entered.iter().map(|e| e.1).sum::<f64>();
    let share = |v: f64| (residual.to_degrees() * v / total).to_radians();
    for (k, t) in turns.iter().enumerate() {
        let t = t.unwrap();
        let (value, v) = match ambiguous.iter().position(|a| a.0 == k) {
            Some(i) => entered[i],
            None => (30.1, 0.25),
        };
        assert!(
            (t.turn_rad - (value.to_radians() - share(v))).abs() < 1e-12,
            "turn {k}"
        );
    }
    turns
}

/// One ambiguous turn (command 2.5° long): its best match 0.05° long
/// lies 1.05° from where the loop puts the turn (1° short), so the loop
/// picks that match's basin and the turn enters at it (1.5°). A best
/// match 4° long is 5° away, a rival's basin: the turn enters at its
/// command (3°). Either way the loop fixes its only unverified turn.
#[test]
fn the_loop_picks_an_ambiguous_turns_basin_or_its_command() {
    let config = SweepConfig::default();
    let sigma = config.candidate_sigma_rad(&ambiguous_turn(32.5, 30.05));
    assert!((sigma.unwrap().to_degrees() - 1.5).abs() < 1e-12);
    for (candidate, entered) in [(30.05, (30.05, 1.5 * 1.5)), (34.0, (32.5, 9.0))] {
        let turns = close_and_check(&[(4, ambiguous_turn(32.5, candidate))], &[entered]);
        assert!(turns[4].is_some_and(|t| !t.fallback && t.evidence == Evidence::Loop));
    }
}

/// Two ambiguous turns (commands 2.5° long and 2° short, best matches
/// 0.3° long and 0.2° short): the best matches' sum lies 1° from where
/// the loop puts it, so the loop picks both basins, and both turns
/// count as fixed by it. With the second best match at a rival 3.5°
/// long, the sum is 4.7° off: both enter at their commands and stay
/// flagged (the loop knows only their sum).
#[test]
fn the_loop_picks_the_basins_of_several_ambiguous_turns_together() {
    for (second, entered) in [
        (29.8, [(30.3, 2.25), (29.8, 2.25)]),
        (33.5, [(32.5, 9.0), (28.0, 9.0)]),
    ] {
        let ambiguous = [(3, ambiguous_turn(32.5, 30.3)), (8, ambiguous_turn(28.0, second))];
        let turns = close_and_check(&ambiguous, &entered);
        let picked = second < 30.0;
        for k in [3, 8] {
            let t = turns[k].unwrap();
            assert_eq!(
                (t.fallback, t.evidence == Evidence::Loop),
                (!picked, picked),
                "{second}"
            );
        }
    }
}

fn scene(bearing: f64) -> f32 {
    let d = bearing.to_degrees().rem_euclid(360.0);
    // An obstacle every 45° (different widths and ranges), so every
    // 30° turn has an edge in its overlap.
    let k = (d / 45.0).floor();
    let local = d - k * 45.0;
    if local < 8.0 + k {
        0.3 + 0.05 * k as f32
    } else {
        f32::INFINITY
    }
}

fn view(heading: f64) -> Rop {
    let w = 0.25f64.to_radians();
    let mut rop = Rop::covering(-30f64.to_radians(), 30f64.to_radians(), w, 0.9).unwrap();
    for i in 0..rop.len() {
        rop.range_m[i] = (0..5)
            .map(|s| scene(heading + rop.bearing_start_rad + (i as f64 + (s as f64 + 0.5) / 5.0) * w))
            .fold(f32::INFINITY, f32::min);
    }
    rop
}

#[test]
fn pirouette_closes_and_recovers_headings() {
    let true_turns_deg = [
        0.0, 31.5, 28.0, 33.0, 29.0, 27.5, 32.0, 30.5, 29.5, 31.0, 28.5, 30.0,
    ];
    let mut heading = 0.0;
    let (mut rops, mut cmds, mut truth) = (Vec::new(), Vec::new(), Vec::new());
    for (k, t) in true_turns_deg.iter().enumerate() {
        heading += f64::to_radians(*t);
        rops.push(view(heading));
        cmds.push((k > 0).then_some(30f64.to_radians()));
        truth.push(heading - true_turns_deg[0]);
    }
    let sweep = assemble(&rops, &cmds, &SweepConfig::default());
    let closure = sweep.closure.expect("the pirouette comes round");
    assert_eq!(closure.frame, 11);
    // Two turns see no edge in their overlap and fall back to the
    // command (true turns 33° and 32°): the loop residual finds them.
    let fallbacks: Vec<usize> = (1..12).filter(|&k| sweep.turns[k].unwrap().fallback).collect();
    assert_eq!(fallbacks, [3, 6]);
    assert!(
        closure.applied && (closure.residual_rad.to_degrees() + 5.0).abs() < 0.5,
        "{closure:?}"
    );
    for (k, h) in sweep.heading_rad.iter().enumerate() {
        assert!(
            (h - truth[k]).abs().to_degrees() < 1.0,
            "frame {k}: {} vs {}",
            h.to_degrees(),
            truth[k].to_degrees()
        );
    }
    // Verified turns keep their sub-degree accuracy.
    for k in (1..12).filter(|k| !fallbacks.contains(k)) {
        let err = sweep.turns[k].unwrap().turn_rad.to_degrees() - true_turns_deg[k];
        assert!(err.abs() < 0.3, "turn {k}: error {err}");
    }
    // The joined sweep sees the obstacle at 90°-99° (k = 2: 10° wide, 0.4 m).
    let i = sweep.rop.bin_of(94f64.to_radians()).unwrap();
    assert!((sweep.rop.range_m[i] - 0.4).abs() < 1e-6);
    let free = sweep.rop.bin_of(120f64.to_radians()).unwrap();
    assert!(sweep.rop.range_m[free].is_infinite());
    assert_eq!(sweep.rop.len(), 1440);
}

/// Starting 2° further round, only the turn before frame 7 (true
/// 30.5°) has no edge in its overlap: the closed loop fixes it, and it
/// counts as verified by the loop, with no link of its own.
#[test]
fn the_one_unmatched_turn_of_a_closed_loop_is_fixed_by_it() {
    let true_turns_deg = [
        2.0, 31.5, 28.0, 33.0, 29.0, 27.5, 32.0, 30.5, 29.5, 31.0, 28.5, 30.0,
    ];
    let mut heading = 0.0;
    let (mut rops, mut cmds) = (Vec::new(), Vec::new());
    for (k, t) in true_turns_deg.iter().enumerate() {
        heading += f64::to_radians(*t);
        rops.push(view(heading));
        cmds.push((k > 0).then_some(30f64.to_radians()));
    }
    let without = SweepConfig {
        close_loop: false,
        ..SweepConfig::default()
    };
    let open = assemble(&rops, &cmds, &without);
    let unmatched: Vec<usize> = (1..12).filter(|&k| open.turns[k].unwrap().fallback).collect();
    assert_eq!(unmatched, [7]);
    let sweep = assemble(&rops, &cmds, &SweepConfig::default());
    assert!(sweep.closure.is_some_and(|c| c.applied));
    let t = sweep.turns[7].unwrap();
    assert!(!t.fallback && t.evidence == Evidence::Loop, "{t:?}");
    let err = t.turn_rad.to_degrees() - 30.5;
    assert!(err.abs() < 0.3, "error {err}");
    assert!(!sweep.links.contains(&(6, 7)) && sweep.links.contains(&(0, 11)));
    for k in (1..12).filter(|&k| k != 7) {
        assert_ne!(sweep.turns[k].unwrap().evidence, Evidence::Loop);
    }
}

/// After the loop (closed by the frame at 342.5°), a turn of 46° leaves
/// 14° of overlap with the frame before, but the frame faces 5° from
/// the sweep's second one. Matched there, a verified turn within half
/// a basin of the re-match stays as it is; one 6° off (a wrong minimum
/// on the narrow overlap) is replaced by the re-match, linked to that
/// frame.
#[test]
fn a_frame_after_the_loop_is_matched_against_the_frame_it_faces() {
    let true_turns_deg = [
        2.0, 31.5, 28.0, 33.0, 29.0, 27.5, 32.0, 30.5, 29.5, 31.0, 28.5, 40.0, 46.0,
    ];
    let mut heading = 0.0;
    let (mut rops, mut cmds) = (Vec::new(), Vec::new());
    for (k, t) in true_turns_deg.iter().enumerate() {
        heading += f64::to_radians(*t);
        rops.push(view(heading));
        cmds.push((k > 0).then_some(f64::to_radians(match k {
            11 => 40.0,
            12 => 44.0,
            _ => 30.0,
        })));
    }
    let config = SweepConfig::default();
    let sweep = assemble(&rops, &cmds, &config);
    assert_eq!(sweep.closure.map(|c| (c.frame, c.applied)), Some((11, true)));
    let measured = sweep.turns[12].unwrap();
    assert!(!measured.fallback, "{measured:?}");
    for (turn_deg, replaced) in [(46.1f64, false), (40.0, true)] {
        let mut turns = sweep.turns.clone();
        let given = TurnEstimate {
            turn_rad: turn_deg.to_radians(),
            ..measured
        };
        turns[12] = Some(given);
        let views: Vec<MatchView> = rops.iter().map(MatchView::from).collect();
        let links = rematch_after_loop(&views, &mut turns, 12, &config);
        let t = turns[12].unwrap();
        if replaced {
            assert_eq!(links, [(1, 12)]);
            let err = t.turn_rad.to_degrees() - 46.0;
            assert!(!t.fallback && err.abs() < 0.3, "error {err}");
        } else {
            assert!(links.is_empty(), "{links:?}");
            assert_eq!(t, given);
        }
    }
}

/// The first frame saw nothing (open floor), so neither its turn nor
/// the closing match verifies and the loop stays open; the frame after
/// it, turned back by 97° (wider than the view), is still matched
/// against the frame it faces, whose heading the verified turns since
/// the last fallback (before frame 7) give.
#[test]
fn frames_after_an_open_loop_are_matched_against_the_frame_they_face() {
    let true_turns_deg = [
        2.0, 31.5, 28.0, 33.0, 29.0, 27.5, 32.0, 30.5, 29.5, 31.0, 28.5, 40.0, -97.0,
    ];
    let mut heading = 0.0;
    let (mut rops, mut cmds) = (Vec::new(), Vec::new());
    for (k, t) in true_turns_deg.iter().enumerate() {
        heading += f64::to_radians(*t);
        let mut rop = view(heading);
        if k == 0 {
            rop.range_m.iter_mut().for_each(|r| *r = f32::INFINITY);
        }
        rops.push(rop);
        cmds.push((k > 0).then_some(f64::to_radians(match k {
            11 => 40.0,
            12 => -95.0,
            _ => 30.0,
        })));
    }
    let sweep = assemble(&rops, &cmds, &SweepConfig::default());
    let closure = sweep.closure.expect("frame 11 comes nearest to round");
    assert!(closure.frame == 11 && !closure.applied, "{closure:?}");
    assert!(sweep.turns[1].unwrap().fallback);
    let t = sweep.turns[12].unwrap();
    assert!(!t.fallback, "{t:?}");
    assert!(sweep.links.contains(&(8, 12)), "{:?}", sweep.links);
    let err = t.turn_rad.to_degrees() + 97.0;
    assert!(err.abs() < 0.3, "error {err}");
}

/// A 1.5 m × 1.3 m room with two boxes, as wall segments.
fn room() -> Vec<[[f64; 2]; 2]> {
    let mut walls = Vec::new();
    let mut poly = |pts: &[[f64; 2]]| {
        for k in 0..pts.len() {
            walls.push([pts[k], pts[(k + 1) % pts.len()]]);
        }
    };
    poly(&[[-0.7, -0.6], [0.8, -0.6], [0.8, 0.7], [-0.7, 0.7]]);
    poly(&[[0.3, 0.2], [0.45, 0.2], [0.45, 0.32], [0.3, 0.32]]);
    poly(&[[-0.4, -0.35], [-0.25, -0.3], [-0.3, -0.15]]);
    walls
}

/// The profile seen from `pos` looking along `heading`: the nearest
/// wall over each 0.25° bin, nothing beyond 0.9 m.
fn view_from(pos: [f64; 2], heading: f64, walls: &[[[f64; 2]; 2]]) -> Rop {
    let w = 0.25f64.to_radians();
    let mut rop = Rop::covering(-30f64.to_radians(), 30f64.to_radians(), w, 0.9).unwrap();
    let cast = |bearing: f64| -> f64 {
        let (dy, dx) = bearing.sin_cos();
        walls
            .iter()
            .filter_map(|[a, b]| {
                // pos + t·d = a + u·(b − a)
                let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
                let den = dx * ey - dy * ex;
                if den.abs() < 1e-12 {
                    return None;
                }
                let (qx, qy) = (a[0] - pos[0], a[1] - pos[1]);
                let t = (qx * ey - qy * ex) / den;
                let u = (qx * dy - qy * dx) / den;
                (t > 0.0 && (0.0..=1.0).contains(&u)).then_some(t)
            })
            .fold(f64::INFINITY, f64::min)
    };
    for i in 0..rop.len() {
        let r = (0..5)
            .map(|s| cast(heading + rop.bearing_start_rad + (i as f64 + (s as f64 + 0.5) / 5.0) * w))
            .fold(f64::INFINITY, f64::min);
        rop.range_m[i] = if r <= 0.9 { r as f32 } else { f32::INFINITY };
    }
    rop
}

/// A robot that turns about a point 5 mm off its centre: the turns'
/// shifts give that point back to a millimetre, and refining the turns
/// about it keeps them as accurate.
#[test]
fn the_pivot_comes_back_from_the_turns() {
    let pivot = [0.004, -0.003];
    let centre = [0.1, 0.05];
    let walls = room();
    let true_turns_deg = [
        10.0, 31.5, 28.0, 33.0, 29.0, 27.5, 32.0, 30.5, 29.5, 31.0, 28.5, 30.0,
    ];
    let (mut rops, mut cmds, mut headings) = (Vec::new(), Vec::new(), Vec::new());
    let mut heading = 0.0;
    for (k, t) in true_turns_deg.iter().enumerate() {
        heading += f64::to_radians(*t);
        let (s, c) = heading.sin_cos();
        let pos = [
            centre[0] - (c * pivot[0] - s * pivot[1]),
            centre[1] - (s * pivot[0] + c * pivot[1]),
        ];
        rops.push(view_from(pos, heading, &walls));
        cmds.push((k > 0).then_some(30f64.to_radians()));
        headings.push(heading);
    }
    let mut config = SweepConfig::default();
    let mut estimate = [0.0; 2];
    for _ in 0..3 {
        let sweep = assemble(&rops, &cmds, &config);
        estimate = pivot_from_turns(sweep.turns.iter().flatten(), 0.002).expect("verified turns");
        config.matching.pivot_m = estimate;
    }
    let err = (estimate[0] - pivot[0]).hypot(estimate[1] - pivot[1]);
    assert!(err < 0.001, "pivot {estimate:?}, true {pivot:?}");
    let sweep = assemble(&rops, &cmds, &config);
    let verified: Vec<f64> = (1..rops.len())
        .filter_map(|k| sweep.turns[k].filter(|t| !t.fallback && t.evidence != Evidence::Loop))
        .map(|t| t.turn_rad)
        .collect();
    assert!(verified.len() >= 5, "{} turns verified", verified.len());
    for k in 1..rops.len() {
        let t = sweep.turns[k].unwrap();
        if !t.fallback {
            let err = (t.turn_rad - (headings[k] - headings[k - 1])).to_degrees();
            assert!(err.abs() < 0.2, "turn {k}: error {err:.3}°");
        }
    }
}

/// Exact algebra: turns whose shifts are exactly what turning about a
/// point makes, one of them seen along a plain wall only (its
/// information singular), give the point back, with or without a
/// floor on each turn's error.
#[test]
fn pivot_from_exact_shifts() {
    let pivot = [-0.003, 0.005];
    // Each turn's estimate is the posterior of its exact shift `d`
    // under a prior about no shift: `(H + λI)·x = H·d`.
    let prior_information = 1e5;
    let turns: Vec<TurnEstimate> = [
        (25f64, [[4e6, 1e6], [1e6, 2e6]]),
        (35.0, [[9e6, 0.0], [0.0, 0.0]]),
        (-30.0, [[1e6, -5e5], [-5e5, 3e6]]),
    ]
    .into_iter()
    .map(|(deg, information)| {
        use nalgebra::{Matrix2, Vector2};
        let (s, c) = deg.to_radians().sin_cos();
        let d = Matrix2::new(1.0 - c, s, -s, 1.0 - c) * Vector2::from(pivot);
        let h = Matrix2::from_fn(|r, c| information[r][c]);
        let x = (h + Matrix2::identity() * prior_information)
            .try_inverse()
            .unwrap()
            * h
            * d;
        TurnEstimate {
            turn_rad: deg.to_radians(),
            confidence: 1.0,
            fallback: false,
            evidence: Evidence::Range,
            overlap_bins: 100,
            candidate_rad: Some(deg.to_radians()),
            shift: Some(crate::matching::TurnShift {
                shift_m: [x.x, x.y],
                prior_mean_m: [0.0, 0.0],
                prior_information,
                information,
            }),
        }
    })
    .collect();
    for floor in [0.0, 0.002] {
        let p = pivot_from_turns(&turns, floor).expect("determined");
        assert!(
            (p[0] - pivot[0]).abs() < 1e-9 && (p[1] - pivot[1]).abs() < 1e-9,
            "{p:?}"
        );
    }
    // A fallback's shift is not evidence.
    let mut fallen = turns.clone();
    for t in &mut fallen {
        t.fallback = true;
    }
    assert!(pivot_from_turns(&fallen, 0.0).is_none());
}
