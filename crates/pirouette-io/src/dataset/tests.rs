//! Tests of `dataset`.

use super::*;

fn manifest() -> Manifest {
    Manifest {
        format: FORMAT_VERSION.into(),
        name: "t".into(),
        camera: CameraSpec {
            width: 8,
            height: 6,
            ipm: IpmMeasurements {
                b: 0.09,
                h: 0.1,
                d: 0.12,
                w: 0.13,
            },
            pinhole: Some(PinholeSpec {
                fx: 7.0,
                fy: 7.0,
                cx: 3.5,
                cy: 2.5,
                height: 0.1,
                tilt_deg: 25.0,
                distortion: None,
            }),
            mount: None,
        },
        max_range: 0.9,
        frames: vec![
            FrameSpec {
                image: "frames/s00/000.png".into(),
                sweep: 0,
                motion: None,
                truth: Some(PoseSpec {
                    x: 0.1,
                    y: 0.2,
                    theta_deg: 30.0,
                }),
            },
            FrameSpec {
                image: "frames/s00/001.png".into(),
                sweep: 0,
                motion: Some(Motion::Turn { turn_deg: 30.0 }),
                truth: None,
            },
            FrameSpec {
                image: "frames/s01/000.png".into(),
                sweep: 1,
                motion: Some(Motion::Forward { forward: 0.3 }),
                truth: None,
            },
        ],
    }
}

fn write(dir: &Path, m: &Manifest) {
    Dataset::write_manifest(dir, m).unwrap();
    for f in &m.frames {
        Dataset::write_image(dir, &f.image, &image::RgbImage::new(8, 6)).unwrap();
    }
}

fn open_err(dir: &Path) -> String {
    Dataset::open(dir).unwrap_err().to_string()
}

#[test]
fn round_trip_keeps_every_field() {
    let dir = tempfile::tempdir().unwrap();
    let m = manifest();
    write(dir.path(), &m);
    let ds = Dataset::open(dir.path()).unwrap();
    assert_eq!(ds.manifest, m);
    assert_eq!(ds.load_image(2).unwrap().dimensions(), (8, 6));
    assert_eq!(ds.camera(None).unwrap().kind(), ModelKind::Pinhole);
    let t = TruthRop {
        bearing_start_deg: -2.5,
        bin_deg: 1.0,
        range: vec![None, Some(0.5)],
    };
    Dataset::write_truth_rop(dir.path(), "frames/s00/001.png", &t).unwrap();
    assert_eq!(ds.truth_rop(1).unwrap(), Some(t));
    assert_eq!(ds.truth_rop(0).unwrap(), None);
}

#[test]
fn optional_fields_are_optional() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), &manifest());
    let text = r#"{"format": "rop-dataset/1", "name": "n",
            "camera": {"width": 8, "height": 6, "ipm": {"b": 0.09, "h": 0.1, "d": 0.12, "w": 0.13}},
            "max_range": 0.9,
            "frames": [{"image": "frames/s00/000.png", "sweep": 0, "motion": null}]}"#;
    std::fs::write(dir.path().join("dataset.json"), text).unwrap();
    let ds = Dataset::open(dir.path()).unwrap();
    assert_eq!(ds.camera(None).unwrap().kind(), ModelKind::Paper);
    assert!(ds.camera(Some(ModelKind::Pinhole)).is_err());
    assert!(ds.truth_poses().is_none());
}

#[test]
fn bad_inputs_give_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, &manifest());
    let manifest_path = d.join("dataset.json").display().to_string();

    // Bad JSON.
    std::fs::write(d.join("dataset.json"), "{ not json").unwrap();
    let e = open_err(d);
    assert!(e.contains(&manifest_path) && e.contains("bad JSON"), "{e}");

    // Unknown format version.
    let mut m = manifest();
    m.format = "rop-dataset/2".into();
    Dataset::write_manifest(d, &m).unwrap();
    let e = open_err(d);
    assert!(e.contains("unknown format `rop-dataset/2`"), "{e}");

    // Non-finite numbers.
    let text = serde_json::to_string(&manifest())
        .unwrap()
        .replace("\"max_range\":0.9", "\"max_range\":-1");
    std::fs::write(d.join("dataset.json"), text).unwrap();
    assert!(open_err(d).contains("max_range"));
    let text = serde_json::to_string(&manifest())
        .unwrap()
        .replace("\"fx\":7.0", "\"fx\":1e999");
    std::fs::write(d.join("dataset.json"), text).unwrap();
    assert!(open_err(d).contains(&manifest_path));

    // Frame without image.
    let mut m = manifest();
    m.frames[1].image = "frames/s00/missing.png".into();
    Dataset::write_manifest(d, &m).unwrap();
    let e = open_err(d);
    assert!(e.contains("frames[1]") && e.contains("does not exist"), "{e}");
    m.frames[1].image = "../escape.png".into();
    Dataset::write_manifest(d, &m).unwrap();
    assert!(open_err(d).contains("inside the dataset"));

    // Wrong image size and unreadable image.
    Dataset::write_manifest(d, &manifest()).unwrap();
    let ds = Dataset::open(d).unwrap();
    Dataset::write_image(d, "frames/s00/001.png", &image::RgbImage::new(4, 4)).unwrap();
    let e = ds.load_image(1).unwrap_err().to_string();
    assert!(e.contains("001.png") && e.contains("4x4"), "{e}");
    std::fs::write(d.join("frames/s00/001.png"), b"not a png").unwrap();
    let e = ds.load_image(1).unwrap_err().to_string();
    assert!(e.contains("001.png") && e.contains("cannot decode"), "{e}");
    std::fs::remove_file(d.join("frames/s00/001.png")).unwrap();
    assert!(ds.load_image(1).unwrap_err().to_string().contains("001.png"));

    // Missing folder.
    assert!(open_err(&d.join("nope")).contains("nope"));
}

