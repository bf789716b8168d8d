//! ROS bags as camera input: `sensor_msgs/Image` or
//! `sensor_msgs/CompressedImage` (JPEG, PNG) frames, with the robot's
//! `nav_msgs/Odometry` where the bag has it, or else the `/tf` transform
//! that places the robot's base (`base_link` or `base_footprint`) in the
//! odometry frame.
//!
//! Read in two passes, so that only the chosen frames are held: the first
//! pass takes every image's stamp and the odometry
//! ([`CameraBag::scan`]); the caller chooses frames from those; the second
//! pass keeps the chosen images' messages ([`CameraBag::frames`]), which
//! are decoded one at a time when a frame is loaded ([`BagFrames::decode`]).

use super::wire::{self, Wire};
use super::{choose, log_kind, open_bag, TF_TYPES};
use crate::IoError;
use pirouette_geom::Pose2;
use std::path::{Path, PathBuf};

const IMAGE_TYPE: &str = "sensor_msgs/Image";
const COMPRESSED_TYPE: &str = "sensor_msgs/CompressedImage";
const ODOM_TYPES: [&str; 1] = ["nav_msgs/Odometry"];

/// The most bytes of image messages held for the chosen frames.
pub const MAX_HELD_BYTES: usize = 4 << 30;

/// A bag's image stream and odometry, without the pixels.
#[derive(Debug, Clone)]
pub struct CameraBag {
    /// The bag's storage file.
    pub path: PathBuf,
    /// The images' topic.
    pub topic: String,
    /// Whether it carries `sensor_msgs/CompressedImage`.
    pub compressed: bool,
    /// Where the odometry comes from: its topic, or `/tf (parent → base)`.
    pub odom_topic: Option<String>,
    /// Each image's header stamp, seconds, in bag order (increasing).
    pub stamps: Vec<f64>,
    /// The odometry (the base's pose in the odometry frame), by stamp.
    pub odometry: Vec<(f64, Pose2)>,
    /// Odometry messages stamped before the previous, skipped.
    pub skipped_odometry: usize,
    /// Damage read past (a ROS 1 bag cut short, chunks skipped).
    pub warnings: Vec<String>,
}

/// The chosen frames' image messages, held to be decoded when loaded.
#[derive(Debug, Clone)]
pub struct BagFrames {
    /// The bag's storage file.
    pub path: PathBuf,
    /// The images' topic.
    pub topic: String,
    wire: Wire,
    compressed: bool,
    messages: Vec<Vec<u8>>,
}

impl BagFrames {
    /// How many frames are held.
    pub fn len(&self) -> usize {
        self.messages.len()
    }

    /// True when none is.
    pub fn is_empty(&self) -> bool {
        self.messages.is_empty()
    }

    /// Frame `k`'s image as 8-bit RGB.
    ///
    /// # Panics
    /// When `k` is not a held frame.
    pub fn decode(&self, k: usize) -> Result<image::RgbImage, IoError> {
        let bytes = &self.messages[k];
        let img = if self.compressed {
            wire::compressed_image(bytes, self.wire)
        } else {
            wire::image(bytes, self.wire)
        };
        img.map_err(|p| IoError::invalid(&self.path, format!("topic {}, chosen frame {k}: {p}", self.topic)))
    }
}

fn seconds(ns: i64) -> f64 {
    ns as f64 * 1e-9
}

