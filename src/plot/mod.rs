//! Pictures for people: ROP diagrams, top-down floor views, boundary
//! overlays, sweep diagrams and maps (PNG), with their axes labelled.

mod text;

use text::{draw_text, text_height, text_width};

use image::{Rgb, RgbImage};
use imageproc::drawing::{draw_filled_circle_mut, draw_hollow_circle_mut, draw_line_segment_mut};
use pirouette_camera::CameraModel;
use pirouette_geom::{Point2, Pose2};
use pirouette_grid::{self as grid, RosMap};
use pirouette_profile::Rop;
use pirouette_vision::ColumnBoundary;

/// Grid spacing of range, metres (the paper's Fig. 4).
pub const GRID_RANGE_M: f64 = 0.1;
/// Grid spacing of bearing, degrees (the paper's Fig. 4).
pub const GRID_BEARING_DEG: f64 = 10.0;

const BACKGROUND: Rgb<u8> = Rgb([255, 255, 255]);
const GRID: Rgb<u8> = Rgb([215, 215, 215]);
const LIMIT: Rgb<u8> = Rgb([240, 160, 40]);
const MEASURED: Rgb<u8> = Rgb([210, 30, 30]);
const TRUTH: Rgb<u8> = Rgb([30, 150, 60]);
const UNDECIDED: Rgb<u8> = Rgb([40, 90, 230]);
const LABEL: Rgb<u8> = Rgb([70, 70, 70]);
/// Font scale of the labels (a 5 × 7 font: 14 pixels tall).
const LABEL_SCALE: u32 = 2;

/// A range label, metres, as the grid lines are spaced.
fn metres(r: f64) -> String {
    format!("{r:.1}")
}

/// Draws `text` centred on `(x, y)`, on a one-pixel white halo so that it
/// reads on dark floor too.
fn label_centred(img: &mut RgbImage, (x, y): (f32, f32), text: &str, colour: Rgb<u8>) {
    let (w, h) = (text_width(text, LABEL_SCALE), text_height(LABEL_SCALE));
    let (x0, y0) = (x as i32 - w as i32 / 2, y as i32 - h as i32 / 2);
    for dy in -1..=1 {
        for dx in -1..=1 {
            draw_text(img, x0 + dx, y0 + dy, text, BACKGROUND, LABEL_SCALE);
        }
    }
    draw_text(img, x0, y0, text, colour, LABEL_SCALE);
}

