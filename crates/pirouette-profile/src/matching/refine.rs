//! A verified turn refined together with the small shift of the robot's
//! centre during it.

use super::{MatchConfig, TurnShift};
use crate::Rop;

/// Refines a turn `theta0` together with a small shift of the robot
/// centre during it (a Gaussian prior of [`MatchConfig::turn_shift_m`]
/// each way, about the shift a turn about [`MatchConfig::pivot_m`] makes):
/// a robot turning in place about a point a few millimetres off its centre
/// moves that centre, and the profiles see the parallax. Left to the turn
/// alone, it bends the estimate on a slanted wall, where a shift toward
/// the wall and a rotation look alike. Every finite range of `after` is
/// moved into `before`'s frame and compared with `before` there in inverse
/// range, in units of `sigma_inv` with the matcher's robust truncation,
/// plus the prior; each point's cost counts as the share of an independent
/// sample it is (bins finer than [`MatchConfig::correlation_rad`] share
/// their errors with their neighbours, as the significance of the match
/// counts them). Gauss-Newton from `theta0` and the expected shift.
/// Returns the turn and the shift (`after`'s centre in `before`'s frame)
/// with what the profiles alone say of it, or `None` where the refinement
/// left the basin the match verified ([`MatchConfig::basin_rad`] about
/// `theta0`).
///
/// The shifts are small beside the ranges, so a point's bearing is moved
/// to first order in the shift, around its bearing at `theta0`.
pub(super) fn refine_with_shift(
    before: &Rop,
    after: &Rop,
    theta0: f64,
    sigma_inv: f64,
    config: &MatchConfig,
) -> Option<(f64, TurnShift)> {
    let problem = ShiftProblem::new(before, after, theta0, sigma_inv, config);
    // From the turn as matched and the shift its pivot makes.
    let (x, a) = problem.solve([0.0, problem.expected[0], problem.expected[1]]);
    let shift = problem.shift(&x, &a);
    (x[0].abs() <= config.basin_rad).then_some((theta0 + x[0], shift))
}

/// A finite range of `after`, moved into `before`'s frame at the turn
/// matched.
struct Point {
    /// Bearing in `before`'s frame at `theta0`.
    bearing: f64,
    cos: f64,
    sin: f64,
    range: f64,
    /// The bearing's derivatives in the shift, `(-sin, cos) / range`.
    d_bearing: [f64; 2],
}

/// The least-squares problem of [`refine_with_shift`] in the unknowns
/// `x = (turn − theta0, shift x, shift y)`.
struct ShiftProblem {
    points: Vec<Point>,
    /// Each bin of `before` as the interval of inverse ranges it allows,
    /// `[lo, hi]`: one value where it sees an obstacle (`lo > 0` exactly
    /// there), from 0 to its reach's inverse where it saw nothing in
    /// sight, NaN where it was not seen.
    bins: Vec<[f64; 2]>,
    /// `before`'s first bearing.
    start: f64,
    /// Reciprocals taken once: a point's residual then divides only for
    /// its inverse range (a division costs several multiplications' time).
    inv_w: f64,
    inv_sigma: f64,
    /// The share of an independent sample one point is.
    independent: f64,
    /// The prior's information on each shift component.
    prior: f64,
    /// The shift a turn by `theta0` about the pivot makes: `(I − R)·pivot`.
    expected: [f64; 2],
}

