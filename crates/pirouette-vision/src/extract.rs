//! Image → boundaries → ROP.

mod decide;
mod line;
mod noise;
mod rows;
mod seed;
mod texture;

use crate::config::{VisionConfig, VisionError};
use crate::scan::{Classifier, Lanes};
use crate::ColumnBoundary;
use noise::{grey_noise_sigma, noise_sigma, Median};
use pirouette_camera::{CameraModel, FloorTable};
use pirouette_profile::filter;
use pirouette_profile::{ColourTag, Rop};
use rows::RowScan;
use seed::{Seed, SEED_ROWS};

/// Turns camera images into boundaries and profiles. Built once per camera:
/// the floor table and the expected obstacle heights in rows are
/// precomputed.
///
/// # Memory
/// About 14 bytes per pixel (1 MiB for 320 × 240).
#[derive(Debug, Clone)]
pub struct RopExtractor {
    table: FloorTable,
    width: u32,
    height: u32,
    max_range_m: f32,
    config: VisionConfig,
    /// Per pixel: rows an obstacle of the minimum height standing on that
    /// pixel's floor point spans (0 above the horizon).
    run_rows: Vec<u16>,
    /// Per column: the topmost floor row, or `height` when none.
    top_floor: Vec<u32>,
    /// Column indices, highest topmost floor row first.
    columns_by_top: Vec<u32>,
    /// Per column: the bearing of its bottom pixel's floor point.
    bottom_bearing: Vec<Option<f64>>,
    /// Per column: the profile bins its floor pixels fall in, bottom up
    /// (see [`Crossing`]).
    crossings: Vec<Vec<Crossing>>,
    /// The floor view's bearing span.
    view_rad: (f64, f64),
}

/// Where an image column's floor pixels pass through one profile bin: the
/// topmost (farthest) of them and its range.
#[derive(Debug, Clone, Copy)]
struct Crossing {
    bin: u32,
    top_row: u32,
    range_m: f32,
}

/// A column's floor point at its boundary (or its farthest floor point when
/// the column is clear).
#[derive(Debug, Clone, Copy)]
struct BoundaryPoint {
    bearing_rad: f64,
    range_m: f32,
    colour: Option<ColourTag>,
    /// An obstacle's base, not the end of sight.
    obstacle: bool,
    /// How far the floor is known: the range of an undecided base nearer
    /// than the obstacle, `+∞` when the floor was followed all the way.
    known_m: f32,
}

