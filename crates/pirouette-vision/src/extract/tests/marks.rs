//! Marks on the floor: bases above which the floor shows again within the
//! mark depth are undecided, deeper ones and walls decided.

use super::*;

const FLOOR: [u8; 3] = [100, 95, 85];
const TAPE: [u8; 3] = [40, 38, 34];
const WALL: [u8; 3] = [220, 220, 220];

/// The image row of column 160 whose floor point lies nearest `range_m`.
fn row_at(ex: &RopExtractor, range_m: f64) -> u32 {
    (0..240)
        .filter_map(|v| ex.table().floor(160, v).map(|p| (v, (p.norm() - range_m).abs())))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap()
        .0
}

/// Floor with a strip of `TAPE` over floor ranges `tape` (metres), and a
/// wall from range `wall_m` on when given. Rows are whole: the strip's
/// rows are those whose floor point falls within its ranges.
fn floor_image(ex: &RopExtractor, tape: (f64, f64), wall_m: Option<f64>) -> image::RgbImage {
    let range: Vec<f64> = (0..240)
        .map(|v| ex.table().floor(160, v).map_or(f64::INFINITY, |p| p.norm()))
        .collect();
    image::RgbImage::from_fn(320, 240, |_, v| {
        let r = range[v as usize];
        image::Rgb(if wall_m.is_some_and(|w| r >= w) {
            WALL
        } else if r >= tape.0 && r <= tape.1 {
            TAPE
        } else {
            FLOOR
        })
    })
}

fn extractor(mark_depth_m: f32) -> RopExtractor {
    RopExtractor::new(
        &cam(),
        0.9,
        VisionConfig {
            mark_depth_m,
            ..VisionConfig::default()
        },
    )
}

/// The middle half of the columns.
fn middle(b: &[ColumnBoundary]) -> &[ColumnBoundary] {
    &b[80..240]
}

/// Of the middle half of the columns, those decided as an obstacle whose
/// base lies within 1.5 rows of `base`, the floor followed all the way.
fn decided_at(b: &[ColumnBoundary], base: u32) -> usize {
    (middle(b).iter())
        .filter(|c| {
            matches!(c, ColumnBoundary::Obstacle { row, undecided: None, .. } if (row - base as f32).abs() <= 1.5)
        })
        .count()
}

/// A strip of tape 15 cm deep across the floor at 0.45 m (taller in the
/// image than a 2 cm obstacle there): the floor shows
/// again above it, so every column is undecided at the strip's nearest
/// row; with the mark depth at 0 every column takes it for an obstacle's
/// base, as the scan did before marks were undecided.
#[test]
fn a_strip_of_tape_is_undecided_not_an_obstacle() {
    let ex = extractor(0.25);
    let img = floor_image(&ex, (0.45, 0.60), None);
    let base = row_at(&ex, 0.45);
    let b = ex.boundaries(&img).unwrap();
    let undecided = middle(&b)
        .iter()
        .filter(|c| matches!(c, ColumnBoundary::Undecided { row } if row.abs_diff(base) <= 1))
        .count();
    assert_eq!(
        undecided,
        160,
        "{:?}",
        middle(&b)
            .iter()
            .find(|c| !matches!(c, ColumnBoundary::Undecided { .. }))
    );
    // Seen from the robot: nothing in sight, the floor known to the strip.
    let rop = ex.rop_from_boundaries(&b);
    let centre = rop.bin_of(0.0).unwrap();
    assert_eq!(rop.range_m[centre], f32::INFINITY);
    assert!(
        (rop.free_reach(centre) - 0.45).abs() < 0.01,
        "{}",
        rop.free_reach(centre)
    );

    let b = extractor(0.0).boundaries(&img).unwrap();
    assert_eq!(decided_at(&b, base), 160);
}

/// The strip, then a wall at 0.75 m: the wall is the obstacle, the floor
/// known only up to the strip. A profile bin holds the wall's range and
/// is free only to the strip.
#[test]
fn a_wall_beyond_a_strip_is_found_and_the_floor_known_to_the_strip() {
    let ex = extractor(0.25);
    let img = floor_image(&ex, (0.45, 0.60), Some(0.75));
    let (base, wall) = (row_at(&ex, 0.45), row_at(&ex, 0.75));
    let b = ex.boundaries(&img).unwrap();
    let found = middle(&b)
        .iter()
        .filter(|c| {
            matches!(c, ColumnBoundary::Obstacle { row, undecided: Some(w), .. }
                if (row - wall as f32).abs() <= 1.5 && w.abs_diff(base) <= 1)
        })
        .count();
    assert_eq!(found, 160, "{:?}", middle(&b)[80]);
    let rop = ex.rop_from_boundaries(&b);
    let centre = rop.bin_of(0.0).unwrap();
    assert!(
        (rop.range_m[centre] - 0.75).abs() < 0.01,
        "{}",
        rop.range_m[centre]
    );
    assert!(
        (rop.free_reach(centre) - 0.45).abs() < 0.01,
        "{}",
        rop.free_reach(centre)
    );
}

/// A strip deeper than the mark depth (0.45 to 0.75 m, with a depth of
/// 25 cm): one view cannot tell it from an obstacle that hides the floor
/// that far, and it is decided as one, the floor followed all the way.
#[test]
fn a_strip_deeper_than_the_mark_depth_is_an_obstacle() {
    let ex = extractor(0.25);
    let img = floor_image(&ex, (0.45, 0.75), None);
    let base = row_at(&ex, 0.45);
    let b = ex.boundaries(&img).unwrap();
    assert_eq!(decided_at(&b, base), 160);
}

/// An undecided base within two columns of a decided base on its line
/// (1.5 rows a column apart at most) is that obstacle's; one farther off,
/// or off the line, stays undecided.
#[test]
fn undecided_bases_on_a_decided_base_line_are_decided() {
    let obstacle = |row: f32| ColumnBoundary::Obstacle {
        row,
        colour: None,
        undecided: None,
    };
    let undecided = ColumnBoundary::Undecided { row: 50 };
    let mut out = vec![
        obstacle(50.0),
        undecided,
        undecided,
        undecided,
        undecided,
        ColumnBoundary::Clear { top_row: 0 },
    ];
    let bases = vec![
        None,
        Some(obstacle(50.4)),
        Some(obstacle(52.9)),
        Some(obstacle(50.2)),
        Some(obstacle(60.0)),
        None,
    ];
    super::super::rows::settle(&mut out, &bases);
    assert_eq!(out[1], obstacle(50.4));
    assert_eq!(out[2], obstacle(52.9), "2.9 rows two columns away: on the line");
    assert_eq!(out[3], undecided, "three columns away");
    assert_eq!(out[4], undecided, "off the line");
}