/// The ROP diagram: range (up) against bearing (left of the robot on the
/// left), grid lines every 10 cm and 10° (ranges labelled every 20 cm,
/// metres, bearings every 10°), the soft range limit in orange, the
/// measured profile in red and, when given, the true one in green.
pub fn rop_diagram(rop: &Rop, truth: Option<&Rop>) -> RgbImage {
    let (w, h) = (640u32, 400u32);
    // Room for the range labels on the left and the bearings below.
    let (left, right, top, bottom) = (48.0f32, 20.0f32, 20.0f32, 32.0f32);
    let mut img = RgbImage::from_pixel(w, h, BACKGROUND);
    let b_lo = rop.bearing_start_rad;
    let b_hi = rop.bin_centre_rad(rop.len().saturating_sub(1)) + rop.bin_width_rad / 2.0;
    let r_top = ((rop.max_range_m as f64 * 1.25) / GRID_RANGE_M).ceil() * GRID_RANGE_M;
    let x_of = |b: f64| left + ((b_hi - b) / (b_hi - b_lo)) as f32 * (w as f32 - left - right);
    let y_of = |r: f64| h as f32 - bottom - (r / r_top) as f32 * (h as f32 - top - bottom);
    let lines = (r_top / GRID_RANGE_M).round() as i64;
    for k in 0..=lines {
        let r = k as f64 * GRID_RANGE_M;
        draw_line_segment_mut(&mut img, (left, y_of(r)), (w as f32 - right, y_of(r)), GRID);
        // The top line carries the unit.
        if k == lines {
            label_centred(&mut img, (left / 2.0, y_of(r)), "m", LABEL);
        } else if k % 2 == 0 {
            label_centred(&mut img, (left / 2.0, y_of(r)), &metres(r), LABEL);
        }
    }
    let (k_lo, k_hi) = (
        (b_lo.to_degrees() / GRID_BEARING_DEG).ceil() as i64,
        (b_hi.to_degrees() / GRID_BEARING_DEG).floor() as i64,
    );
    for k in k_lo..=k_hi {
        let b = (k as f64 * GRID_BEARING_DEG).to_radians();
        draw_line_segment_mut(&mut img, (x_of(b), top), (x_of(b), h as f32 - bottom), GRID);
        let text = format!("{}°", k as f64 * GRID_BEARING_DEG);
        label_centred(&mut img, (x_of(b), h as f32 - bottom / 2.0), &text, LABEL);
    }
    draw_line_segment_mut(
        &mut img,
        (x_of(0.0), top),
        (x_of(0.0), h as f32 - bottom),
        Rgb([160, 160, 160]),
    );
    let limit = y_of(rop.max_range_m as f64);
    draw_line_segment_mut(&mut img, (left, limit), (w as f32 - right, limit), LIMIT);
    for (profile, colour) in truth.map(|t| (t, TRUTH)).into_iter().chain([(rop, MEASURED)]) {
        let mut last: Option<(f32, f32)> = None;
        for i in 0..profile.len() {
            let Some(r) = profile.reliable(i) else {
                last = None;
                continue;
            };
            let p = (x_of(profile.bin_centre_rad(i)), y_of(r as f64));
            if let Some(q) = last {
                draw_line_segment_mut(&mut img, q, p, colour);
            }
            draw_filled_circle_mut(&mut img, (p.0 as i32, p.1 as i32), 2, colour);
            last = Some(p);
        }
    }
    img
}

/// A radial grid around `centre`: circles every [`GRID_RANGE_M`] out to
/// `reach_m` (every other one labelled in metres along the forward ray),
/// the soft limit in orange with its value, rays every
/// [`GRID_BEARING_DEG`] over `bearings_deg` (inclusive);
/// `polar(range, bearing)` places a point.
fn radial_grid(
    img: &mut RgbImage,
    centre: (f32, f32),
    scale: f64,
    reach_m: f64,
    max_range_m: f64,
    bearings_deg: (f64, f64),
    polar: impl Fn(f64, f64) -> (f32, f32),
) {
    let c = (centre.0 as i32, centre.1 as i32);
    let mut r = GRID_RANGE_M;
    while r <= reach_m {
        draw_hollow_circle_mut(img, c, (r * scale) as i32, GRID);
        r += GRID_RANGE_M;
    }
    draw_hollow_circle_mut(img, c, (max_range_m * scale) as i32, LIMIT);
    let mut b = bearings_deg.0;
    while b <= bearings_deg.1 + 1e-9 {
        draw_line_segment_mut(img, centre, polar(reach_m, b.to_radians()), GRID);
        b += GRID_BEARING_DEG;
    }
    // Every other circle labelled, metres, just right of the forward ray;
    // the soft limit's value in orange left of it.
    let h = text_height(LABEL_SCALE) as f32;
    let rings = (reach_m / GRID_RANGE_M + 1e-9).floor() as i64;
    for k in (2..=rings).step_by(2) {
        let r = k as f64 * GRID_RANGE_M;
        let (x, y) = polar(r, 0.0);
        let text = metres(r);
        let w = text_width(&text, LABEL_SCALE) as f32;
        label_centred(img, (x + 4.0 + w / 2.0, y - h / 2.0 - 2.0), &text, LABEL);
    }
    let text = format!("{max_range_m:.2}");
    let (x, y) = polar(max_range_m, 0.0);
    let w = text_width(&text, LABEL_SCALE) as f32;
    label_centred(img, (x - 4.0 - w / 2.0, y - h / 2.0 - 2.0), &text, LIMIT);
}

