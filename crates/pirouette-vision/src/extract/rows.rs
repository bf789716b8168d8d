//! One image's scan, a row at a time from the bottom up (see
//! [`crate::scan`]): the state the rows share and one method per step of a
//! row.

use super::decide::Cues;
use super::RopExtractor;
use crate::scan::{Candidate, Candidates, Classifier, Lanes};
use crate::ColumnBoundary;
use std::iter::Peekable;
use std::ops::Range;

/// The state of a scan between rows.
pub(super) struct RowScan<'a> {
    ex: &'a RopExtractor,
    px: &'a [u8],
    cues: Cues<'a>,
    /// The boundary found in each column so far.
    pub out: Vec<ColumnBoundary>,
    /// The floor models of the columns still scanned.
    pub lanes: Lanes,
    classifier: Classifier,
    edge_classifier: Classifier,
    bright_classifier: Classifier,
    faint_classifier: Classifier,
    /// The grey level's noise, where the texture cue is on.
    grey_sigma: f32,
    /// Candidate obstacle bases whose runs are still being scanned.
    candidates: Candidates,
    /// Columns scanned past their topmost floor row only to finish a run.
    past_top: Vec<bool>,
    /// Columns whose first candidate can be decided at the current row.
    ready: Vec<usize>,
    /// Per column: the nearest undecided base, where the floor showed
    /// again above one: its row, and the obstacle's base it would be.
    undecided: Vec<Option<(u32, ColumnBoundary)>>,
}

impl<'a> RowScan<'a> {
    /// The scan of image `px` by `ex` with the floor test `classifier`,
    /// from the seeds' floor models `lanes` and boundaries `out`.
    pub fn new(
        ex: &'a RopExtractor,
        px: &'a [u8],
        classifier: Classifier,
        lanes: Lanes,
        out: Vec<ColumnBoundary>,
    ) -> Self {
        let config = &ex.config;
        let grey_sigma = if config.texture_ratio > 0.0 {
            super::grey_noise_sigma(px, ex.width, ex.height, super::Median::Plain)
        } else {
            0.0
        };
        let m = out.len();
        Self {
            ex,
            px,
            cues: Cues::new(ex, px),
            out,
            lanes,
            edge_classifier: classifier.scaled(config.edge_fraction),
            bright_classifier: classifier.scaled_both(config.edge_fraction),
            faint_classifier: classifier.scaled_both(config.faint_step_fraction),
            classifier,
            grey_sigma,
            candidates: Candidates::new(m, ex.height as usize),
            past_top: vec![false; m],
            ready: Vec::new(),
            undecided: vec![None; m],
        }
    }

    /// The floor models of columns `cols` take row `v`.
    pub fn step(&mut self, v: u32, cols: Range<usize>) {
        let c = &self.ex.config;
        self.lanes.step(
            self.px,
            v as usize,
            (
                &self.classifier,
                &self.bright_classifier,
                self.faint_classifier.brightness_step,
            ),
            (c.adapt_rate, c.trend_rate),
            cols,
        );
    }

    /// Columns whose row `v` is not floor: a candidate base each, over the
    /// run of rows not floor that ends there.
    pub fn queue_off_floor(&mut self, v: u32, cols: Range<usize>) {
        let m = self.out.len();
        for u in self.lanes.off_columns(cols) {
            if self.past_top[u] {
                continue;
            }
            let run = self.ex.run_rows[v as usize * m + u].max(1) as u32;
            self.candidates.push(
                u,
                Candidate {
                    row: v,
                    lo: (v + 1).saturating_sub(run),
                    // This row is one of the column's rows not floor.
                    off_before: self.lanes.off_rows(u) - 1,
                    floor: self.lanes.predicted(u),
                    trend: self.lanes.trend_before(u),
                    edge: false,
                },
            );
        }
    }

    /// Sharp steps within the floor's tolerances at row `v`, of
    /// chromaticity and (with the texture cue) of brightness alone where
    /// the texture drops above them, by more above faint steps: followed
    /// over their runs at once, queued only when they are an obstacle's
    /// base.
    pub fn queue_edges(&mut self, v: u32, cols: Range<usize>) {
        let Self {
            ex,
            cues,
            lanes,
            candidates,
            past_top,
            classifier,
            edge_classifier,
            bright_classifier,
            faint_classifier,
            grey_sigma,
            ..
        } = self;
        let (ex, cues, lanes, past_top) = (*ex, *cues, &*lanes, &*past_top);
        let config = &ex.config;
        let chroma_edges = lanes.edge_columns(cols.clone()).filter(|&u| {
            !past_top[u]
                && cues.edge_confirms(u as u32, v, lanes.coasted(u, config.trend_rate), edge_classifier)
        });
        // A step of brightness alone, tested with its tolerances and
        // texture ratio.
        let brightness_step = |u: usize, test: (&Classifier, f32)| {
            !past_top[u]
                && cues.bright_edge_confirms(
                    u as u32,
                    v,
                    test,
                    *grey_sigma,
                    (&lanes.predicted(u), classifier),
                )
        };
        let bright_edges = (config.texture_ratio > 0.0)
            .then(|| lanes.bright_edge_columns(cols.clone()))
            .into_iter()
            .flatten()
            .filter(|&u| brightness_step(u, (bright_classifier, config.texture_ratio)));
        let faint_edges = config
            .faint_steps()
            .then(|| lanes.faint_edge_columns(cols.clone()))
            .into_iter()
            .flatten()
            .filter(|&u| brightness_step(u, (faint_classifier, config.faint_texture_ratio)));
        for u in chroma_edges.chain(bright_edges).chain(faint_edges) {
            candidates.push(
                u,
                Candidate {
                    row: v,
                    lo: v,
                    off_before: lanes.off_rows(u),
                    floor: lanes.predicted(u),
                    trend: lanes.trend_before(u),
                    edge: true,
                },
            );
        }
    }