impl CameraBag {
    /// Reads the image stamps and odometry of the bag at `path` (a ROS 1
    /// bag, a ROS 2 bag folder or its storage file). `image_topic` names
    /// the images where the bag has several image topics; `odom_topic`
    /// the odometry where it has several.
    pub fn scan(path: &Path, image_topic: Option<&str>, odom_topic: Option<&str>) -> Result<Self, IoError> {
        let (kind, file) = log_kind(path)?;
        let mut source = open_bag(kind, &file)?;
        let s = source.as_ref();
        let topic = choose(
            &file,
            s,
            image_topic,
            &[IMAGE_TYPE, COMPRESSED_TYPE],
            "image_topic",
        )?;
        let Some(topic) = topic else {
            let all: Vec<String> = (s.connections().iter())
                .map(|c| format!("{} ({})", c.topic, c.msg_type))
                .collect();
            return Err(IoError::invalid(
                &file,
                format!(
                    "no sensor_msgs/Image or CompressedImage topic in the bag (it has {})",
                    all.join(", ")
                ),
            ));
        };
        // `choose` counts Image and CompressedImage topics as one kind.
        let compressed = s
            .connections()
            .iter()
            .any(|c| c.topic == topic && c.msg_type == COMPRESSED_TYPE);
        let odom = choose(&file, s, odom_topic, &ODOM_TYPES, "odom_topic")?;
        let images_on: Vec<bool> = s.connections().iter().map(|c| c.topic == topic).collect();
        let odom_on: Vec<bool> = s
            .connections()
            .iter()
            .map(|c| Some(&c.topic) == odom.as_ref())
            .collect();
        // Without an odometry topic, `/tf`'s transforms of the base.
        let tf_on: Vec<bool> = (s.connections().iter())
            .map(|c| odom.is_none() && c.topic == "/tf" && TF_TYPES.contains(&c.msg_type.as_str()))
            .collect();
        let mut tf_frames: Option<(String, String)> = None;
        let wire = s.wire();
        let mut out = CameraBag {
            path: file.clone(),
            topic,
            compressed,
            odom_topic: odom,
            stamps: Vec::new(),
            odometry: Vec::new(),
            skipped_odometry: 0,
            warnings: Vec::new(),
        };
        while let Some(m) = source.next_message()? {
            let bad = |p: String| {
                IoError::invalid(
                    &file,
                    format!(
                        "topic {}, message at byte {} (sqlite3: row {}): {p}",
                        out.topic, m.offset, m.offset
                    ),
                )
            };
            if images_on[m.connection] {
                let (stamp_ns, _) = wire::image_header(&m.data, wire).map_err(bad)?;
                let t = seconds(stamp_ns);
                if let Some(&last) = out.stamps.last() {
                    if t <= last {
                        return Err(bad(format!("frames out of time order: {t} s after {last} s")));
                    }
                }
                out.stamps.push(t);
            } else if odom_on[m.connection] || tf_on[m.connection] {
                let poses = if odom_on[m.connection] {
                    vec![wire::odometry(&m.data, wire).map_err(bad)?]
                } else {
                    wire::transforms(&m.data, wire).map_err(bad)?
                };
                for p in poses {
                    if tf_on[m.connection] {
                        // The first transform of a base fixes the pair.
                        match &tf_frames {
                            Some((parent, child)) if *parent != p.parent || *child != p.child => continue,
                            Some(_) => {}
                            None if matches!(p.child.as_str(), "base_link" | "base_footprint") => {
                                tf_frames = Some((p.parent.clone(), p.child.clone()));
                            }
                            None => continue,
                        }
                    }
                    let t = seconds(p.stamp_ns);
                    if out.odometry.last().is_some_and(|&(last, _)| t <= last) {
                        out.skipped_odometry += 1;
                    } else {
                        out.odometry.push((t, p.pose));
                    }
                }
            }
        }
        if out.stamps.is_empty() {
            return Err(IoError::invalid(
                &file,
                format!("no image on topic {}", out.topic),
            ));
        }
        out.warnings = source.warnings();
        Ok(out)
    }