/// The top-down floor view: the camera image warped onto the floor (robot
/// at the bottom centre, forward up), a radial grid every 10 cm and 10°,
/// and the profile's obstacle points in red.
pub fn floor_view(camera: &impl CameraModel, image: &RgbImage, rop: &Rop) -> RgbImage {
    let size = 480u32;
    let mut img = RgbImage::from_pixel(size, size, BACKGROUND);
    let reach_m = rop.max_range_m as f64 * 1.2;
    let scale = (size as f64 - 20.0) / reach_m;
    let origin = (size as f64 / 2.0, size as f64 - 10.0);
    let to_canvas = |p: Point2| ((origin.0 - p.y * scale) as f32, (origin.1 - p.x * scale) as f32);
    for cy in 0..size {
        for cx in 0..size {
            let p = Point2::new((origin.1 - cy as f64) / scale, (origin.0 - cx as f64) / scale);
            if p.x <= 0.0 {
                continue;
            }
            let Some((u, v)) = camera.floor_to_pixel(p) else {
                continue;
            };
            if camera.contains(u, v) && camera.pixel_to_floor(u, v).is_some() {
                let (ui, vi) = (
                    u.round().clamp(0.0, image.width() as f64 - 1.0),
                    v.round().clamp(0.0, image.height() as f64 - 1.0),
                );
                img.put_pixel(cx, cy, *image.get_pixel(ui as u32, vi as u32));
            }
        }
    }
    let polar = |r: f64, b: f64| to_canvas(Point2::from_polar(r, b));
    radial_grid(
        &mut img,
        (origin.0 as f32, origin.1 as f32),
        scale,
        reach_m,
        rop.max_range_m as f64,
        (-90.0, 90.0),
        polar,
    );
    for i in 0..rop.len() {
        if let Some(r) = rop.reliable(i) {
            let (x, y) = to_canvas(Point2::from_polar(r as f64, rop.bin_centre_rad(i)));
            draw_filled_circle_mut(&mut img, (x as i32, y as i32), 2, MEASURED);
        }
    }
    img
}

/// The camera image with the floor/obstacle boundary of every column drawn
/// in red (green where the column is clear to its top floor row), and
/// undecided bases (a mark on the floor or a low obstacle) in blue.
pub fn boundary_overlay(image: &RgbImage, boundaries: &[ColumnBoundary]) -> RgbImage {
    let mut img = image.clone();
    let bottom = img.height() as f32 - 1.0;
    for (u, b) in boundaries.iter().enumerate() {
        let mut put = |row: f32, colour: Rgb<u8>| {
            img.put_pixel(u as u32, row.round().clamp(0.0, bottom) as u32, colour);
        };
        match *b {
            ColumnBoundary::Obstacle { row, undecided, .. } => {
                put(row, MEASURED);
                if let Some(w) = undecided {
                    put(w as f32, UNDECIDED);
                }
            }
            ColumnBoundary::Clear { top_row } => put(top_row as f32, TRUTH),
            ColumnBoundary::Undecided { row } => put(row as f32, UNDECIDED),
            ColumnBoundary::NoFloor => {}
        }
    }
    img
}

