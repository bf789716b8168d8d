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

/// Random walls and posts, seen from a random pose with noise, and a
/// prior off the truth by up to its own spread: the branch-and-bound
/// search finds the exhaustive search's best pose, covariance and rival
/// to the bit, scoring a fraction of the poses.
#[test]
fn branch_and_bound_finds_what_the_exhaustive_search_finds() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (mut cases, mut scored, mut all, mut rivals, mut every_pose) = (0, 0, 0, 0, 0);
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
        // The cheaper first, while the field has no pooled levels yet.
        let cheaper = register(&field, &seen, &prior, &search(Search::Cheaper)).unwrap();
        let full = register(&field, &seen, &prior, &search(Search::Exhaustive)).unwrap();
        let fast = register(&field, &seen, &prior, &search(Search::BranchAndBound)).unwrap();
        if full.evaluated == 0 {
            continue;
        }
        assert_eq!(
            Registration {
                evaluated: full.evaluated,
                ..cheaper
            },
            full,
            "case {case}: the cheaper search"
        );
        every_pose += usize::from(cheaper.evaluated == full.evaluated);
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
    // (The field's pooled levels bound aligned blocks, up to twice as wide
    // as a search's block, and the rival is sought 10 nats down: an eighth.)
    assert!(scored * 5 < all, "{scored} of {all} poses scored");
    // The cheaper search scored every pose somewhere (a field without
    // levels, a small window), not everywhere.
    assert!(
        (1..cases).contains(&every_pose),
        "every pose scored in {every_pose} of {cases} cases"
    );
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

/// Laplace's covariance at the refined pose is the spread of the exact
/// posterior about it: weighed on a fine grid of poses (the exact field's
/// score plus the prior, exponentiated), the room's posterior has the
/// variances the curvature gives, to within a fifth.
#[test]
fn laplace_is_the_spread_of_the_exact_posterior() {
    let world = room();
    let field = field_of(&world);
    let truth = Pose2::new(0.9, 0.55, 0.4);
    let seen = seen_from(&world, &truth, 2.0, 1e-6, 1);
    let prior = PosePrior {
        mean: truth * Pose2::new(0.004, -0.003, 0.003),
        sigma_forward_m: 0.02,
        sigma_left_m: 0.02,
        sigma_theta_rad: 0.02,
    };
    let config = RegisterConfig {
        covariance: Covariance::Laplace,
        ..RegisterConfig::default()
    };
    let res = field.resolution_m();
    let points = thin_points(&seen, config.spacing_m.max(res));
    let (lattice, _) = Lattice::around(&prior, &points, res, &config);
    let anchored = Anchored::new(&field, &points, prior.mean, res);
    let (pose, information) = refine(&anchored, &prior, res, lattice.theta_step);
    let laplace = information.try_inverse().unwrap();
    // The exact posterior on a grid of ±4σ, 17 steps a side.
    let sd = |k: usize| laplace[(k, k)].sqrt();
    let n = 8i64;
    let step = [
        4.0 * sd(0) / n as f64,
        4.0 * sd(1) / n as f64,
        4.0 * sd(2) / n as f64,
    ];
    let mut samples = Vec::new();
    for i in -n..=n {
        for j in -n..=n {
            for k in -n..=n {
                let d = Vector3::new(i as f64 * step[0], j as f64 * step[1], k as f64 * step[2]);
                let p = Pose2::new(pose.x + d.x, pose.y + d.y, pose.theta + d.z);
                let score = anchored.evaluate(&p).0 + prior.log_density(p.x, p.y, p.theta);
                samples.push((score, d));
            }
        }
    }
    let top = samples.iter().map(|s| s.0).fold(f64::NEG_INFINITY, f64::max);
    let (mut w_sum, mut mean, mut second) = (0.0, Vector3::zeros(), Matrix3::zeros());
    for (score, d) in &samples {
        let w = (score - top).exp();
        w_sum += w;
        mean += w * d;
        second += w * d * d.transpose();
    }
    mean /= w_sum;
    let exact = second / w_sum - mean * mean.transpose();
    for k in 0..3 {
        let ratio = exact[(k, k)] / laplace[(k, k)];
        assert!(
            (0.8..1.25).contains(&ratio),
            "axis {k}: exact {exact} against Laplace {laplace}"
        );
    }
    // And the refined pose is the posterior's peak to within a step of
    // the grid, a third of its spread (the exact field of points sampled
    // every 2 mm has kinks where the nearest point changes, at which the
    // Gauss-Newton steps stop).
    let (_, at) = samples
        .iter()
        .fold((f64::NEG_INFINITY, Vector3::zeros()), |b, s| {
            if s.0 > b.0 {
                (s.0, s.1)
            } else {
                b
            }
        });
    for k in 0..3 {
        assert!(
            at[k].abs() <= step[k] * 1.001,
            "axis {k}: the grid's best {at} off the pose"
        );
    }
}

