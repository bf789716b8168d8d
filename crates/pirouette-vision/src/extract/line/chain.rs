//! A base is a line: the candidate runs of neighbouring samples chained
//! into lines across the image, and the bases that lie on them.
//!
//! One sample's candidates are noisy: the base's own row may fail where a
//! speck or a smoother cell of grain lies under it, and a cell of grain a
//! few rows down may pass. A line through the candidates of many samples
//! holds where they agree. Samples the column scan settled (a base within
//! the soft limit, or no floor) neither carry a line nor break one: an
//! object in front of a wall hides a stretch of its base.

use super::{MAX_ROW_STEP, STRIDE};

/// A run of neighbouring candidate rows of one sample, down to `hi`, and
/// the row its base is put at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Run {
    pub(super) hi: i32,
    pub(super) sharpest: i32,
}

/// The most unsettled samples a line may pass without a candidate (its
/// base hidden there by a speck, or the grain's estimate there too noisy):
/// half the default window.
const MAX_GAP: usize = 4;

/// The longest chain ending at a run: how many runs it holds, and the run
/// before (sample, index).
#[derive(Debug, Clone, Copy)]
struct Link {
    runs: usize,
    prev: Option<(usize, usize)>,
}

/// The lines through the candidate runs `runs` (per sample): chains of
/// runs, one a sample, each within `MAX_ROW_STEP` rows a column of the one
/// before, passing at most `MAX_GAP` unsettled samples without a run (one
/// row more allowed for each, the steepest line tried) and any number of
/// `settled` ones, within a window's length of samples. The longest chain
/// is taken first, its runs removed, and so on while a chain holds at
/// least a window (`2·hs + 1`) of runs. Each line as its samples and base
/// rows, left to right.
pub(super) fn lines(mut runs: Vec<Vec<Run>>, settled: &[bool], hs: usize) -> Vec<Vec<(usize, i32)>> {
    let ms = runs.len();
    let window = 2 * hs + 1;
    let mut out = Vec::new();
    loop {
        let mut best: Vec<Vec<Link>> = Vec::with_capacity(ms);
        for c in 0..ms {
            let mut here = Vec::with_capacity(runs[c].len());
            for r in &runs[c] {
                let mut top = Link { runs: 1, prev: None };
                let mut skipped = 0;
                for p in (c.saturating_sub(window)..c).rev() {
                    if settled[p] {
                        continue;
                    }
                    let reach = MAX_ROW_STEP * STRIDE as i32 + (skipped * STRIDE / 2) as i32;
                    for (k, q) in runs[p].iter().enumerate() {
                        if (r.sharpest - q.sharpest).abs() <= reach && best[p][k].runs + 1 > top.runs {
                            top = Link {
                                runs: best[p][k].runs + 1,
                                prev: Some((p, k)),
                            };
                        }
                    }
                    skipped += 1;
                    if skipped > MAX_GAP {
                        break;
                    }
                }
                here.push(top);
            }
            best.push(here);
        }
        let longest = (0..ms)
            .flat_map(|c| (0..best[c].len()).map(move |k| (c, k)))
            .max_by_key(|&(c, k)| best[c][k].runs);
        let Some((c, k)) = longest.filter(|&(c, k)| best[c][k].runs >= window) else {
            return out;
        };
        let mut chain = Vec::with_capacity(best[c][k].runs);
        let mut at = Some((c, k));
        while let Some((c, k)) = at {
            chain.push((c, runs[c][k].sharpest));
            at = best[c][k].prev;
        }
        for &(c, _) in &chain {
            runs[c].clear();
        }
        chain.reverse();
        out.push(chain);
    }
}

/// The bases of a line's samples that lie on it: within `MAX_ROW_STEP`
/// rows of a neighbour's in the chain. A base further from both is the
/// grain's, a few rows below the surface's, met where the line bridged a
/// gap.
pub(super) fn on_the_line(chain: &[(usize, i32)]) -> impl Iterator<Item = (usize, i32)> + '_ {
    (0..chain.len()).filter_map(move |i| {
        let (j, v) = chain[i];
        let near = |k: usize| chain.get(k).is_some_and(|&(_, w)| (v - w).abs() <= MAX_ROW_STEP);
        (chain.len() == 1 || i.checked_sub(1).is_some_and(near) || near(i + 1)).then_some((j, v))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(row: i32) -> Vec<Run> {
        vec![Run {
            hi: row,
            sharpest: row,
        }]
    }

    /// A base at row 40 over 20 samples, hidden in three (a gap) and
    /// settled in four more (an object in front), with a cell of grain at
    /// row 52 in two samples: one line, at row 40, through every sample
    /// that has a run there; the grain's runs are too far to join it and
    /// too few to make a line of their own.
    #[test]
    fn a_line_passes_gaps_and_settled_samples() {
        let mut runs: Vec<Vec<Run>> = (0..20).map(|_| run(40)).collect();
        let mut settled = vec![false; 20];
        for c in [5, 6, 7] {
            runs[c].clear();
        }
        for c in 10..14 {
            runs[c].clear();
            settled[c] = true;
        }
        runs[15].push(Run { hi: 52, sharpest: 52 });
        runs[16].push(Run { hi: 52, sharpest: 52 });
        let found = lines(runs, &settled, 4);
        assert_eq!(found.len(), 1);
        let samples: Vec<usize> = (0..20)
            .filter(|c| !(5..8).contains(c) && !(10..14).contains(c))
            .collect();
        assert_eq!(found[0], samples.iter().map(|&c| (c, 40)).collect::<Vec<_>>());
    }

    /// Runs of one row in every sample but two gaps longer than
    /// `MAX_GAP`: the two chains as long as the window are two lines; the
    /// third, a sample shorter, is none.
    #[test]
    fn a_long_gap_ends_a_line_and_short_lines_are_dropped() {
        let window = 9;
        let second = window + MAX_GAP + 1;
        let third = second + window + MAX_GAP + 1;
        let n = third + window - 1;
        let mut runs: Vec<Vec<Run>> = (0..n).map(|_| run(30)).collect();
        for r in &mut runs[window..second] {
            r.clear();
        }
        for r in &mut runs[second + window..third] {
            r.clear();
        }
        let found = lines(runs, &vec![false; n], 4);
        let mut spans: Vec<(usize, usize)> = found.iter().map(|l| (l[0].0, l.len())).collect();
        spans.sort_unstable();
        assert_eq!(spans, vec![(0, window), (second, window)]);
    }

    /// Rows may step by `MAX_ROW_STEP` a column (4 a sample) and no more.
    #[test]
    fn rows_follow_on_within_the_step() {
        let steep: Vec<Vec<Run>> = (0..10).map(|c| run(10 + 4 * c)).collect();
        assert_eq!(lines(steep, &[false; 10], 4).len(), 1);
        let steeper: Vec<Vec<Run>> = (0..10).map(|c| run(10 + 5 * c)).collect();
        assert!(lines(steeper, &[false; 10], 4).is_empty());
    }

    /// A base three rows from both its neighbours is left out; one within
    /// two rows of either, or on a sloping line, is kept.
    #[test]
    fn bases_off_the_line_are_left_out() {
        let chain = [(0, 40), (1, 40), (2, 43), (3, 40), (4, 42), (6, 46), (7, 47)];
        let kept: Vec<(usize, i32)> = on_the_line(&chain).collect();
        assert_eq!(kept, vec![(0, 40), (1, 40), (3, 40), (4, 42), (6, 46), (7, 47)]);
    }
}
