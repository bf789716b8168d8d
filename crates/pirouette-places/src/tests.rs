use super::*;
use pirouette_profile::{ColourTag, Rop};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::f64::consts::{PI, TAU};

/// A sweep of a smooth room turned by `turn_rad`, 0.25° bins, limit 2 m.
fn room(turn_rad: f64) -> Rop {
    let mut rop = Rop::empty(-PI, 0.25f64.to_radians(), 1440, 2.0);
    for i in 0..rop.len() {
        let b = rop.bin_centre_rad(i) + turn_rad;
        rop.range_m[i] =
            (1.0 + 0.3 * (2.0 * b).cos() + 0.2 * (3.0 * b + 1.0).sin() + 0.1 * (7.0 * b).cos()) as f32;
        let red = if b.rem_euclid(TAU) < PI { 200.0 } else { 40.0 };
        rop.colour[i] = ColourTag::from_rgb([red, 120.0, 90.0]);
    }
    rop
}

fn transforms() -> Transforms {
    Transforms::new(&SignatureConfig::default()).unwrap()
}

#[test]
fn the_key_is_unchanged_by_a_turn_and_the_shift_search_finds_it() {
    let t = transforms();
    let a = t.signature(&room(0.0)).unwrap();
    for turn_deg in [-170.0, -33.3, 0.0, 12.7, 90.0, 179.0] {
        let b = t.signature(&room(f64::to_radians(turn_deg))).unwrap();
        for (ka, kb) in a.key.iter().zip(&b.key) {
            // A turn by a fraction of a 1° sample changes the samples slightly.
            assert!((ka - kb).abs() < 2e-3, "{turn_deg}: {ka} vs {kb}");
        }
        let (mut qa, mut qb) = (Vec::new(), Vec::new());
        t.rebuild(&b.dct, &mut qb);
        t.rebuild(&a.dct, &mut qa);
        let (rotation, rms) = t.best_shifts(&qb, &t.spectrum(&qb), &qa, 1)[0];
        let err = pirouette_geom::wrap_angle(rotation - turn_deg.to_radians()).to_degrees();
        assert!(
            err.abs() < 1.0,
            "turn {turn_deg}°: found {}°",
            rotation.to_degrees()
        );
        assert!(rms < 0.05, "{rms}");
    }
}

#[test]
fn a_signature_fits_the_size_budget() {
    let s = transforms().signature(&room(0.0)).unwrap();
    let bytes = 4 * (s.key.len() + s.dct.len()) + 4 + 2 * s.colour.chroma.len();
    assert_eq!(bytes, SignatureConfig::default().signature_bytes());
    assert_eq!(bytes, 180);
}

#[test]
fn unseen_bins_are_filled_between_their_seen_neighbours_and_too_few_refused() {
    let config = SignatureConfig::default();
    let mut rop = Rop::empty(-PI, 1f64.to_radians(), 360, 2.0);
    for i in 0..360 {
        rop.range_m[i] = 1.0;
    }
    // Bins at bearings [0°, 10°) unseen; those at 10° read 2 m (no return).
    for i in 180..190 {
        rop.range_m[i] = f32::NAN;
    }
    rop.range_m[190] = f32::INFINITY;
    let v = condition(&rop, &config).unwrap();
    // Sample j covers bearings [j, j+1)°: samples 0..10 unseen, filled
    // from 1 m (sample 359) to 2 m (sample 10).
    assert_eq!(v[10], 2.0);
    for (g, sample) in v.iter().take(10).enumerate() {
        let expected = 1.0 + (g + 1) as f64 / 11.0;
        assert!((sample - expected).abs() < 1e-12, "{g}: {sample}");
    }
    for i in 0..300 {
        rop.range_m[i] = f32::NAN;
    }
    assert!(matches!(
        condition(&rop, &config),
        Err(PlacesError::IncompleteSweep { .. })
    ));
}

#[test]
fn colour_tags_do_not_change_with_the_light() {
    let t = transforms();
    let a = t.signature(&room(0.0)).unwrap();
    // A warmer, dimmer light: every channel scaled differently.
    let mut warm = room(0.0);
    for c in warm.colour.iter_mut().flatten() {
        let rgb = c.0.map(f32::from);
        *c = ColourTag::from_rgb([rgb[0] * 0.9, rgb[1] * 0.6, rgb[2] * 0.4]).unwrap();
    }
    let b = t.signature(&warm).unwrap();
    let d = colour_distance(&a.colour, b.colour.seen, &b.colour.chroma, 0.0, 4).unwrap();
    assert!(d < 0.05, "{d}");
    // Turned half round, the red half faces the other way.
    let d = colour_distance(&a.colour, b.colour.seen, &b.colour.chroma, PI, 4).unwrap();
    assert!(d > 0.8, "{d}");
}