/// Two views of random walls, each a camera's 60° sector up to 2.5 m,
/// from poses apart by up to 2 m and any heading: where they share
/// nothing `may_accept` says so before any search, and it never says so
/// of a pair that registration accepts (both covariances, both searches
/// of the posterior).
#[test]
fn may_accept_refuses_only_what_registration_would_not_accept() {
    let mut rng = ChaCha8Rng::seed_from_u64(29);
    let sector = |world: &[Point2], pose: &Pose2| -> Vec<Point2> {
        seen_from(world, pose, 2.5, 0.003, 0)
            .into_iter()
            .filter(|p| p.y.atan2(p.x).abs() <= 30f64.to_radians())
            .collect()
    };
    let (mut refused, mut accepted, mut cases) = (0, 0, 0);
    for _ in 0..200 {
        let mut world = Vec::new();
        for _ in 0..rng.random_range(3..8) {
            let (x0, y0) = (rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0));
            let angle: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            let length = rng.random_range(0.5..3.0);
            for k in 0..(length / 0.004) as usize {
                let t = k as f64 * 0.004;
                world.push(Point2::new(x0 + t * angle.cos(), y0 + t * angle.sin()));
            }
        }
        let a = Pose2::new(0.0, 0.0, rng.random_range(-3.0..3.0));
        let b = Pose2::new(
            rng.random_range(-1.4..1.4),
            rng.random_range(-1.4..1.4),
            a.theta + rng.random_range(-1.5..1.5),
        );
        let mapped: Vec<Point2> = sector(&world, &a)
            .into_iter()
            .map(|p| a.transform_point(p))
            .collect();
        let seen = sector(&world, &b);
        if mapped.len() < 20 || seen.len() < 20 {
            continue;
        }
        let field = field_of(&mapped);
        let prior = PosePrior {
            mean: b * Pose2::new(rng.random_range(-0.05..0.05), rng.random_range(-0.05..0.05), 0.02),
            sigma_forward_m: 0.05,
            sigma_left_m: 0.05,
            sigma_theta_rad: 3f64.to_radians(),
        };
        for (covariance, search) in [
            (Covariance::Posterior, Search::Exhaustive),
            (Covariance::Posterior, Search::BranchAndBound),
            (Covariance::Laplace, Search::BranchAndBound),
        ] {
            let config = RegisterConfig {
                covariance,
                search,
                ..RegisterConfig::default()
            };
            let may = may_accept(&field, &seen, &prior, &config).unwrap();
            let reg = register(&field, &seen, &prior, &config).unwrap();
            assert!(may || !reg.accepted, "refused a pair registration accepts");
            cases += 1;
            refused += usize::from(!may);
            accepted += usize::from(reg.accepted);
        }
    }
    // Both outcomes are exercised.
    assert!(
        cases >= 90 && refused >= 20 && accepted >= 20,
        "{cases} {refused} {accepted}"
    );
}

/// An endpoint counts as matched within 2σ of an obstacle on unseen floor.
#[test]
fn the_matched_radius_is_two_sigma() {
    let field = LikelihoodField::from_points(&[Point2::new(0.0, 0.0)], 0.01, 0.015, 0.2);
    let r = field.matched_radius().unwrap();
    assert!((r - 0.03).abs() < 1e-6, "{r}");
    // Just inside it the value is the matched level's; just beyond, below.
    let near = (0.2 + 0.8 * (-2.0f64).exp()).ln();
    assert!(field.exact(Point2::new(0.03 - 1e-7, 0.0)) >= near);
    assert!(field.exact(Point2::new(0.03 + 1e-4, 0.0)) < near);
}
