//! Random places for benchmarks and tests: sweeps of random rectangular
//! rooms with round obstacles, seen from random spots.

use crate::{PlaceIndex, PlaceMeta, PlacesError, SignatureConfig};
use pirouette_profile::{ColourTag, Rop};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::{PI, TAU};

/// A random room's sweep: a rectangle 2-8 m a side with up to six round
/// obstacles 0.1-0.4 m across, seen from a random spot in it with a
/// random heading, each surface with its own colour; 1° bins; ranges
/// beyond `limit_m` read as no return.
pub fn random_sweep(rng: &mut impl Rng, limit_m: f32) -> Rop {
    let (w, h) = (rng.random_range(2.0..8.0), rng.random_range(2.0..8.0));
    let (x, y) = (rng.random_range(0.2..w - 0.2), rng.random_range(0.2..h - 0.2));
    let heading: f64 = rng.random_range(-PI..PI);
    let count = rng.random_range(0..=6);
    let mut colour = || ColourTag::from_rgb([rng.random(), rng.random(), rng.random()]);
    let walls: [Option<ColourTag>; 4] = std::array::from_fn(|_| colour());
    let disc_colours: Vec<Option<ColourTag>> = (0..count).map(|_| colour()).collect();
    let discs: Vec<[f64; 3]> = (0..count)
        .map(|_| {
            [
                rng.random_range(0.0..w),
                rng.random_range(0.0..h),
                rng.random_range(0.05..0.2),
            ]
        })
        .collect();
    let bins = 360;
    let mut rop = Rop::empty(-PI, TAU / bins as f64, bins, limit_m);
    for i in 0..bins {
        let (s, c) = (heading + rop.bin_centre_rad(i)).sin_cos();
        // The room's walls: the nearest of the four lines ahead.
        let mut best = (f64::INFINITY, None);
        for (t, wall) in [((w - x) / c, 0), (-x / c, 1), ((h - y) / s, 2), (-y / s, 3)] {
            if t > 0.0 && t < best.0 {
                best = (t, walls[wall]);
            }
        }
        for ([cx, cy, r], tag) in discs.iter().zip(&disc_colours) {
            let (dx, dy) = (cx - x, cy - y);
            let along = dx * c + dy * s;
            let across2 = dx * dx + dy * dy - along * along;
            if along > 0.0 && across2 < r * r {
                let t = along - (r * r - across2).sqrt();
                if t > 0.0 && t < best.0 {
                    best = (t, *tag);
                }
            }
        }
        let (t, tag) = best;
        if t <= f64::from(limit_m) {
            rop.range_m[i] = t as f32;
            rop.colour[i] = tag;
        } else {
            rop.range_m[i] = f32::INFINITY;
        }
    }
    rop
}

/// An index of `places` random places (default signature settings, soft
/// range limit 4 m), reproducible from `seed`.
pub fn random_index(places: usize, seed: u64) -> Result<PlaceIndex, PlacesError> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut index = PlaceIndex::new(SignatureConfig::default())?;
    let dataset = index.dataset_id("synthetic");
    for sweep in 0..places {
        let rop = random_sweep(&mut rng, SYNTHETIC_LIMIT_M);
        let signature = index.transforms().signature(&rop)?;
        let meta = PlaceMeta {
            dataset,
            sweep: sweep as u32,
            truth: None,
            profile: None,
            map_pose: None,
            look_alike: None,
        };
        index.insert(&signature, SYNTHETIC_LIMIT_M, meta)?;
    }
    Ok(index)
}

/// The soft range limit of [`random_index`]'s places, metres.
pub const SYNTHETIC_LIMIT_M: f32 = 4.0;