/// The top-down sweep diagram (the paper's Fig. 5): the 360° profile around
/// the robot, seen floor in light grey, obstacles within the soft limit in
/// red, ranges beyond it in grey, a radial grid every 10 cm and 10°.
pub fn sweep_diagram(sweep: &Rop) -> RgbImage {
    let size = 600u32;
    let mut img = RgbImage::from_pixel(size, size, BACKGROUND);
    let reach_m = sweep.max_range_m as f64 * 1.3;
    let scale = (size as f64 / 2.0 - 10.0) / reach_m;
    let c = (size as f64 / 2.0, size as f64 / 2.0);
    // Forward (0°) up, left (+90°) to the left.
    let to_canvas = |r: f64, b: f64| {
        (
            (c.0 - r * b.sin() * scale) as f32,
            (c.1 - r * b.cos() * scale) as f32,
        )
    };
    for i in 0..sweep.len() {
        if !sweep.seen(i) {
            continue;
        }
        let r = (sweep.range_m[i] as f64).min(reach_m);
        let b = sweep.bin_centre_rad(i);
        draw_line_segment_mut(
            &mut img,
            (c.0 as f32, c.1 as f32),
            to_canvas(r, b),
            Rgb([225, 225, 225]),
        );
    }
    radial_grid(
        &mut img,
        (c.0 as f32, c.1 as f32),
        scale,
        reach_m,
        sweep.max_range_m as f64,
        (0.0, 350.0),
        to_canvas,
    );
    for i in 0..sweep.len() {
        let r = sweep.range_m[i] as f64;
        if !r.is_finite() || r > reach_m {
            continue;
        }
        let colour = if sweep.reliable(i).is_some() {
            MEASURED
        } else {
            Rgb([150, 150, 150])
        };
        let (x, y) = to_canvas(r, sweep.bin_centre_rad(i));
        draw_filled_circle_mut(&mut img, (x as i32, y as i32), 2, colour);
    }
    draw_filled_circle_mut(&mut img, (c.0 as i32, c.1 as i32), 4, Rgb([40, 40, 40]));
    img
}

/// The map for people: free floor white, obstacles black, unknown grey,
/// each cell a `scale`-pixel square (chosen so that the picture is at least
/// 600 pixels across, at most 8 per cell); the trajectory in blue, each
/// sweep's spot as a red disc with a tick along its first frame's heading,
/// the map frame's origin as a green disc, and a scale bar.
pub fn map_picture(map: &RosMap, frames: &[Pose2], sweeps: &[Pose2]) -> RgbImage {
    let longest = map.width.max(map.height).max(1);
    let scale = (600usize.div_ceil(longest)).clamp(1, 8) as u32;
    let (w, h) = (map.width as u32 * scale, map.height as u32 * scale);
    let mut img = RgbImage::new(w.max(1), h.max(1));
    for (k, &grey) in map.pixels.iter().enumerate() {
        let (col, row) = ((k % map.width) as u32, (k / map.width) as u32);
        let colour = match grey {
            grid::FREE => Rgb([255, 255, 255]),
            grid::OCCUPIED => Rgb([0, 0, 0]),
            _ => Rgb([190, 190, 190]),
        };
        for dy in 0..scale {
            for dx in 0..scale {
                img.put_pixel(col * scale + dx, row * scale + dy, colour);
            }
        }
    }
    let to_canvas = |p: Point2| {
        let col = (p.x - map.origin_m[0]) / map.resolution_m;
        let row = map.height as f64 - (p.y - map.origin_m[1]) / map.resolution_m;
        ((col * scale as f64) as f32, (row * scale as f64) as f32)
    };
    let path = Rgb([30, 90, 220]);
    for pair in frames.windows(2) {
        draw_line_segment_mut(
            &mut img,
            to_canvas(pair[0].translation()),
            to_canvas(pair[1].translation()),
            path,
        );
    }
    let radius = (3 * scale as i32).clamp(4, 12);
    for pose in sweeps {
        let (x, y) = to_canvas(pose.translation());
        draw_filled_circle_mut(&mut img, (x as i32, y as i32), radius, MEASURED);
        let tip = to_canvas(pose.transform_point(Point2::new(
            2.5 * radius as f64 * map.resolution_m / scale as f64,
            0.0,
        )));
        draw_line_segment_mut(&mut img, (x, y), tip, MEASURED);
    }
    let (x, y) = to_canvas(Point2::new(0.0, 0.0));
    draw_filled_circle_mut(&mut img, (x as i32, y as i32), radius / 2, TRUTH);
    scale_bar(&mut img, scale as f64 / map.resolution_m);
    img
}