    /// Decides the candidates whose runs end at row `v`, in scan order:
    /// the first that is an obstacle ends the column, unless the floor
    /// shows again above it (then it is undecided, and the scan goes on);
    /// a column past its top with none left sees nothing.
    pub fn decide_row(&mut self, v: u32) {
        let lanes = &self.lanes;
        self.candidates
            .complete_row(v as usize, |u| lanes.off_rows(u), &mut self.ready);
        for &u in &self.ready {
            while let Some((c, off)) = self.candidates.decidable(u) {
                if let Some(b) = self.cues.decide(u as u32, &c, off, &self.classifier) {
                    if self.cues.floor_resumes(u as u32, &c, &self.classifier) {
                        self.undecided[u].get_or_insert((c.row, b));
                    } else {
                        self.out[u] = match b {
                            ColumnBoundary::Obstacle { row, colour, .. } => ColumnBoundary::Obstacle {
                                row,
                                colour,
                                undecided: self.undecided[u].map(|(w, _)| w),
                            },
                            other => other,
                        };
                        self.lanes.stop(u);
                        self.candidates.clear(u);
                        break;
                    }
                }
                self.candidates.pop(u);
            }
            if self.lanes.is_alive(u) && self.past_top[u] && self.candidates.is_empty(u) {
                self.out[u] = self.clear(u, self.ex.top_floor[u]);
                self.lanes.stop(u);
            }
        }
    }

    /// Column `u`, scanned to its last floor row `top_row` without an
    /// obstacle: clear, or undecided from its nearest undecided base.
    fn clear(&self, u: usize, top_row: u32) -> ColumnBoundary {
        match self.undecided[u] {
            Some((row, _)) => ColumnBoundary::Undecided { row },
            None => ColumnBoundary::Clear { top_row },
        }
    }

    /// Columns whose floor ends at row `v` (the next of `ends`, columns by
    /// falling top row) see nothing, once their candidates are decided.
    pub fn end_columns<'e>(&mut self, v: u32, ends: &mut Peekable<impl Iterator<Item = &'e u32>>) {
        while let Some(&&u) = ends.peek() {
            if self.ex.top_floor[u as usize] < v {
                break;
            }
            ends.next();
            let u = u as usize;
            if self.lanes.is_alive(u) {
                if self.candidates.is_empty(u) {
                    self.out[u] = self.clear(u, v);
                    self.lanes.stop(u);
                } else {
                    self.past_top[u] = true;
                }
            }
        }
    }

    /// The boundaries, undecided bases that continue an obstacle's base
    /// line decided ([`settle`]).
    pub fn finish(mut self) -> Vec<ColumnBoundary> {
        let bases: Vec<Option<ColumnBoundary>> = self.undecided.iter().map(|b| b.map(|(_, b)| b)).collect();
        settle(&mut self.out, &bases);
        self.out
    }
}

/// Columns either side of an undecided base in which [`settle`] looks for a
/// decided base on the same line: past the three-pixel smoothing.
const LINE_COLUMNS: usize = 2;

/// How far, rows per column apart, two columns' bases may lie and still
/// be on one line.
const LINE_ROWS_PER_COLUMN: f32 = 1.5;

/// Decides the undecided bases (`bases`, per column the nearest, as the
/// obstacle's base it would be) that continue the line of an obstacle's
/// base decided within [`LINE_COLUMNS`] columns (as `out` holds them):
/// where a column grazes an obstacle's side, the floor beside it shows
/// above its base, but the columns that cross the obstacle show that the
/// base is an obstacle's. A mark on the floor ends no decided base's
/// line.
pub(super) fn settle(out: &mut [ColumnBoundary], bases: &[Option<ColumnBoundary>]) {
    let decided: Vec<Option<f32>> = (out.iter())
        .map(|b| match *b {
            ColumnBoundary::Obstacle {
                row, undecided: None, ..
            } => Some(row),
            _ => None,
        })
        .collect();
    let n = out.len();
    for (u, base) in bases.iter().enumerate() {
        let Some(base @ ColumnBoundary::Obstacle { row, .. }) = *base else {
            continue;
        };
        let on_line = (u.saturating_sub(LINE_COLUMNS)..(u + LINE_COLUMNS + 1).min(n))
            .filter(|&k| k != u)
            .any(|k| {
                decided[k].is_some_and(|r| (r - row).abs() <= LINE_ROWS_PER_COLUMN * k.abs_diff(u) as f32)
            });
        if on_line {
            out[u] = base;
        }
    }
}