impl RopExtractor {
    /// Precomputes the tables for `camera` with soft range limit
    /// `max_range_m`.
    ///
    /// # Panics
    /// When `config` is invalid; see [`RopExtractor::try_new`].
    #[allow(
        clippy::expect_used,
        reason = "documented under # Panics; try_new is the fallible form"
    )]
    pub fn new(camera: &(impl CameraModel + ?Sized), max_range_m: f64, config: VisionConfig) -> Self {
        Self::try_new(camera, max_range_m, config).expect("valid vision settings")
    }

    /// As [`RopExtractor::new`], with invalid settings as an error.
    pub fn try_new(
        camera: &(impl CameraModel + ?Sized),
        max_range_m: f64,
        config: VisionConfig,
    ) -> Result<Self, VisionError> {
        config.validate()?;
        if !(max_range_m.is_finite() && max_range_m > 0.0) {
            return Err(VisionError::BadConfig {
                problem: format!("max range {max_range_m} must be positive"),
            });
        }
        let table = FloorTable::new(camera);
        let (width, height) = (camera.width(), camera.height());
        let mut run_rows = vec![0u16; width as usize * height as usize];
        for v in 0..height {
            for u in 0..width {
                let Some(p) = table.floor(u, v) else { continue };
                let top = camera.project([p.x, p.y, config.min_obstacle_height_m]);
                // An obstacle at least as tall as the camera reaches the
                // horizon: it spans every row above.
                let rows = match top {
                    Some((_, vt)) if vt.is_finite() => (v as f64 - vt).max(1.0),
                    _ => v as f64 + 1.0,
                };
                run_rows[(v * width + u) as usize] = rows.min(u16::MAX as f64).round() as u16;
            }
        }
        let top_floor: Vec<u32> = (0..width)
            .map(|u| table.top_floor_row(u).unwrap_or(height))
            .collect();
        let mut columns_by_top: Vec<u32> = (0..width).collect();
        columns_by_top.sort_by_key(|&u| std::cmp::Reverse(top_floor[u as usize]));
        let bottom_bearing = (0..width)
            .map(|u| table.floor(u, height - 1).map(|p| p.bearing()))
            .collect();
        let view_rad = table.bearing_span().unwrap_or((0.0, 0.0));
        #[allow(
            clippy::expect_used,
            reason = "the bin width is checked above and the view span is finite"
        )]
        let bins = Rop::covering(view_rad.0, view_rad.1, config.bin_width_rad, max_range_m as f32)
            .expect("bin width checked and the view span is finite");
        let crossings = (0..width)
            .map(|u| {
                let mut out: Vec<Crossing> = Vec::new();
                for v in (top_floor[u as usize].min(height)..height).rev() {
                    let Some(p) = table.floor(u, v) else { continue };
                    let Some(bin) = bins.bin_of(p.bearing()) else {
                        continue;
                    };
                    let here = Crossing {
                        bin: bin as u32,
                        top_row: v,
                        range_m: p.norm() as f32,
                    };
                    match out.last_mut() {
                        Some(last) if last.bin == here.bin => *last = here,
                        _ => out.push(here),
                    }
                }
                out
            })
            .collect();
        Ok(Self {
            table,
            width,
            height,
            max_range_m: max_range_m as f32,
            config,
            run_rows,
            top_floor,
            columns_by_top,
            bottom_bearing,
            crossings,
            view_rad,
        })
    }

    /// The settings.
    pub fn config(&self) -> &VisionConfig {
        &self.config
    }

    /// The floor table.
    pub fn table(&self) -> &FloorTable {
        &self.table
    }

    fn check_size(&self, img: &image::RgbImage) -> Result<(), VisionError> {
        if img.dimensions() != (self.width, self.height) {
            return Err(VisionError::WrongSize {
                width: self.width,
                height: self.height,
                found_width: img.width(),
                found_height: img.height(),
            });
        }
        Ok(())
    }

    /// The boundary of every column, left to right.
    pub fn boundaries(&self, img: &image::RgbImage) -> Result<Vec<ColumnBoundary>, VisionError> {
        self.check_size(img)?;
        let px = img.as_raw();
        let sigma = noise_sigma(px, self.width, self.height);
        Ok(self.scan(px, sigma))
    }

    /// The profile of an image: boundaries through the floor table into
    /// bins, joined between neighbouring columns, then filtered.
    pub fn rop(&self, img: &image::RgbImage) -> Result<Rop, VisionError> {
        let boundaries = self.boundaries(img)?;
        Ok(self.rop_from_boundaries(&boundaries))
    }

    /// The profile from column boundaries (see [`RopExtractor::rop`]).
    pub fn rop_from_boundaries(&self, boundaries: &[ColumnBoundary]) -> Rop {
        let (lo, hi) = self.view_rad;
        #[allow(
            clippy::expect_used,
            reason = "the extractor's bin width was checked when it was made"
        )]
        let mut rop = Rop::covering(lo, hi, self.config.bin_width_rad, self.max_range_m)
            .expect("bin width checked and the view span is finite");
        // Each column's floor point at its boundary, filed with the floor
        // seen below it.
        let points = self.boundary_points(boundaries);
        self.insert_points(&mut rop, &points);
        // How far each bin's floor is seen.
        let reach = self.floor_reach(boundaries, rop.len());
        // Bins narrower than a column between columns on one surface.
        join_neighbours(&mut rop, &points);
        filter::apply(&mut rop, self.config.filter);
        // A bin that sees a surface is seen as far as that surface; one with
        // nothing in sight only as far as its floor was seen.
        for ((free, &range), r) in rop.free_m.iter_mut().zip(&rop.range_m).zip(reach) {
            if range == f32::INFINITY && r < self.max_range_m {
                *free = r;
            }
        }
        // A bin whose every column met an undecided base before its
        // obstacle is known free only that far.
        for (i, known) in known_reach(&rop, &points).into_iter().enumerate() {
            if rop.range_m[i].is_finite() && known < rop.range_m[i] {
                rop.free_m[i] = known;
            }
        }
        rop
    }

    /// Each column's floor point at its boundary (or its farthest floor
    /// point when clear).
    fn boundary_points(&self, boundaries: &[ColumnBoundary]) -> Vec<Option<BoundaryPoint>> {
        (boundaries.iter().enumerate())
            .map(|(u, b)| match *b {
                ColumnBoundary::Obstacle {
                    row,
                    colour,
                    undecided,
                } => {
                    let p = self
                        .table
                        .floor_at_row(u as u32, row.min((self.height - 1) as f32))?;
                    Some(BoundaryPoint {
                        bearing_rad: p.bearing(),
                        range_m: p.norm() as f32,
                        colour,
                        obstacle: true,
                        known_m: undecided
                            .and_then(|w| self.table.floor(u as u32, w))
                            .map_or(f32::INFINITY, |q| q.norm() as f32),
                    })
                }
                // Seen from the column's bottom: nothing in sight, as far
                // as the last floor row or the undecided base.
                ColumnBoundary::Clear { top_row: row } | ColumnBoundary::Undecided { row } => {
                    let p = self.table.floor(u as u32, row)?;
                    Some(BoundaryPoint {
                        bearing_rad: p.bearing(),
                        range_m: f32::INFINITY,
                        colour: None,
                        obstacle: false,
                        known_m: f32::INFINITY,
                    })
                }
                ColumnBoundary::NoFloor => None,
            })
            .collect()
    }

    /// Files each column's point in `rop`, and the floor below it as seen
    /// and free: the bins between the column's bottom pixel and its
    /// boundary.
    fn insert_points(&self, rop: &mut Rop, points: &[Option<BoundaryPoint>]) {
        for (u, p) in points.iter().enumerate() {
            let Some(p) = p else { continue };
            rop.insert(p.bearing_rad, p.range_m, p.colour);
            if let Some(bottom) = self.bottom_bearing[u] {
                let (a, b) = (bottom.min(p.bearing_rad), bottom.max(p.bearing_rad));
                if let (Some(i0), Some(i1)) = (rop.bin_of(a), rop.bin_of(b)) {
                    for i in i0..=i1 {
                        rop.insert(rop.bin_centre_rad(i), f32::INFINITY, None);
                    }
                }
            }
        }
    }

    /// How far each of `bins` bins' floor is seen: a column's floor below
    /// its boundary passes through bins on the way, and at the sides of
    /// the view its near floor lies at wider bearings than its far floor.
    /// A bin with nothing in sight is free only that far.
    fn floor_reach(&self, boundaries: &[ColumnBoundary], bins: usize) -> Vec<f32> {
        let mut reach = vec![0f32; bins];
        for (u, (crossings, b)) in self.crossings.iter().zip(boundaries).enumerate() {
            // Floor rows below `below`; a column cut short at an undecided
            // base is seen in the bin it is cut in only as far as that row.
            let (below, cut) = match *b {
                ColumnBoundary::Undecided { row } => (
                    row as f32,
                    self.table.floor(u as u32, row).map(|p| p.norm() as f32),
                ),
                ColumnBoundary::Obstacle { row, .. } => (row, None),
                ColumnBoundary::Clear { top_row } => (top_row as f32 - 1.0, None),
                ColumnBoundary::NoFloor => continue,
            };
            // Bottom up: the rows above the first crossing past `below`
            // are past it too.
            for c in crossings {
                let r = &mut reach[c.bin as usize];
                if c.top_row as f32 > below {
                    *r = r.max(c.range_m);
                } else {
                    if let Some(cut) = cut {
                        *r = r.max(cut);
                    }
                    break;
                }
            }
        }
        reach
    }

    /// The floor mask (255 floor, 0 not floor) implied by the boundaries.
    pub fn floor_mask(&self, boundaries: &[ColumnBoundary]) -> image::GrayImage {
        let mut mask = image::GrayImage::new(self.width, self.height);
        for (u, b) in boundaries.iter().enumerate() {
            let first_floor = match *b {
                ColumnBoundary::Obstacle { row, .. } => (row + 0.5).ceil().max(0.0) as u32,
                ColumnBoundary::Clear { top_row } => top_row,
                ColumnBoundary::Undecided { row } => row + 1,
                ColumnBoundary::NoFloor => self.height,
            };
            for v in first_floor..self.height {
                mask.put_pixel(u as u32, v, image::Luma([255]));
            }
        }
        mask
    }

    /// Scans every column from the bottom up, all columns one row at a
    /// time (see [`crate::scan`]), then along lines for the bases the
    /// columns alone cannot tell (see [`line`]).
    fn scan(&self, px: &[u8], sigma: f32) -> Vec<ColumnBoundary> {
        let mut out = self.scan_rows(px, sigma);
        if self.config.line_cue() {
            line::add_bases(
                self,
                px,
                grey_noise_sigma(px, self.width, self.height, Median::Grouped),
                &mut out,
            );
        }
        out
    }

    /// The column-wise cues' boundaries, all columns one row at a time.
    fn scan_rows(&self, px: &[u8], sigma: f32) -> Vec<ColumnBoundary> {
        let (m, n) = (self.width as usize, self.height);
        let mut out = vec![ColumnBoundary::NoFloor; m];
        let mut lanes = Lanes::new(m);
        let classifier = self.classifier(sigma);
        for (u, (slot, seed)) in out
            .iter_mut()
            .zip(seed::seeds(
                px,
                (self.width, self.height),
                &self.top_floor,
                &classifier,
            ))
            .enumerate()
        {
            match seed {
                Seed::NoFloor => {}
                Seed::Clear { top_row } => *slot = ColumnBoundary::Clear { top_row },
                Seed::Track(track) => lanes.start(u, track),
            }
        }
        // Every scanned column has more floor than its seed, so all start
        // at the row above a full seed.
        let Some(mut cols) = alive_span(&lanes, 0..m) else {
            return out;
        };
        let mut scan = RowScan::new(self, px, classifier, lanes, out);
        let mut ends = self.columns_by_top.iter().peekable();
        let mut v = n - SEED_ROWS - 1;
        loop {
            // The live columns' floor models take the row.
            scan.step(v, cols.clone());
            // Rows off the floor, and sharp steps within its tolerances:
            // candidate obstacle bases.
            scan.queue_off_floor(v, cols.clone());
            scan.queue_edges(v, cols.clone());
            // The candidates whose runs end here decided.
            scan.decide_row(v);
            // Columns whose floor ends at this row.
            scan.end_columns(v, &mut ends);
            match alive_span(&scan.lanes, cols) {
                Some(next) if v > 0 => cols = next,
                _ => return scan.finish(),
            }
            v -= 1;
        }
    }

    /// The cues that decide obstacle bases in image `px`.
    #[cfg(test)]
    fn cues<'a>(&'a self, px: &'a [u8]) -> decide::Cues<'a> {
        decide::Cues::new(self, px)
    }

    /// The floor test for an image whose noise (of a three-pixel average)
    /// is `sigma`.
    fn classifier(&self, sigma: f32) -> Classifier {
        Classifier {
            noise: self.config.noise_sigmas * sigma,
            brightness_step: self.config.min_brightness_step,
            chroma_step: self.config.min_chroma_step,
        }
    }
}