impl ShiftProblem {
    fn new(before: &Rop, after: &Rop, theta0: f64, sigma_inv: f64, config: &MatchConfig) -> Self {
        let (shift_sigma_m, pivot_m) = (config.turn_shift_m, config.pivot_m);
        // The bins' directions by rotating the first one bin by bin (one
        // `sin_cos` for the first bearing, one for the bin width; the
        // rounding error grows by about an ulp a bin).
        let mut points = Vec::with_capacity(after.len());
        let (mut sin, mut cos) = (after.bin_centre_rad(0) + theta0).sin_cos();
        let (sin_w, cos_w) = after.bin_width_rad.sin_cos();
        for i in 0..after.len() {
            let range = after.range_m[i] as f64;
            if range.is_finite() {
                points.push(Point {
                    bearing: after.bin_centre_rad(i) + theta0,
                    cos,
                    sin,
                    range,
                    d_bearing: [-sin / range, cos / range],
                });
            }
            (sin, cos) = (sin * cos_w + cos * sin_w, cos * cos_w - sin * sin_w);
        }
        let bins: Vec<[f64; 2]> = (0..before.len())
            .map(|j| {
                let r = before.range_m[j] as f64;
                if r.is_finite() {
                    [1.0 / r, 1.0 / r]
                } else if r.is_nan() {
                    [f64::NAN; 2]
                } else {
                    [0.0, 1.0 / (before.free_reach(j) as f64).max(1e-3)]
                }
            })
            .collect();
        let expected = {
            let (s, c) = theta0.sin_cos();
            [
                (1.0 - c) * pivot_m[0] + s * pivot_m[1],
                -s * pivot_m[0] + (1.0 - c) * pivot_m[1],
            ]
        };
        Self {
            points,
            bins,
            start: before.bearing_start_rad,
            inv_w: 1.0 / before.bin_width_rad,
            inv_sigma: 1.0 / sigma_inv,
            independent: (after.bin_width_rad / config.correlation_rad).min(1.0),
            prior: 1.0 / (shift_sigma_m * shift_sigma_m),
            expected,
        }
    }

    /// A point's residual in units of `sigma_inv` at turn `theta0 + x[0]`
    /// and shift `(x[1], x[2])`, with its derivatives in those three:
    /// against `before`'s inverse range interpolated between bin centres
    /// where both neighbours see an obstacle, else against the interval of
    /// the bin it falls in. `None` where it falls outside `before` or on an
    /// unseen bin.
    fn residual(&self, p: &Point, x: &[f64; 3]) -> Option<(f64, [f64; 3])> {
        let (bins, inv_w, inv_sigma) = (&self.bins, self.inv_w, self.inv_sigma);
        let d_bearing = [1.0, p.d_bearing[0], p.d_bearing[1]];
        let bearing = p.bearing + x[0] + x[1] * d_bearing[1] + x[2] * d_bearing[2];
        let u = (bearing - self.start) * inv_w;
        // (NaN falls outside too.)
        if u.is_nan() || u < 0.0 {
            return None;
        }
        let [lo, hi] = *bins.get(u as usize)?;
        if lo.is_nan() {
            return None;
        }
        let inv = 1.0 / (p.range + x[1] * p.cos + x[2] * p.sin);
        let d_inv = [0.0, -p.cos * inv * inv, -p.sin * inv * inv];
        // The bin centres either side: `j0` and `j0 + 1` (`u ≥ 0`, so the
        // truncation is a floor from -0.5 up); both must see an obstacle
        // (NaN, unseen, compares false).
        let v = u - 0.5;
        if v >= 0.0 {
            let j0 = v as usize;
            if let (Some(&[a, _]), Some(&[b, _])) = (bins.get(j0), bins.get(j0 + 1)) {
                if a > 0.0 && b > 0.0 {
                    let f = v - j0 as f64;
                    let expect = (1.0 - f) * a + f * b;
                    let slope = (b - a) * inv_w;
                    let de = [
                        (d_inv[0] - slope * d_bearing[0]) * inv_sigma,
                        (d_inv[1] - slope * d_bearing[1]) * inv_sigma,
                        (d_inv[2] - slope * d_bearing[2]) * inv_sigma,
                    ];
                    return Some(((inv - expect) * inv_sigma, de));
                }
            }
        }
        let (e, sign) = if inv - hi > 0.0 && inv - hi >= lo - inv {
            (inv - hi, 1.0)
        } else if lo - inv > 0.0 {
            (lo - inv, -1.0)
        } else {
            return Some((0.0, [0.0; 3]));
        };
        let s = sign * inv_sigma;
        Some((e * inv_sigma, [d_inv[0] * s, d_inv[1] * s, d_inv[2] * s]))
    }