/// A legend entry's mark.
#[derive(Debug, Clone, Copy)]
pub enum Swatch {
    /// A filled square of the colour (an area, a cell).
    Fill(Rgb<u8>),
    /// A line of the colour (a path, a profile).
    Line(Rgb<u8>),
    /// A dot of the colour (a place).
    Dot(Rgb<u8>),
}

/// `img` with a title above it and a legend below: each entry a swatch
/// and its words, laid out in rows. Where the picture is at least as
/// wide as the figure, its own buffer grows to hold the title and legend,
/// so a large map's picture is never held twice.
pub fn titled(img: RgbImage, title: &str, legend: &[(Swatch, &str)]) -> RgbImage {
    // Half-size text where the title would not fit a small picture, and
    // the title wrapped at spaces where even that is too wide.
    let scale = if text_width(title, LABEL_SCALE) + 16 > img.width() {
        1
    } else {
        LABEL_SCALE
    };
    let th = text_height(scale);
    let (pad, swatch, gap) = (4 * scale, th, 9 * scale);
    let width = img.width().max(120);
    let mut lines: Vec<String> = vec![String::new()];
    for word in title.split(' ') {
        let last = lines.last().map(String::as_str).unwrap_or("");
        let joined = if last.is_empty() {
            word.to_string()
        } else {
            format!("{last} {word}")
        };
        if text_width(&joined, scale) + 2 * pad > width && !last.is_empty() {
            lines.push(word.to_string());
        } else if let Some(l) = lines.last_mut() {
            *l = joined;
        }
    }
    // Entries placed in rows that fit the width.
    let mut rows: Vec<Vec<(u32, Swatch, &str)>> = vec![Vec::new()];
    let mut x = pad;
    for &(mark, words) in legend {
        let w = swatch + 6 + text_width(words, scale);
        if x + w + pad > width && x > pad {
            rows.push(Vec::new());
            x = pad;
        }
        if let Some(row) = rows.last_mut() {
            row.push((x, mark, words));
        }
        x += w + gap;
    }
    let title_h = lines.len() as u32 * (th + pad) + pad;
    let row_h = th + pad;
    let legend_h = if legend.is_empty() {
        0
    } else {
        rows.len() as u32 * row_h + pad
    };
    let mut out = around(img, width, title_h, legend_h);
    for (k, line) in lines.iter().enumerate() {
        let y = pad + k as u32 * (th + pad);
        draw_text(&mut out, pad as i32, y as i32, line, Rgb([20, 20, 20]), scale);
    }
    let img_h = out.height() - title_h - legend_h;
    for (r, row) in rows.iter().enumerate() {
        let y = title_h + img_h + pad / 2 + r as u32 * row_h;
        for &(x, mark, words) in row {
            let (cx, cy) = ((x + swatch / 2) as f32, (y + swatch / 2) as f32);
            match mark {
                Swatch::Fill(c) => {
                    for dy in 0..swatch {
                        for dx in 0..swatch {
                            let edge = dx == 0 || dy == 0 || dx == swatch - 1 || dy == swatch - 1;
                            out.put_pixel(x + dx, y + dy, if edge { LABEL } else { c });
                        }
                    }
                }
                Swatch::Line(c) => {
                    for d in -1..=1 {
                        let yy = cy + d as f32;
                        draw_line_segment_mut(&mut out, (x as f32, yy), ((x + swatch) as f32, yy), c);
                    }
                }
                Swatch::Dot(c) => {
                    draw_filled_circle_mut(&mut out, (cx as i32, cy as i32), (swatch / 2) as i32, c)
                }
            }
            draw_text(&mut out, (x + swatch + 6) as i32, y as i32, words, LABEL, scale);
        }
    }
    out
}

