//! Tests of `plot`.

use super::*;

/// A title and legend go above and below the picture, which is copied
/// unchanged between them; a title too wide for a small picture is
/// drawn at half size rather than widening it much.
#[test]
fn a_titled_picture_keeps_the_picture_and_adds_title_and_legend() {
    let inner = RgbImage::from_pixel(300, 100, Rgb([10, 200, 10]));
    let legend = [
        (Swatch::Dot(MEASURED), "red dots"),
        (Swatch::Line(TRUTH), "green line"),
    ];
    let out = titled(inner.clone(), "A title", &legend);
    assert_eq!(out.width(), 300);
    assert!(out.height() > 100 + 2 * text_height(LABEL_SCALE));
    // The picture sits right under the title bar, unchanged.
    let bar = text_height(LABEL_SCALE) + 2 * 4 * LABEL_SCALE;
    assert!((0..300)
        .all(|x| *out.get_pixel(x, bar) == Rgb([10, 200, 10])
            && *out.get_pixel(x, bar + 99) == Rgb([10, 200, 10])));
    // Ink in the title bar and in the legend.
    assert!((0..bar).any(|y| (0..300).any(|x| *out.get_pixel(x, y) != BACKGROUND)));
    assert!((bar + 100..out.height()).any(|y| (0..300).any(|x| *out.get_pixel(x, y) == MEASURED)));
    let long = titled(
        inner.clone(),
        "A title far too long for a picture three hundred pixels wide",
        &[],
    );
    assert_eq!(long.width(), 300, "wrapped, not widened");
    assert!(long.height() >= 100 + 2 * text_height(1), "two lines at least");
}

/// A picture as wide as its figure grows in place; the figure is the
/// one a fresh canvas with the picture laid over it gives, pixel for
/// pixel, and a narrower picture is laid on a wider canvas at the left.
#[test]
fn a_picture_grown_in_place_equals_one_laid_on_a_canvas() {
    let picture = RgbImage::from_fn(37, 11, |x, y| Rgb([x as u8 * 7, y as u8 * 23, (x * y) as u8]));
    let laid = |width: u32| {
        let mut out = RgbImage::from_pixel(width, 5 + 11 + 3, BACKGROUND);
        image::imageops::overlay(&mut out, &picture, 0, 5);
        out
    };
    assert_eq!(around(picture.clone(), 37, 5, 3), laid(37));
    assert_eq!(around(picture.clone(), 50, 5, 3), laid(50));
    assert_eq!(around(picture.clone(), 37, 0, 0), picture);
}

/// The overlay draws where the model projects the floor grid: a point
/// on two grid lines is in the grid's colour, a point between lines,
/// rings and rays is left as it was.
#[test]
fn the_calibration_overlay_draws_the_grid_where_the_model_projects_it() {
    let camera = pirouette_camera::PinholeModel {
        width: 320,
        height: 240,
        fx: 277.1,
        fy: 277.1,
        cx: 159.5,
        cy: 119.5,
        height_m: 0.1,
        tilt_rad: 25f64.to_radians(),
        mount_forward_m: 0.01,
        mount_left_m: 0.0,
        distortion: Default::default(),
    };
    let black = RgbImage::new(320, 240);
    let img = calibration_overlay(&camera, &black, 1.8);
    // The colours within a pixel of where `p` projects (a line is
    // drawn to the nearest pixel).
    let around = |p: Point2| -> Vec<Rgb<u8>> {
        let (u, v) = camera.floor_to_pixel(p).unwrap();
        let (u, v) = (u.round() as i64, v.round() as i64);
        (-1..=1)
            .flat_map(|dv| (-1..=1).map(move |du| (u + du, v + dv)))
            .map(|(x, y)| *img.get_pixel(x as u32, y as u32))
            .collect()
    };
    assert!(around(Point2::new(0.5, 0.1)).contains(&OVERLAY_GRID));
    assert!(around(Point2::new(0.55, 0.05))
        .iter()
        .all(|c| *c == Rgb([0, 0, 0])));
    // On the 0.75 m ring, between rays and grid lines.
    assert!(around(Point2::from_polar(0.75, 14f64.to_radians())).contains(&OVERLAY_RING));
    // The 0° ray, drawn last, covers the y = 0 grid line.
    let ray = around(Point2::new(0.65, 0.0));
    assert!(
        ray.contains(&OVERLAY_RAY) && !ray.contains(&OVERLAY_GRID),
        "{ray:?}"
    );
}