    /// The image messages of the frames at positions `chosen` (increasing)
    /// of [`CameraBag::stamps`], read in a second pass.
    pub fn frames(&self, chosen: &[usize]) -> Result<BagFrames, IoError> {
        let (kind, file) = log_kind(&self.path)?;
        let mut source = open_bag(kind, &file)?;
        let on: Vec<bool> = source
            .connections()
            .iter()
            .map(|c| c.topic == self.topic)
            .collect();
        let mut messages = Vec::with_capacity(chosen.len());
        let (mut k, mut held) = (0usize, 0usize);
        while messages.len() < chosen.len() {
            let Some(m) = source.next_message()? else {
                break;
            };
            if !on[m.connection] {
                continue;
            }
            if chosen[messages.len()] == k {
                held += m.data.len();
                if held > MAX_HELD_BYTES {
                    return Err(IoError::invalid(
                        &file,
                        format!(
                            "the chosen frames' images pass {} GiB: choose fewer (select.min_turn_deg, min_move_m or every)",
                            MAX_HELD_BYTES >> 30
                        ),
                    ));
                }
                messages.push(m.data);
            }
            k += 1;
        }
        if messages.len() < chosen.len() {
            return Err(IoError::invalid(&file, "the bag changed between two readings"));
        }
        Ok(BagFrames {
            path: file,
            topic: self.topic.clone(),
            wire: source.wire(),
            compressed: self.compressed,
            messages,
        })
    }
}

#[cfg(test)]
mod tests {
    use crate::bag::wire::{encode, FramePose, Wire};
    use crate::bag::write::{write_mcap, write_ros1, OutMessage, Ros1Compression};
    use crate::bag::Connection;
    use crate::{Dataset, Motion};
    use pirouette_geom::Pose2;
    use std::path::Path;

    const CALIBRATION: &str = "image_width: 16\nimage_height: 12\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [14, 0, 7.5, 0, 14, 5.5, 0, 0, 1]\ndistortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\n";

    /// Frame `k`: a different grey for each, so that frames tell apart.
    fn frame(k: usize) -> image::RgbImage {
        image::RgbImage::from_fn(16, 12, |u, v| image::Rgb([(10 * k) as u8, u as u8, v as u8]))
    }

    /// Twelve frames 0.1 s apart, the robot turning 4° each 0.1 s, as
    /// raw images on one topic and PNG on another, with odometry every
    /// 0.01 s; in `wire`'s serialisation.
    fn recording(wire: Wire) -> (Vec<Connection>, Vec<OutMessage>) {
        recording_with(wire, false)
    }

    /// As [`recording`], the odometry as `/tf` transforms (with another
    /// frame's transform beside each) where `tf` is set.
    fn recording_with(wire: Wire, tf: bool) -> (Vec<Connection>, Vec<OutMessage>) {
        let connections = vec![
            Connection::new("/camera/image_raw".into(), "sensor_msgs/Image"),
            Connection::new(
                "/camera/image_raw/compressed".into(),
                "sensor_msgs/msg/CompressedImage",
            ),
            if tf {
                Connection::new("/tf".into(), "tf2_msgs/msg/TFMessage")
            } else {
                Connection::new("/odom".into(), "nav_msgs/Odometry")
            },
        ];
        let mut messages = Vec::new();
        let t0 = 1_000_000_000_000i64;
        for k in 0..=120i64 {
            let t = t0 + k * 10_000_000;
            if k % 10 == 0 && k < 120 {
                let img = frame((k / 10) as usize);
                let mut png = Vec::new();
                img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
                    .unwrap();
                for (c, data) in [
                    (0, encode::image(t, "camera", &img, wire)),
                    (1, encode::compressed_image(t, "camera", &png, wire)),
                ] {
                    messages.push(OutMessage {
                        connection: c,
                        time_ns: t as u64,
                        data,
                    });
                }
            }
            let odom = FramePose {
                stamp_ns: t,
                parent: "odom".into(),
                child: "base_link".into(),
                pose: Pose2::new(0.0, 0.0, (0.4 * k as f64).to_radians()),
            };
            let arm = FramePose {
                parent: "base_link".into(),
                child: "arm".into(),
                pose: Pose2::new(1.0, 2.0, 3.0),
                ..odom.clone()
            };
            messages.push(OutMessage {
                connection: 2,
                time_ns: t as u64,
                data: if tf {
                    encode::transforms(&[arm, odom], wire)
                } else {
                    encode::odometry(&odom, wire)
                },
            });
        }
        (connections, messages)
    }