/// `img` on a canvas `width` wide with `above` rows of background over
/// it and `below` rows under it. A picture already `width` wide keeps its
/// buffer: it grows, and the picture's rows move down in place.
fn around(img: RgbImage, width: u32, above: u32, below: u32) -> RgbImage {
    let (w, h) = img.dimensions();
    let height = above + h + below;
    if w != width {
        let mut out = RgbImage::from_pixel(width, height, BACKGROUND);
        image::imageops::overlay(&mut out, &img, 0, i64::from(above));
        return out;
    }
    let row = 3 * w as usize;
    let mut buf = img.into_raw();
    let picture = buf.len();
    let shift = above as usize * row;
    buf.reserve_exact((above + below) as usize * row);
    buf.resize(picture + (above + below) as usize * row, 0);
    buf.copy_within(0..picture, shift);
    let (top, rest) = buf.split_at_mut(shift);
    for pixel in top.chunks_exact_mut(3).chain(rest[picture..].chunks_exact_mut(3)) {
        pixel.copy_from_slice(&BACKGROUND.0);
    }
    RgbImage::from_raw(width, height, buf).expect("the buffer holds width × height pixels")
}

/// [`map_picture`] with a title and its legend: what each colour and
/// mark means, and how the map frame's axes lie (+x right, +y up).
/// Without sweeps (a laser log's map), the sweep mark is left out of the
/// legend.
pub fn map_figure(map: &RosMap, frames: &[Pose2], sweeps: &[Pose2], title: &str) -> RgbImage {
    let mut legend = vec![
        (Swatch::Fill(Rgb([255, 255, 255])), "free floor"),
        (Swatch::Fill(Rgb([0, 0, 0])), "obstacle"),
        (Swatch::Fill(Rgb([190, 190, 190])), "unknown"),
        (Swatch::Line(Rgb([30, 90, 220])), "robot path"),
    ];
    if !sweeps.is_empty() {
        legend.push((Swatch::Dot(MEASURED), "sweep spot, tick = heading"));
    }
    legend.push((Swatch::Dot(TRUTH), "first frame: map origin, facing +x"));
    legend.push((Swatch::Line(LABEL), "map axes: +x right, +y up"));
    titled(map_picture(map, frames, sweeps), title, &legend)
}

/// [`rop_diagram`] with a title naming the frame and its legend.
pub fn rop_figure(rop: &Rop, truth: Option<&Rop>, frame: &str) -> RgbImage {
    let mut legend = vec![(Swatch::Dot(MEASURED), "measured range")];
    if truth.is_some() {
        legend.push((Swatch::Dot(TRUTH), "true range"));
    }
    legend.push((Swatch::Line(LIMIT), "soft range limit"));
    legend.push((Swatch::Line(GRID), "grid: 10 cm, 10 deg; bearing + = left"));
    titled(
        rop_diagram(rop, truth),
        &format!("Radial obstacle profile of {frame}"),
        &legend,
    )
}

/// [`sweep_diagram`] with a title naming the sweep and its legend.
pub fn sweep_figure(sweep: &Rop, name: &str) -> RgbImage {
    titled(
        sweep_diagram(sweep),
        &format!("360 deg radial sweep {name} (forward up)"),
        &[
            (Swatch::Fill(Rgb([225, 225, 225])), "floor seen"),
            (Swatch::Line(LIMIT), "soft range limit"),
            (Swatch::Dot(MEASURED), "obstacle within the soft limit"),
            (Swatch::Dot(Rgb([150, 150, 150])), "range beyond it"),
            (Swatch::Dot(Rgb([40, 40, 40])), "robot"),
            (Swatch::Line(GRID), "grid: 10 cm, 10 deg"),
        ],
    )
}

/// [`floor_view`] with a title naming the frame and its legend.
pub fn floor_figure(camera: &impl CameraModel, image: &RgbImage, rop: &Rop, frame: &str) -> RgbImage {
    titled(
        floor_view(camera, image, rop),
        &format!("Floor seen from above, {frame} (robot at the bottom, forward up)"),
        &[
            (Swatch::Dot(MEASURED), "obstacle found"),
            (Swatch::Line(LIMIT), "soft range limit"),
            (Swatch::Line(GRID), "grid: 10 cm, 10 deg"),
        ],
    )
}