#[test]
fn diagram_draws_profile_truth_and_limit() {
    let mut rop = Rop::covering(-0.5, 0.5, 1f64.to_radians(), 0.9).unwrap();
    for i in 0..rop.len() {
        rop.range_m[i] = 0.5;
    }
    let img = rop_diagram(&rop, Some(&rop.clone()));
    let count = |c: Rgb<u8>| img.pixels().filter(|p| **p == c).count();
    assert!(count(MEASURED) > 100 && count(LIMIT) > 100 && count(GRID) > 1000);
    // Labels: ranges in the left margin, bearings in the bottom one,
    // never over the plot.
    let (mut left, mut below) = (0, 0);
    for (x, y, p) in img.enumerate_pixels() {
        if *p == LABEL {
            assert!(x < 48 || y >= 400 - 32, "label ink in the plot at ({x}, {y})");
            if x < 48 {
                left += 1
            } else {
                below += 1
            }
        }
    }
    assert!(left > 200 && below > 200, "{left} {below}");
}

#[test]
fn sweep_diagram_labels_its_circles_and_the_limit() {
    let mut rop = Rop::covering(-3.1, 3.1, 1f64.to_radians(), 0.9).unwrap();
    rop.range_m.iter_mut().for_each(|r| *r = 0.5);
    let img = sweep_diagram(&rop);
    let count = |c: Rgb<u8>| img.pixels().filter(|p| **p == c).count();
    // 0.2 … 1.0 m in grey, the limit (0.90) in orange beside its circle.
    assert!(count(LABEL) > 5 * 60, "{}", count(LABEL));
    // Orange off the limit's circle is its label.
    let ring = 0.9 * (300.0 - 10.0) / (0.9 * 1.3);
    let off_ring = img
        .enumerate_pixels()
        .filter(|(x, y, p)| {
            let d = (*x as f64 - 300.0).hypot(*y as f64 - 300.0);
            **p == LIMIT && (d - ring).abs() > 3.0
        })
        .count();
    assert!(off_ring > 40, "{off_ring}");
}

#[test]
fn map_picture_puts_cells_and_sweeps_where_the_map_says() {
    // 100 × 50 cells of 1 cm from (-0.2, -0.1); one occupied cell at
    // map point (0.305, 0.205).
    let (width, height) = (100, 50);
    let mut pixels = vec![grid::FREE; width * height];
    let (col, row) = (50, height - 1 - 30);
    pixels[row * width + col] = grid::OCCUPIED;
    let map = RosMap {
        width,
        height,
        pixels,
        resolution_m: 0.01,
        origin_m: [-0.2, -0.1],
        occupied_thresh: 0.65,
        free_thresh: 0.196,
    };
    let sweep = Pose2::new(0.5, 0.2, 0.0);
    let img = map_picture(&map, &[Pose2::IDENTITY, sweep], &[sweep]);
    let scale = 6; // 600 / 100 cells
    assert_eq!(img.dimensions(), (600, 300));
    assert_eq!(
        *img.get_pixel(50 * scale + 2, row as u32 * scale + 2),
        Rgb([0, 0, 0])
    );
    // The sweep's disc at column (0.5 + 0.2) / 0.01 = 70, row 50 - 30 = 20.
    assert_eq!(*img.get_pixel(70 * scale, 20 * scale), MEASURED);
    assert!(
        img.pixels().any(|p| *p == Rgb([30, 90, 220])),
        "the trajectory is drawn"
    );
    // 600 pixels a metre: 20 cm (120 pixels) is the longest bar within
    // a quarter of the width, 12 pixels in from the bottom left.
    let ink = Rgb([20, 20, 20]);
    let y = 300 - 12;
    assert!((12..=132).all(|x| *img.get_pixel(x, y) == ink));
    assert_ne!(*img.get_pixel(140, y), ink);
}