    fn rig(dir: &Path, bag: &str, topic: Option<&str>) {
        std::fs::write(dir.join("camera_info.yaml"), CALIBRATION).unwrap();
        let topic = topic.map_or(String::new(), |t| format!(r#", "image_topic": "{t}""#));
        std::fs::write(
            dir.join("rig.json"),
            format!(
                r#"{{ "format": "pirouette-images/1", "calibration": "camera_info.yaml", "height": 0.3,
                     "tilt_deg": 20.0, "max_range": 2.0, "bag": "{bag}"{topic} }}"#
            ),
        )
        .unwrap();
    }

    #[test]
    fn ros1_and_ros2_camera_bags_give_the_same_frames_chosen_by_odometry() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path();
        let (c1, m1) = recording(Wire::Ros1);
        write_ros1(&p.join("run.bag"), &c1, m1, Ros1Compression::Lz4, 1 << 12).unwrap();
        let (c2, m2) = recording(Wire::Cdr);
        write_mcap(&p.join("run2"), &c2, m2).unwrap();
        let (c3, m3) = recording_with(Wire::Cdr, true);
        write_mcap(&p.join("run-tf"), &c3, m3).unwrap();
        for (bag, topic) in [
            ("run.bag", "/camera/image_raw"),
            ("run.bag", "/camera/image_raw/compressed"),
            ("run2", "/camera/image_raw/compressed"),
            ("run2", "/camera/image_raw"),
            ("run-tf", "/camera/image_raw"),
        ] {
            rig(p, bag, Some(topic));
            let ds = Dataset::open(p).unwrap();
            // 4° a frame, a frame chosen at every 10°: 0, 3, 6, 9.
            assert_eq!(ds.manifest.frames.len(), 4, "{bag} {topic}");
            for (n, f) in ds.manifest.frames.iter().enumerate() {
                assert_eq!(ds.load_image(n).unwrap(), frame(3 * n), "{bag} {topic} frame {n}");
                match f.motion {
                    None => assert_eq!(n, 0),
                    Some(Motion::Move { relative }) => {
                        assert!((relative.turn_deg - 12.0).abs() < 1e-9 && relative.forward.abs() < 1e-12)
                    }
                    other => panic!("{other:?}"),
                }
            }
            assert!((ds.stamps[1] - ds.stamps[0] - 0.3).abs() < 1e-6);
            assert!(ds.image_path(2).display().to_string().contains(topic));
        }
    }

    #[test]
    fn camera_bags_without_one_image_topic_are_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path();
        let (c, m) = recording(Wire::Ros1);
        write_ros1(&p.join("run.bag"), &c, m.clone(), Ros1Compression::None, 1 << 12).unwrap();
        rig(p, "run.bag", None);
        let e = Dataset::open(p).unwrap_err().to_string();
        assert!(
            e.contains("run.bag") && e.contains("2 topics") && e.contains("image_topic"),
            "{e}"
        );
        // No image topic at all.
        let odom_only: Vec<OutMessage> = m.into_iter().filter(|m| m.connection == 2).collect();
        write_ros1(
            &p.join("odom.bag"),
            &c[2..],
            odom_only.into_iter().map(|m| OutMessage { connection: 0, ..m }),
            Ros1Compression::None,
            1 << 12,
        )
        .unwrap();
        rig(p, "odom.bag", None);
        let e = Dataset::open(p).unwrap_err().to_string();
        assert!(
            e.contains("odom.bag") && e.contains("no sensor_msgs/Image"),
            "{e}"
        );
        // Images of another size than the calibration's.
        rig(p, "run.bag", Some("/camera/image_raw"));
        std::fs::write(
            p.join("camera_info.yaml"),
            CALIBRATION.replace("image_width: 16", "image_width: 32"),
        )
        .unwrap();
        let e = Dataset::open(p).unwrap_err().to_string();
        assert!(
            e.contains("camera_info.yaml") && e.contains("32x12") && e.contains("16x12"),
            "{e}"
        );
    }
}