/// [`boundary_overlay`] with a title naming the frame and its legend.
pub fn boundary_figure(image: &RgbImage, boundaries: &[ColumnBoundary], frame: &str) -> RgbImage {
    titled(
        boundary_overlay(image, boundaries),
        &format!("Floor boundary in {frame}"),
        &[
            (Swatch::Line(MEASURED), "obstacle's base"),
            (Swatch::Line(TRUTH), "floor clear to the top"),
            (Swatch::Line(UNDECIDED), "undecided: a mark or a low obstacle"),
        ],
    )
}

/// Colours of the calibration overlay's floor grid, range rings and
/// bearing rays.
pub const OVERLAY_GRID: Rgb<u8> = Rgb([0, 220, 255]);
/// See [`OVERLAY_GRID`].
pub const OVERLAY_RING: Rgb<u8> = Rgb([255, 210, 0]);
/// See [`OVERLAY_GRID`].
pub const OVERLAY_RAY: Rgb<u8> = Rgb([255, 60, 200]);

/// The camera image with the floor grid its model projects onto it, to
/// check a calibration by eye: lines every 10 cm along and across the
/// robot's heading, range rings every 25 cm and bearing rays every 10°
/// from the turning centre, out to `reach_m`. Where the model is right,
/// a line on a floor seam or tape in the image lies on it.
pub fn calibration_overlay(camera: &impl CameraModel, image: &RgbImage, reach_m: f64) -> RgbImage {
    let mut img = image.clone();
    // A floor curve drawn as short projected segments, each kept only
    // where both ends fall in the image.
    let mut curve = |points: &mut dyn Iterator<Item = Point2>, colour: Rgb<u8>| {
        let mut last: Option<(f64, f64)> = None;
        for p in points {
            let here = camera.floor_to_pixel(p).filter(|&(u, v)| camera.contains(u, v));
            if let (Some(a), Some(b)) = (last, here) {
                draw_line_segment_mut(
                    &mut img,
                    (a.0 as f32, a.1 as f32),
                    (b.0 as f32, b.1 as f32),
                    colour,
                );
            }
            last = here;
        }
    };
    let step = 0.005;
    let n = (reach_m / step).ceil() as i64;
    let lines = (reach_m / GRID_RANGE_M).floor() as i64;
    for k in -lines..=lines {
        let c = k as f64 * GRID_RANGE_M;
        // Across the heading (x = c) and along it (y = c).
        curve(
            &mut (-n..=n).map(|i| Point2::new(c, i as f64 * step)),
            OVERLAY_GRID,
        );
        curve(
            &mut (0..=n).map(|i| Point2::new(i as f64 * step, c)),
            OVERLAY_GRID,
        );
    }
    let rings = (reach_m / 0.25).floor() as i64;
    for k in 1..=rings {
        let r = k as f64 * 0.25;
        curve(
            &mut (-900..=900).map(|i| Point2::from_polar(r, (i as f64 * 0.1).to_radians())),
            OVERLAY_RING,
        );
    }
    for k in -9..=9 {
        let b = (k as f64 * GRID_BEARING_DEG).to_radians();
        curve(
            &mut (0..=n).map(|i| Point2::from_polar(i as f64 * step, b)),
            OVERLAY_RAY,
        );
    }
    img
}

/// [`calibration_overlay`] with a title naming the frame and its legend.
pub fn calibration_figure(
    camera: &impl CameraModel,
    image: &RgbImage,
    reach_m: f64,
    frame: &str,
) -> RgbImage {
    titled(
        calibration_overlay(camera, image, reach_m),
        &format!("Calibration check, {frame}: the floor grid the camera model projects"),
        &[
            (Swatch::Line(OVERLAY_GRID), "10 cm grid"),
            (Swatch::Line(OVERLAY_RING), "range every 25 cm"),
            (Swatch::Line(OVERLAY_RAY), "bearing every 10 deg"),
        ],
    )
}