    /// The matcher's robust cost (truncated quadratic) plus the prior at
    /// `x`, and the Gauss-Newton normal equations of its inliers (|e| ≤ 3:
    /// the truncation's quadratic part), in one pass over the points.
    fn linearise(&self, x: &[f64; 3]) -> (f64, [[f64; 3]; 3], [f64; 3]) {
        let (prior, independent) = (self.prior, self.independent);
        let (ex, ey) = (x[1] - self.expected[0], x[2] - self.expected[1]);
        let cost = (ex * ex + ey * ey) * prior;
        let mut a = [[0.0; 3]; 3];
        let mut g = [0.0, ex * prior, ey * prior];
        a[1][1] = prior;
        a[2][2] = prior;
        let (mut data_cost, mut data_a, mut data_g) = (0.0, [[0.0; 3]; 3], [0.0; 3]);
        for p in &self.points {
            let Some((e, jac)) = self.residual(p, x) else {
                continue;
            };
            data_cost += (e * e).min(9.0);
            if e.abs() <= 3.0 {
                for r in 0..3 {
                    data_g[r] += jac[r] * e;
                    for c in 0..3 {
                        data_a[r][c] += jac[r] * jac[c];
                    }
                }
            }
        }
        for r in 0..3 {
            g[r] += independent * data_g[r];
            for c in 0..3 {
                a[r][c] += independent * data_a[r][c];
            }
        }
        (cost + independent * data_cost, a, g)
    }

    /// Gauss-Newton with step halving from `x`, until a step no longer
    /// moves the turn by a microradian or the shift by a hundredth of a
    /// millimetre: the solution and its normal matrix.
    fn solve(&self, mut x: [f64; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
        let (mut best, mut a, mut g) = self.linearise(&x);
        for _ in 0..10 {
            let Some(step) = solve3(&a, &g) else { break };
            if step[0].abs() < 1e-6 && step[1].hypot(step[2]) < 1e-5 {
                break;
            }
            let mut scale = 1.0;
            let mut moved = false;
            for _ in 0..6 {
                let trial = [
                    x[0] - scale * step[0],
                    x[1] - scale * step[1],
                    x[2] - scale * step[2],
                ];
                let (value, ta, tg) = self.linearise(&trial);
                if value < best {
                    (x, best, a, g, moved) = (trial, value, ta, tg, true);
                    break;
                }
                scale *= 0.5;
            }
            if !moved || (scale * step[0]).abs() < 1e-6 {
                break;
            }
        }
        (x, a)
    }

    /// The shift at solution `x` with normal matrix `a`, and the profiles'
    /// information on it: `a` without the prior, the turn marginalised
    /// out (its Schur complement).
    fn shift(&self, x: &[f64; 3], a: &[[f64; 3]; 3]) -> TurnShift {
        let prior = self.prior;
        let mut information = [[a[1][1] - prior, a[1][2]], [a[2][1], a[2][2] - prior]];
        if a[0][0] > 0.0 {
            for r in 0..2 {
                for c in 0..2 {
                    information[r][c] -= a[r + 1][0] * a[0][c + 1] / a[0][0];
                }
            }
        }
        TurnShift {
            shift_m: [x[1], x[2]],
            prior_mean_m: self.expected,
            prior_information: prior,
            information,
        }
    }
}

/// The solution of the 3 × 3 system `a·x = b` (Cramer's rule), `None` when
/// `a` is singular.
fn solve3(a: &[[f64; 3]; 3], b: &[f64; 3]) -> Option<[f64; 3]> {
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    if !d.is_finite() || d.abs() < 1e-300 {
        return None;
    }
    let mut x = [0.0; 3];
    for (k, xk) in x.iter_mut().enumerate() {
        let mut m = *a;
        for r in 0..3 {
            m[r][k] = b[r];
        }
        *xk = det(&m) / d;
    }
    Some(x)
}
