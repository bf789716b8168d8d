//! Tests of `correlative`.

use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The walls of a 1.5 × 1.3 m box and a post, sampled every 2 mm.
fn room() -> Vec<Point2> {
    let mut pts = Vec::new();
    let n = 750;
    for k in 0..=n {
        let t = k as f64 / n as f64;
        pts.push(Point2::new(1.5 * t, 0.0));
        pts.push(Point2::new(1.5 * t, 1.3));
        pts.push(Point2::new(0.0, 1.3 * t));
        pts.push(Point2::new(1.5, 1.3 * t));
    }
    for k in 0..200 {
        let a = k as f64 / 200.0 * std::f64::consts::TAU;
        pts.push(Point2::new(0.5 + 0.05 * a.cos(), 0.6 + 0.05 * a.sin()));
    }
    pts
}

fn field_of(world: &[Point2]) -> LikelihoodField {
    LikelihoodField::from_points(world, 0.01, 0.015, 0.2)
}

/// What a robot at `pose` sees of `world` within `max_range`, in its
/// own frame (no occlusion: enough for a registration test).
fn seen_from(world: &[Point2], pose: &Pose2, max_range: f64, noise_m: f64, seed: u64) -> Vec<Point2> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let inv = pose.inverse();
    world
        .iter()
        .map(|p| inv.transform_point(*p))
        .filter(|p| p.norm() <= max_range)
        .map(|p| {
            Point2::new(
                p.x + rng.random_range(-noise_m..noise_m),
                p.y + rng.random_range(-noise_m..noise_m),
            )
        })
        .collect()
}

/// The posterior's covariance skips poses far below the best without
/// their `exp`, and the result is exactly that of the poses the
/// definition keeps (weight at least [`NEGLIGIBLE`]) alone, in order.
#[test]
fn skipping_negligible_poses_leaves_the_covariance_exact() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let poses: Vec<(f64, Vector3<f64>)> = (0..4000)
        .map(|_| {
            // Log weights from 0 down to −40 below the best: about
            // half skipped unseen, a few weighed and dropped, the rest
            // kept.
            let score = 3.0 - rng.random_range(0.0..40.0f64);
            let x = Vector3::new(
                rng.random_range(-0.1..0.1),
                rng.random_range(-0.1..0.1),
                rng.random_range(-0.2..0.2),
            );
            (score, x)
        })
        .collect();
    let best = poses.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
    let kept: Vec<(f64, Vector3<f64>)> = poses
        .iter()
        .copied()
        .filter(|(score, _)| (score - best).exp() >= NEGLIGIBLE)
        .collect();
    let unseen = poses.iter().filter(|p| p.0 - best < NEGLIGIBLE_LN).count();
    assert!(unseen > 1000 && kept.len() > 1000 && unseen + kept.len() < poses.len());
    let (res, step) = (0.01, 0.004);
    assert_eq!(
        lattice_covariance(poses.iter().copied(), best, res, step),
        lattice_covariance(kept, best, res, step)
    );
}

/// Random walls and posts, seen from a random pose with noise, and a
/// prior off the truth by up to its own spread: the branch-and-bound
/// search finds the exhaustive search's best pose, covariance and rival
/// to the bit, scoring fewer poses.
#[test]
fn branch_and_bound_finds_what_the_exhaustive_search_finds() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (mut cases, mut scored, mut all, mut rivals) = (0, 0, 0, 0);
    for case in 0..24 {
        let mut world = Vec::new();
        for _ in 0..rng.random_range(2..7) {
            let (x0, y0) = (rng.random_range(-1.5..1.5), rng.random_range(-1.5..1.5));
            let angle: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            let length = rng.random_range(0.3..2.0);
            for k in 0..(length / 0.004) as usize {
                let t = k as f64 * 0.004;
                world.push(Point2::new(x0 + t * angle.cos(), y0 + t * angle.sin()));
            }
        }
        for _ in 0..rng.random_range(0..4) {
            let (cx, cy) = (rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            for k in 0..60 {
                let a = k as f64 / 60.0 * std::f64::consts::TAU;
                world.push(Point2::new(cx + 0.04 * a.cos(), cy + 0.04 * a.sin()));
            }
        }
        let field = field_of(&world);
        let truth = Pose2::new(
            rng.random_range(-0.3..0.3),
            rng.random_range(-0.3..0.3),
            rng.random_range(-3.0..3.0),
        );
        let mut seen = seen_from(&world, &truth, rng.random_range(0.8..2.0), 0.004, case);
        if case % 6 == 5 {
            // Clutter the map does not hold.
            seen.extend(
                (0..40).map(|_| Point2::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))),
            );
        }
        let prior = PosePrior {
            mean: truth
                * Pose2::new(
                    rng.random_range(-0.05..0.05),
                    rng.random_range(-0.05..0.05),
                    rng.random_range(-0.05..0.05),
                ),
            sigma_forward_m: rng.random_range(0.01..0.06),
            sigma_left_m: rng.random_range(0.01..0.06),
            sigma_theta_rad: rng.random_range(0.005..0.05),
        };
        let search = |search| RegisterConfig {
            search,
            ..RegisterConfig::default()
        };
        let full = register(&field, &seen, &prior, &search(Search::Exhaustive)).unwrap();
        let fast = register(&field, &seen, &prior, &search(Search::BranchAndBound)).unwrap();
        if full.evaluated == 0 {
            continue;
        }
        assert_eq!(
            Registration {
                evaluated: full.evaluated,
                ..fast.clone()
            },
            full,
            "case {case}"
        );
        cases += 1;
        scored += fast.evaluated;
        all += full.evaluated;
        rivals += usize::from(full.rival.is_some());
    }
    assert!(cases >= 20, "{cases} cases searched");
    assert!(rivals >= 1, "no case had a rival peak");
    assert!(scored * 10 < all, "{scored} of {all} poses scored");
}