#[test]
fn grey_and_16_bit_images_load_as_rgb() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), &manifest());
    let grey = image::GrayImage::from_pixel(8, 6, image::Luma([100]));
    grey.save(dir.path().join("frames/s00/000.png")).unwrap();
    let deep = image::ImageBuffer::<image::Rgb<u16>, _>::from_pixel(8, 6, image::Rgb([65535, 0, 0]));
    deep.save(dir.path().join("frames/s00/001.png")).unwrap();
    let ds = Dataset::open(dir.path()).unwrap();
    assert_eq!(ds.load_image(0).unwrap().get_pixel(0, 0).0, [100, 100, 100]);
    assert_eq!(ds.load_image(1).unwrap().get_pixel(0, 0).0, [255, 0, 0]);
}

#[test]
fn a_lens_and_a_general_move_round_trip_and_reach_the_camera() {
    let dir = tempfile::tempdir().unwrap();
    let mut m = manifest();
    m.camera.pinhole.as_mut().unwrap().distortion = Some(LensSpec {
        model: "equidistant".into(),
        d: vec![-0.01, 0.02, -0.01, 0.004],
    });
    m.frames[2].motion = Some(Motion::Move {
        relative: MoveSpec {
            forward: 0.2,
            left: -0.05,
            turn_deg: 12.5,
        },
    });
    write(dir.path(), &m);
    let text = std::fs::read_to_string(dir.path().join("dataset.json")).unwrap();
    assert!(
        text.contains("\"move\"") && text.contains("\"equidistant\""),
        "{text}"
    );
    let ds = Dataset::open(dir.path()).unwrap();
    assert_eq!(ds.manifest, m);
    let Camera::Pinhole(p) = ds.camera(None).unwrap() else {
        panic!("the pinhole model")
    };
    assert_eq!(
        p.distortion,
        Distortion::Equidistant {
            k: [-0.01, 0.02, -0.01, 0.004]
        }
    );
    // The paper's model has no lens: asked for on a distorted camera, it
    // is refused rather than mapping through the wrong geometry.
    assert!(ds
        .camera(Some(ModelKind::Paper))
        .unwrap_err()
        .to_string()
        .contains("distortion"));
    let rel = ds.manifest.frames[2].motion.unwrap().relative_pose();
    assert_eq!((rel.x, rel.y), (0.2, -0.05));
    assert!((rel.theta - 12.5f64.to_radians()).abs() < 1e-15);
    // A turn then a straight move is the general move's special case.
    let turn_then_move =
        Motion::Turn { turn_deg: 30.0 }.relative_pose() * Motion::Forward { forward: 0.4 }.relative_pose();
    let general = Motion::from_relative(&turn_then_move).relative_pose();
    assert!((general.x - 0.4 * 30f64.to_radians().cos()).abs() < 1e-12);
    assert!((general.y - 0.4 * 30f64.to_radians().sin()).abs() < 1e-12);
}

#[test]
fn a_bad_lens_or_move_is_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let mut m = manifest();
    m.camera.pinhole.as_mut().unwrap().distortion = Some(LensSpec {
        model: "rational_polynomial".into(),
        d: vec![0.1; 8],
    });
    write(dir.path(), &m);
    let e = open_err(dir.path());
    assert!(
        e.contains("camera.pinhole.distortion") && e.contains("unknown distortion model"),
        "{e}"
    );
    let mut m = manifest();
    m.frames[2].motion = Some(Motion::Move {
        relative: MoveSpec {
            forward: 300.0,
            left: 0.0,
            turn_deg: 0.0,
        },
    });
    write(dir.path(), &m);
    let e = open_err(dir.path());
    assert!(e.contains("frames[2]") && e.contains("millimetres"), "{e}");
}
