//! Outlier filters over the bins of a profile.
//!
//! Both work on finite ranges only: unseen bins stay unseen and `+∞`
//! ("nothing in sight") counts as a range larger than any other.

use crate::Rop;

/// Which outlier filter to apply.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OutlierFilter {
    /// Leave the profile as measured.
    None,
    /// The paper's filter: the mean over three neighbouring bins.
    Mean3,
    /// Median over three neighbouring bins: removes one-bin spikes and
    /// keeps obstacle edges sharp (the default).
    #[default]
    Median3,
}

impl std::str::FromStr for OutlierFilter {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "none" => Ok(Self::None),
            "mean3" => Ok(Self::Mean3),
            "median3" => Ok(Self::Median3),
            _ => Err(format!("unknown filter `{s}` (expected none, mean3 or median3)")),
        }
    }
}

/// Applies `filter` to the ranges of `rop` in place.
pub fn apply(rop: &mut Rop, filter: OutlierFilter) {
    match filter {
        OutlierFilter::None => {}
        OutlierFilter::Mean3 => mean3(rop),
        OutlierFilter::Median3 => median3(rop),
    }
}

fn window(r: &[f32], i: usize) -> impl Iterator<Item = f32> + '_ {
    let lo = i.saturating_sub(1);
    let hi = (i + 2).min(r.len());
    r[lo..hi].iter().copied().filter(|v| !v.is_nan())
}

/// The paper's 3-bin average. A bin that sees nothing in sight (`+∞`) keeps
/// that value; a finite bin averages its finite neighbours.
pub fn mean3(rop: &mut Rop) {
    let src = rop.range_m.clone();
    for (i, out) in rop.range_m.iter_mut().enumerate() {
        if !src[i].is_finite() {
            continue;
        }
        let (sum, n) = window(&src, i)
            .filter(|v| v.is_finite())
            .fold((0.0, 0), |(s, n), v| (s + v, n + 1));
        *out = sum / n as f32;
    }
}

/// The 3-bin median (two values: the larger, so a lone near spike beside
/// one neighbour is not kept). Colour tags follow the kept range.
pub fn median3(rop: &mut Rop) {
    let src = rop.range_m.clone();
    for (i, out) in rop.range_m.iter_mut().enumerate() {
        if src[i].is_nan() {
            continue;
        }
        let mut w = [f32::NAN; 3];
        let mut n = 0;
        for v in window(&src, i) {
            w[n] = v;
            n += 1;
        }
        let vals = &mut w[..n];
        vals.sort_by(f32::total_cmp);
        let m = vals[n / 2];
        if m != src[i] && !m.is_finite() {
            rop.colour[i] = None;
        }
        *out = m;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rop(r: &[f32]) -> Rop {
        let mut p = Rop::empty(0.0, 0.1, r.len(), 5.0);
        p.range_m = r.to_vec();
        p
    }

    #[test]
    fn median_removes_spike_keeps_edge() {
        let mut p = rop(&[1.0, 1.0, 0.2, 1.0, 1.0, 2.0, 2.0, 2.0]);
        median3(&mut p);
        assert_eq!(p.range_m, vec![1.0, 1.0, 1.0, 1.0, 1.0, 2.0, 2.0, 2.0]);
    }

    #[test]
    fn median_removes_near_spike_in_open_space() {
        let inf = f32::INFINITY;
        let mut p = rop(&[inf, inf, 0.3, inf, inf]);
        median3(&mut p);
        assert!(p.range_m.iter().all(|v| v.is_infinite()));
    }

    #[test]
    fn mean_averages_three_and_keeps_unseen() {
        let mut p = rop(&[1.0, 2.0, 3.0, f32::NAN]);
        mean3(&mut p);
        assert_eq!(p.range_m[0], 1.5);
        assert_eq!(p.range_m[1], 2.0);
        assert_eq!(p.range_m[2], 2.5);
        assert!(p.range_m[3].is_nan());
    }
}