#[test]
fn recovers_a_pose_far_off_its_prior() {
    let world = room();
    let field = field_of(&world);
    let truth = Pose2::new(1.005, 0.44, 0.06);
    let seen = seen_from(&world, &truth, 0.9, 0.003, 1);
    // The command said 0.5 m; the robot went 0.46 m and veered.
    let start = Pose2::new(0.55, 0.40, 0.03);
    let prior = PosePrior::after_forward(&start, 0.5, 1f64.to_radians(), &MotionNoise::default());
    let err0 = prior.mean.between(&truth);
    assert!(err0.translation().norm() > 0.03 && err0.theta.abs() > 1f64.to_radians());
    let reg = register(&field, &seen, &prior, &RegisterConfig::default()).unwrap();
    assert!(reg.accepted);
    let err = reg.pose.between(&truth);
    assert!(err.translation().norm() < 0.004, "{err:?}");
    assert!(err.theta.abs() < 0.2f64.to_radians(), "{err:?}");
    // The covariance is a covariance, and it is not wider than the prior.
    let c = reg.covariance;
    assert!((c - c.transpose()).norm() < 1e-12);
    assert!(c.symmetric_eigenvalues().iter().all(|&e| e > 0.0));
    assert!(c[(0, 0)] < prior.covariance()[(0, 0)] && c[(2, 2)] < prior.covariance()[(2, 2)]);
}

/// Two long parallel walls along x 0.6 m apart, nothing across: their
/// field, the truth at the middle, and what it sees.
fn corridor() -> (LikelihoodField, Pose2, Vec<Point2>) {
    let mut world = Vec::new();
    for k in 0..=1500 {
        let x = k as f64 * 0.002;
        world.push(Point2::new(x, 0.0));
        world.push(Point2::new(x, 0.6));
    }
    let truth = Pose2::new(1.5, 0.3, 0.0);
    let seen = seen_from(&world, &truth, 0.9, 0.002, 2);
    (field_of(&world), truth, seen)
}

#[test]
fn a_corridor_is_uncertain_along_its_walls() {
    let (field, truth, seen) = corridor();
    let start = Pose2::new(1.0, 0.3, 0.0);
    let prior = PosePrior::after_forward(&start, 0.5, 0.5f64.to_radians(), &MotionNoise::default());
    let reg = register(&field, &seen, &prior, &RegisterConfig::default()).unwrap();
    assert!(reg.accepted);
    assert!(
        (reg.pose.y - truth.y).abs() < 0.004,
        "across the corridor: pinned"
    );
    let c = reg.covariance;
    assert!(
        c[(0, 0)] > 20.0 * c[(1, 1)],
        "along the corridor: the walls say nothing ({c})"
    );
}

/// The corridor's posterior spreads along it: a limit below its spread
/// leaves the match untrusted (both searches alike), one above it changes
/// nothing.
#[test]
fn a_posterior_spread_over_too_many_poses_is_not_trusted() {
    let (field, _, seen) = corridor();
    let prior = PosePrior::after_forward(&Pose2::new(1.0, 0.3, 0.0), 0.5, 0.01, &MotionNoise::default());
    let with = |search, max_spread_poses| RegisterConfig {
        search,
        max_spread_poses,
        ..RegisterConfig::default()
    };
    let free = register(&field, &seen, &prior, &with(Search::Exhaustive, usize::MAX)).unwrap();
    assert!(free.accepted);
    for search in [Search::Exhaustive, Search::BranchAndBound] {
        let loose = register(&field, &seen, &prior, &with(search, 50)).unwrap();
        assert!(!loose.accepted, "{search:?}");
        assert_eq!(loose.pose, prior.mean);
        assert_eq!(loose.covariance, prior.covariance());
        let roomy = register(&field, &seen, &prior, &with(search, 1 << 20)).unwrap();
        assert_eq!(
            Registration {
                evaluated: free.evaluated,
                ..roomy
            },
            free,
            "{search:?}"
        );
    }
}