#[test]
fn the_tree_finds_what_a_scan_of_every_key_finds() {
    let index = synthetic::random_index(3000, 7).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let config = QueryConfig::default();
    for _ in 0..50 {
        let rop = synthetic::random_sweep(&mut rng, synthetic::SYNTHETIC_LIMIT_M);
        let q = index.transforms().signature(&rop).unwrap();
        assert_eq!(index.query(&q, &config), index.query_brute(&q, &config));
        for k in [1, 16, 300] {
            assert_eq!(index.nearest_keys(&q.key, k), index.nearest_keys_brute(&q.key, k));
        }
    }
    // A stored key (found within the first fetch), one far from every
    // place (the search falls back to a scan), and one far on the
    // dimensions the tree leaves out (a wide ball searched in the tree).
    let stored = index.contents().keys[17];
    let far = stored.map(|v| v + 10.0);
    let mut off_tree = stored;
    off_tree[KEY_DIMS - 1] += 3.0;
    for key in [stored, far, off_tree] {
        for k in [1, 16, 300] {
            assert_eq!(index.nearest_keys(&key, k), index.nearest_keys_brute(&key, k));
        }
    }
}

#[test]
fn a_stored_place_seen_again_turned_is_found_first() {
    let mut index = synthetic::random_index(500, 3).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let rop = synthetic::random_sweep(&mut rng, synthetic::SYNTHETIC_LIMIT_M);
    let s = index.transforms().signature(&rop).unwrap();
    let dataset = index.dataset_id("extra");
    let meta = PlaceMeta {
        dataset,
        sweep: 0,
        truth: None,
        profile: Some(StoredProfile::from_rop(&rop)),
        map_pose: None,
        look_alike: None,
    };
    let id = index.insert(&s, synthetic::SYNTHETIC_LIMIT_M, meta).unwrap();
    // The same view turned by 50 bins (50°).
    let mut turned = rop.clone();
    turned.range_m.rotate_left(50);
    turned.colour.rotate_left(50);
    let q = index.transforms().signature(&turned).unwrap();
    let best = index.query(&q, &QueryConfig::default())[0];
    assert_eq!(best.place, id);
    assert!(
        (best.rotation_rad.to_degrees() - 50.0).abs() < 1.0,
        "{}",
        best.rotation_rad.to_degrees()
    );
}

#[test]
fn a_stored_profile_keeps_ranges_to_a_millimetre() {
    let mut rop = room(0.3);
    rop.range_m[5] = f32::NAN;
    rop.range_m[6] = f32::INFINITY;
    let back = StoredProfile::from_rop(&rop).to_rop().unwrap();
    assert!(back.range_m[5].is_nan() && back.range_m[6] == f32::INFINITY);
    for i in 7..rop.len() {
        assert!((back.range_m[i] - rop.range_m[i]).abs() <= 0.0005 + 1e-6);
    }
    assert_eq!(back.bin_centre_rad(100), rop.bin_centre_rad(100));
}

#[test]
fn signatures_of_other_settings_or_range_limits_are_refused() {
    let mut index = PlaceIndex::new(SignatureConfig::default()).unwrap();
    let s = index.transforms().signature(&room(0.0)).unwrap();
    let d = index.dataset_id("a");
    let meta = PlaceMeta {
        dataset: d,
        sweep: 0,
        truth: None,
        profile: None,
        map_pose: None,
        look_alike: None,
    };
    index.insert(&s, 2.0, meta.clone()).unwrap();
    assert!(matches!(
        index.insert(&s, 3.0, meta.clone()),
        Err(PlacesError::Mismatch { .. })
    ));
    let other = Transforms::new(&SignatureConfig {
        coefficients: 16,
        ..SignatureConfig::default()
    })
    .unwrap()
    .signature(&room(0.0))
    .unwrap();
    assert!(matches!(
        index.insert(&other, 2.0, meta),
        Err(PlacesError::Mismatch { .. })
    ));
}

#[test]
fn inconsistent_contents_are_refused() {
    let index = synthetic::random_index(10, 1).unwrap();
    let mut c = index.contents().clone();
    c.dct.pop();
    assert!(matches!(
        PlaceIndex::from_contents(c),
        Err(PlacesError::BadIndex { .. })
    ));
    let mut c = index.contents().clone();
    c.meta[3].dataset = 9;
    assert!(PlaceIndex::from_contents(c).is_err());
    let mut c = index.contents().clone();
    c.keys[2][0] = f32::NAN;
    assert!(PlaceIndex::from_contents(c).is_err());
    let mut c = index.contents().clone();
    c.config.samples = 0;
    assert!(matches!(
        PlaceIndex::from_contents(c),
        Err(PlacesError::BadConfig { .. })
    ));
}