/// Per bin of `rop`, how far the floor is known in front of the obstacles
/// of `points` that fall in it: the farthest of their known reaches
/// (`+∞` where one of them was followed all the way, or none falls in it).
fn known_reach(rop: &Rop, points: &[Option<BoundaryPoint>]) -> Vec<f32> {
    let mut known = vec![f32::NEG_INFINITY; rop.len()];
    for p in points.iter().flatten().filter(|p| p.obstacle) {
        if let Some(i) = rop.bin_of(p.bearing_rad) {
            known[i] = known[i].max(p.known_m);
        }
    }
    known
        .into_iter()
        .map(|k| if k == f32::NEG_INFINITY { f32::INFINITY } else { k })
        .collect()
}

/// Joins neighbouring columns that see the same surface (both obstacles,
/// ranges within 5 %), so that bins narrower than a column still get a
/// range: those between them take the range interpolated along the
/// bearing, and the colour of the column nearer in bearing.
fn join_neighbours(rop: &mut Rop, points: &[Option<BoundaryPoint>]) {
    for pair in points.windows(2) {
        let (Some(a), Some(b)) = (pair[0], pair[1]) else {
            continue;
        };
        if !(a.obstacle && b.obstacle) || (a.range_m - b.range_m).abs() > 0.05 * a.range_m.min(b.range_m) {
            continue;
        }
        let (first, last) = if a.bearing_rad <= b.bearing_rad {
            (a, b)
        } else {
            (b, a)
        };
        let Some(i0) = rop.bin_of(first.bearing_rad) else {
            continue;
        };
        let Some(i1) = rop.bin_of(last.bearing_rad) else {
            continue;
        };
        for i in i0 + 1..i1 {
            let c = rop.bin_centre_rad(i);
            let t = ((c - first.bearing_rad) / (last.bearing_rad - first.bearing_rad)) as f32;
            let r = first.range_m + t * (last.range_m - first.range_m);
            let colour = if t < 0.5 { first.colour } else { last.colour };
            rop.insert(c, r, colour);
        }
    }
}

/// The span from the first to the last alive column within `cols`, `None`
/// when none is.
fn alive_span(lanes: &Lanes, cols: std::ops::Range<usize>) -> Option<std::ops::Range<usize>> {
    let first = cols.clone().find(|&u| lanes.is_alive(u))?;
    let last = cols.rev().find(|&u| lanes.is_alive(u))?;
    Some(first..last + 1)
}

#[cfg(test)]
mod tests;