#[test]
fn too_little_to_match_keeps_the_prior_and_says_so() {
    let world = room();
    let field = field_of(&world);
    let prior = PosePrior::after_forward(&Pose2::new(0.5, 0.5, 0.0), 0.3, 0.01, &MotionNoise::default());
    let few = vec![Point2::new(0.3, 0.0); 3];
    let reg = register(&field, &few, &prior, &RegisterConfig::default()).unwrap();
    assert!(!reg.accepted);
    assert_eq!(reg.pose, prior.mean);
    assert_eq!(reg.covariance, prior.covariance());
    let bad = PosePrior {
        sigma_forward_m: 0.0,
        ..prior
    };
    assert!(register(&field, &few, &bad, &RegisterConfig::default()).is_err());
}

#[test]
fn prior_after_forward_moves_along_the_heading() {
    let start = Pose2::new(1.0, 2.0, std::f64::consts::FRAC_PI_2);
    let p = PosePrior::after_forward(&start, 0.5, 0.0, &MotionNoise::default());
    assert!((p.mean.x - 1.0).abs() < 1e-12 && (p.mean.y - 2.5).abs() < 1e-12);
    // Along the heading (world y here) the distance error dominates.
    let c = p.covariance();
    assert!((c[(1, 1)] - p.sigma_forward_m.powi(2)).abs() < 1e-12);
    assert!((c[(0, 0)] - p.sigma_left_m.powi(2)).abs() < 1e-12);
    assert!((p.sigma_forward_m - (0.05f64).hypot(0.01)).abs() < 1e-12);
}

#[test]
fn thinning_keeps_one_point_per_cell() {
    let pts = [
        Point2::new(0.001, 0.001),
        Point2::new(0.009, 0.002),
        Point2::new(0.011, 0.0),
        Point2::new(f64::NAN, 0.0),
    ];
    assert_eq!(thin_points(&pts, 0.01), vec![pts[0], pts[2]]);
}

/// The rival peak by a map of every kept pose: the definition, for
/// [`rival_peak`]'s slabs to be checked against.
fn rival_peak_by_map(kept: &[KeptPose], best: LatticeBest, apart: (i64, i64)) -> Option<KeptPose> {
    let score: std::collections::HashMap<(i64, i64, i64), f64> =
        kept.iter().map(|&(kt, k)| ((kt, k.a, k.b), k.score)).collect();
    let (ra, rt) = apart;
    let near = |kt: i64, a: i64, b: i64| {
        (kt - best.3).abs() <= rt && (a - best.1).abs() <= ra && (b - best.2).abs() <= ra
    };
    let peak = |kt: i64, k: &Kept| {
        (-1..=1).all(|dt| {
            (-1..=1).all(|da| {
                (-1..=1).all(|db| {
                    score
                        .get(&(kt + dt, k.a + da, k.b + db))
                        .is_none_or(|&s| s <= k.score)
                })
            })
        })
    };
    kept.iter()
        .copied()
        .filter(|&(kt, k)| !near(kt, k.a, k.b) && peak(kt, &k))
        .fold(None, |r: Option<KeptPose>, c| match r {
            Some(r) if r.1.score >= c.1.score => Some(r),
            _ => Some(c),
        })
}

#[test]
fn rival_peak_is_the_best_local_maximum_away_from_the_best() {
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let (mut found, mut none) = (0, 0);
    for case in 0..400 {
        let (nx, ny) = (rng.random_range(0..6i64), rng.random_range(0..6i64));
        let nt = rng.random_range(0..5i64);
        // Random subsets of the lattice with few distinct scores (ties).
        let density = rng.random_range(0.05..1.0);
        let mut kept: Vec<KeptPose> = Vec::new();
        for kt in -nt..=nt {
            for b in -ny..=ny {
                for a in -nx..=nx {
                    if rng.random_bool(density) {
                        let score = f64::from(rng.random_range(0..8u8));
                        kept.push((kt, Kept { a, b, score }));
                    }
                }
            }
        }
        let Some(&(bt, bk)) = kept.iter().max_by(|x, y| x.1.score.total_cmp(&y.1.score)) else {
            continue;
        };
        let best = (bk.score, bk.a, bk.b, bt);
        // Apart by a step (any peak beyond the best's neighbours), or more.
        let (ra, rt) = (rng.random_range(1..4i64), rng.random_range(1..3i64));
        let expected = rival_peak_by_map(&kept, best, (ra, rt));
        let got = rival_peak(&kept, best, nx, ny, Apart { a: ra, kt: rt });
        assert_eq!(
            got.map(|(t, k)| (t, k.a, k.b, k.score)),
            expected.map(|(t, k)| (t, k.a, k.b, k.score)),
            "case {case}"
        );
        if expected.is_some() {
            found += 1;
        } else {
            none += 1;
        }
    }
    assert!(
        found > 100 && none > 10,
        "{found} cases with a rival, {none} without"
    );
}