/// A scale bar in the bottom left corner: the longest of 1 m, 50, 20 and
/// 10 cm that takes at most a quarter of the picture's width, labelled.
/// `px_per_m`: pixels per metre.
fn scale_bar(img: &mut RgbImage, px_per_m: f64) {
    let quarter = img.width() as f64 / 4.0;
    let Some((m, text)) = [(1.0, "1 m"), (0.5, "50 cm"), (0.2, "20 cm"), (0.1, "10 cm")]
        .into_iter()
        .find(|(m, _)| m * px_per_m <= quarter)
    else {
        return;
    };
    let len = (m * px_per_m).round() as i32;
    let (x0, y) = (12i32, img.height() as i32 - 12);
    let ink = Rgb([20, 20, 20]);
    for dy in -1..=1 {
        let y = (y + dy) as f32;
        draw_line_segment_mut(img, (x0 as f32, y), ((x0 + len) as f32, y), ink);
    }
    for x in [x0, x0 + len] {
        draw_line_segment_mut(img, (x as f32, (y - 6) as f32), (x as f32, (y + 1) as f32), ink);
    }
    let h = text_height(LABEL_SCALE) as f32;
    label_centred(
        img,
        (x0 as f32 + len as f32 / 2.0, y as f32 - 6.0 - h / 2.0 - 2.0),
        text,
        ink,
    );
}

/// The precision-recall curve of place queries as the score threshold
/// varies: recall (right) against precision (up), both 0-1 with grid lines
/// every 0.1, one dot per threshold joined in order of threshold, the
/// threshold written beside every few dots.
pub fn pr_figure(curve: &[(f64, f64, f64)], name: &str) -> RgbImage {
    let (side, margin) = (400u32, 50u32);
    let mut img = RgbImage::from_pixel(side + 2 * margin, side + 2 * margin, BACKGROUND);
    let at = |recall: f64, precision: f64| {
        (
            margin as f32 + (recall.clamp(0.0, 1.0) * side as f64) as f32,
            (margin + side) as f32 - (precision.clamp(0.0, 1.0) * side as f64) as f32,
        )
    };
    for k in 0..=10 {
        let v = k as f64 / 10.0;
        draw_line_segment_mut(&mut img, at(v, 0.0), at(v, 1.0), GRID);
        draw_line_segment_mut(&mut img, at(0.0, v), at(1.0, v), GRID);
        if k % 2 == 0 {
            let (x, y) = at(v, 0.0);
            label_centred(&mut img, (x, y + 14.0), &format!("{v:.1}"), LABEL);
            let (x, y) = at(0.0, v);
            label_centred(&mut img, (x - 22.0, y), &format!("{v:.1}"), LABEL);
        }
    }
    let (x, y) = at(0.5, 0.0);
    label_centred(&mut img, (x, y + 34.0), "recall@1", LABEL);
    let (x, y) = at(0.0, 1.0);
    label_centred(&mut img, (x + 40.0, y - 20.0), "precision", LABEL);
    for pair in curve.windows(2) {
        draw_line_segment_mut(
            &mut img,
            at(pair[0].2, pair[0].1),
            at(pair[1].2, pair[1].1),
            MEASURED,
        );
    }
    let every = curve.len().div_ceil(8).max(1);
    for (k, &(t, p, r)) in curve.iter().enumerate() {
        let (x, y) = at(r, p);
        draw_filled_circle_mut(&mut img, (x as i32, y as i32), 4, MEASURED);
        if k % every == 0 {
            label_centred(&mut img, (x + 26.0, y - 12.0), &format!("{t:.2}"), TRUTH);
        }
    }
    titled(
        img,
        &format!("Place queries of {name}: precision and recall over the score threshold"),
        &[
            (Swatch::Dot(MEASURED), "one score threshold"),
            (Swatch::Dot(TRUTH), "threshold (label)"),
            (Swatch::Line(GRID), "grid: 0.1"),
        ],
    )
}

#[cfg(test)]
mod tests;
