//! The few messages a laser map needs, decoded from ROS 1 serialisation
//! (packed little-endian, `u32` lengths) or from CDR (ROS 2: an
//! encapsulation header, then each value aligned to its size relative to
//! the payload, strings with their terminating NUL).
//!
//! Written here rather than taken from a crate: the messages are three
//! fixed layouts, and no maintained crate reads both serialisations
//! without generated code for each message type.

use pirouette_geom::Pose2;

/// How a bag serialises its messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wire {
    /// ROS 1.
    Ros1,
    /// CDR (ROS 2); the byte order is read from each message.
    Cdr,
}

/// The longest string or array read from a message.
const MAX_ITEMS: usize = 1 << 24;

/// A cursor over one message's bytes.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
    /// Where alignment counts from (CDR: after the encapsulation header).
    origin: usize,
    align: bool,
    big_endian: bool,
}

impl<'a> Cursor<'a> {
    fn new(bytes: &'a [u8], wire: Wire) -> Result<Self, String> {
        match wire {
            Wire::Ros1 => Ok(Self {
                bytes,
                at: 0,
                origin: 0,
                align: false,
                big_endian: false,
            }),
            Wire::Cdr => {
                let head = bytes.get(..4).ok_or("a CDR message shorter than its header")?;
                let big_endian = match head[1] {
                    0 => true,
                    1 => false,
                    k => return Err(format!("CDR representation {k} (known: 0, 1)")),
                };
                Ok(Self {
                    bytes,
                    at: 4,
                    origin: 4,
                    align: true,
                    big_endian,
                })
            }
        }
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        if self.align {
            let rel = self.at - self.origin;
            self.at += (n - rel % n) % n;
        }
        let out = self
            .bytes
            .get(self.at..self.at + n)
            .ok_or("the message is cut short")?;
        self.at += n;
        Ok(out)
    }

    fn u32(&mut self) -> Result<u32, String> {
        let b: [u8; 4] = self.take(4)?.try_into().map_err(|_| "4 bytes")?;
        Ok(if self.big_endian {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        })
    }

    fn f32(&mut self) -> Result<f32, String> {
        self.u32().map(f32::from_bits)
    }

    fn f64(&mut self) -> Result<f64, String> {
        let b: [u8; 8] = self.take(8)?.try_into().map_err(|_| "8 bytes")?;
        Ok(f64::from_bits(if self.big_endian {
            u64::from_be_bytes(b)
        } else {
            u64::from_le_bytes(b)
        }))
    }

    fn count(&mut self) -> Result<usize, String> {
        let n = self.u32()? as usize;
        if n > MAX_ITEMS || n > self.bytes.len() {
            return Err(format!(
                "a length of {n} in a message of {} bytes",
                self.bytes.len()
            ));
        }
        Ok(n)
    }

    fn string(&mut self) -> Result<String, String> {
        let n = self.count()?;
        let at = self.at;
        let raw = self
            .bytes
            .get(at..at + n)
            .ok_or("a string runs past the message")?;
        self.at += n;
        let text = if self.align {
            raw.strip_suffix(&[0]).unwrap_or(raw)
        } else {
            raw
        };
        String::from_utf8(text.to_vec()).map_err(|_| "a string that is not UTF-8".into())
    }

    /// A header's stamp (nanoseconds) and frame.
    fn header(&mut self) -> Result<(i64, String), String> {
        if !self.align {
            self.u32()?; // seq
        }
        let sec = self.u32()?;
        let nsec = self.u32()?;
        // ROS 1 times are unsigned, ROS 2 seconds signed.
        let sec = if self.align {
            i64::from(sec as i32)
        } else {
            i64::from(sec)
        };
        if nsec >= 1_000_000_000 {
            return Err(format!("a stamp with {nsec} nanoseconds"));
        }
        let frame = self.string()?;
        Ok((sec * 1_000_000_000 + i64::from(nsec), frame))
    }

    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }

    /// A `uint8[]`: its length, then the bytes as they are.
    fn byte_array(&mut self) -> Result<&'a [u8], String> {
        let n = self.count()?;
        let at = self.at;
        let raw = self
            .bytes
            .get(at..at + n)
            .ok_or("a byte array runs past the message")?;
        self.at += n;
        Ok(raw)
    }

    fn f32s(&mut self) -> Result<Vec<f32>, String> {
        let n = self.count()?;
        (0..n).map(|_| self.f32()).collect()
    }

    /// A pose (position, orientation) as planar.
    fn pose(&mut self) -> Result<Pose2, String> {
        let (x, y, _z) = (self.f64()?, self.f64()?, self.f64()?);
        let (qx, qy, qz, qw) = (self.f64()?, self.f64()?, self.f64()?, self.f64()?);
        planar(x, y, qx, qy, qz, qw)
    }
}

/// The planar part of a 3D pose, checked.
fn planar(x: f64, y: f64, qx: f64, qy: f64, qz: f64, qw: f64) -> Result<Pose2, String> {
    let norm = (qx * qx + qy * qy + qz * qz + qw * qw).sqrt();
    if !(x.is_finite() && y.is_finite() && x.abs() < 1e6 && y.abs() < 1e6 && (0.5..=2.0).contains(&norm)) {
        return Err(format!(
            "a pose ({x}, {y}) or orientation ({qx}, {qy}, {qz}, {qw}) that is not a robot's"
        ));
    }
    let yaw = (2.0 * (qw * qz + qx * qy)).atan2(1.0 - 2.0 * (qy * qy + qz * qz));
    Ok(Pose2::new(x, y, yaw))
}

/// A `sensor_msgs/LaserScan`.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanMsg {
    /// Header stamp, nanoseconds.
    pub stamp_ns: i64,
    /// The laser's frame.
    pub frame: String,
    /// Bearing of the first beam, radians.
    pub angle_min: f32,
    /// Bearing of the last beam, radians.
    pub angle_max: f32,
    /// Angle between beams, radians.
    pub angle_increment: f32,
    /// Readings below this are not ranges, metres.
    pub range_min: f32,
    /// Readings above this are no return, metres.
    pub range_max: f32,
    /// The readings.
    pub ranges: Vec<f32>,
}

/// Decodes a `sensor_msgs/LaserScan`.
pub fn laser_scan(bytes: &[u8], wire: Wire) -> Result<ScanMsg, String> {
    let mut c = Cursor::new(bytes, wire)?;
    let (stamp_ns, frame) = c.header()?;
    let angle_min = c.f32()?;
    let angle_max = c.f32()?;
    let angle_increment = c.f32()?;
    let _time_increment = c.f32()?;
    let _scan_time = c.f32()?;
    let range_min = c.f32()?;
    let range_max = c.f32()?;
    let ranges = c.f32s()?;
    Ok(ScanMsg {
        stamp_ns,
        frame,
        angle_min,
        angle_max,
        angle_increment,
        range_min,
        range_max,
        ranges,
    })
}

/// A pose of `child` in `parent` at a time: an odometry message or a
/// transform.
#[derive(Debug, Clone, PartialEq)]
pub struct FramePose {
    /// Stamp, nanoseconds.
    pub stamp_ns: i64,
    /// The frame it is given in.
    pub parent: String,
    /// The frame it places.
    pub child: String,
    /// `parent_from_child`, planar.
    pub pose: Pose2,
}

/// Decodes a `nav_msgs/Odometry` (its pose; the twist and covariances
/// are not read).
pub fn odometry(bytes: &[u8], wire: Wire) -> Result<FramePose, String> {
    let mut c = Cursor::new(bytes, wire)?;
    let (stamp_ns, parent) = c.header()?;
    let child = c.string()?;
    let pose = c.pose()?;
    Ok(FramePose {
        stamp_ns,
        parent,
        child,
        pose,
    })
}

/// Decodes a `tf2_msgs/TFMessage` (or ROS 1's `tf/tfMessage`): its
/// transforms.
pub fn transforms(bytes: &[u8], wire: Wire) -> Result<Vec<FramePose>, String> {
    let mut c = Cursor::new(bytes, wire)?;
    let n = c.count()?;
    let mut out = Vec::with_capacity(n.min(64));
    for _ in 0..n {
        let (stamp_ns, parent) = c.header()?;
        let child = c.string()?;
        let pose = c.pose()?;
        out.push(FramePose {
            stamp_ns,
            parent,
            child,
            pose,
        });
    }
    Ok(out)
}

/// The header of a `sensor_msgs/Image` or `sensor_msgs/CompressedImage`:
/// its stamp (nanoseconds) and frame, without reading the pixels.
pub fn image_header(bytes: &[u8], wire: Wire) -> Result<(i64, String), String> {
    Cursor::new(bytes, wire)?.header()
}

/// The largest image side a camera message may have, pixels.
const MAX_IMAGE_SIDE: u32 = 8192;

/// Decodes a `sensor_msgs/Image` (encodings `rgb8`, `bgr8`, `rgba8`,
/// `bgra8`, `mono8`) into 8-bit RGB.
pub fn image(bytes: &[u8], wire: Wire) -> Result<image::RgbImage, String> {
    let mut c = Cursor::new(bytes, wire)?;
    c.header()?;
    let height = c.u32()?;
    let width = c.u32()?;
    let encoding = c.string()?;
    let _big_endian = c.u8()?;
    let step = c.u32()? as usize;
    let data = c.byte_array()?;
    if width == 0 || height == 0 || width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
        return Err(format!("an image of {width}x{height} pixels"));
    }
    let channels = match encoding.as_str() {
        "rgb8" | "bgr8" => 3,
        "rgba8" | "bgra8" => 4,
        "mono8" | "8UC1" => 1,
        other => {
            return Err(format!(
                "image encoding `{other}` (read: rgb8, bgr8, rgba8, bgra8, mono8)"
            ))
        }
    };
    let (w, h) = (width as usize, height as usize);
    if step < w * channels || data.len() < step * (h - 1) + w * channels {
        return Err(format!(
            "{} bytes of data for a {width}x{height} {encoding} image with rows of {step} bytes",
            data.len()
        ));
    }
    let swap = encoding.starts_with("bgr");
    Ok(image::RgbImage::from_fn(width, height, |u, v| {
        let at = v as usize * step + u as usize * channels;
        let px = &data[at..at + channels];
        image::Rgb(match (channels, swap) {
            (1, _) => [px[0]; 3],
            (_, true) => [px[2], px[1], px[0]],
            _ => [px[0], px[1], px[2]],
        })
    }))
}

/// Decodes a `sensor_msgs/CompressedImage` (JPEG or PNG) into 8-bit RGB.
pub fn compressed_image(bytes: &[u8], wire: Wire) -> Result<image::RgbImage, String> {
    let mut c = Cursor::new(bytes, wire)?;
    c.header()?;
    let format = c.string()?;
    let data = c.byte_array()?;
    let kind = image::guess_format(data).map_err(|e| format!("compressed image ({format}): {e}"))?;
    if !matches!(kind, image::ImageFormat::Jpeg | image::ImageFormat::Png) {
        return Err(format!("compressed image of {kind:?} (read: JPEG, PNG)"));
    }
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(data), kind);
    reader.limits({
        let mut l = image::Limits::default();
        l.max_image_width = Some(MAX_IMAGE_SIDE);
        l.max_image_height = Some(MAX_IMAGE_SIDE);
        l
    });
    Ok(reader
        .decode()
        .map_err(|e| format!("compressed image ({format}): {e}"))?
        .into_rgb8())
}

/// Encoders of the same messages, for tests and for writing bags.
pub mod encode {
    use super::{FramePose, ScanMsg, Wire};

    /// A `sensor_msgs/Image` of `rgb8` pixels.
    pub fn image(stamp_ns: i64, frame: &str, img: &image::RgbImage, wire: Wire) -> Vec<u8> {
        let mut w = Writer::new(wire);
        w.header(stamp_ns, frame);
        w.u32(img.height());
        w.u32(img.width());
        w.string("rgb8");
        w.buf.push(0);
        w.u32(img.width() * 3);
        w.u32(img.as_raw().len() as u32);
        w.buf.extend_from_slice(img.as_raw());
        w.finish()
    }

    /// A `sensor_msgs/CompressedImage` of `png` bytes.
    pub fn compressed_image(stamp_ns: i64, frame: &str, png: &[u8], wire: Wire) -> Vec<u8> {
        let mut w = Writer::new(wire);
        w.header(stamp_ns, frame);
        w.string("png");
        w.u32(png.len() as u32);
        w.buf.extend_from_slice(png);
        w.finish()
    }

    /// A message being written.
    pub struct Writer {
        buf: Vec<u8>,
        align: bool,
    }

    impl Writer {
        /// An empty message (CDR: little-endian, with its header).
        pub fn new(wire: Wire) -> Self {
            match wire {
                Wire::Ros1 => Self {
                    buf: Vec::new(),
                    align: false,
                },
                Wire::Cdr => Self {
                    buf: vec![0, 1, 0, 0],
                    align: true,
                },
            }
        }

        fn pad(&mut self, n: usize) {
            if self.align {
                while (self.buf.len() - 4) % n != 0 {
                    self.buf.push(0);
                }
            }
        }

        fn u32(&mut self, v: u32) {
            self.pad(4);
            self.buf.extend_from_slice(&v.to_le_bytes());
        }

        fn f32(&mut self, v: f32) {
            self.u32(v.to_bits());
        }

        fn f64(&mut self, v: f64) {
            self.pad(8);
            self.buf.extend_from_slice(&v.to_le_bytes());
        }

        fn string(&mut self, s: &str) {
            let nul = usize::from(self.align);
            self.u32((s.len() + nul) as u32);
            self.buf.extend_from_slice(s.as_bytes());
            if self.align {
                self.buf.push(0);
            }
        }

        fn header(&mut self, stamp_ns: i64, frame: &str) {
            if !self.align {
                self.u32(0);
            }
            self.u32(stamp_ns.div_euclid(1_000_000_000) as u32);
            self.u32(stamp_ns.rem_euclid(1_000_000_000) as u32);
            self.string(frame);
        }

        fn pose(&mut self, p: &pirouette_geom::Pose2) {
            for v in [
                p.x,
                p.y,
                0.0,
                0.0,
                0.0,
                (p.theta / 2.0).sin(),
                (p.theta / 2.0).cos(),
            ] {
                self.f64(v);
            }
        }

        /// The bytes.
        pub fn finish(self) -> Vec<u8> {
            self.buf
        }
    }

    /// A `sensor_msgs/LaserScan`.
    pub fn laser_scan(m: &ScanMsg, wire: Wire) -> Vec<u8> {
        let mut w = Writer::new(wire);
        w.header(m.stamp_ns, &m.frame);
        for v in [
            m.angle_min,
            m.angle_max,
            m.angle_increment,
            0.0,
            0.0,
            m.range_min,
            m.range_max,
        ] {
            w.f32(v);
        }
        w.u32(m.ranges.len() as u32);
        for &r in &m.ranges {
            w.f32(r);
        }
        w.u32(0);
        w.finish()
    }

    /// A `nav_msgs/Odometry` (zero twist and covariances).
    pub fn odometry(m: &FramePose, wire: Wire) -> Vec<u8> {
        let mut w = Writer::new(wire);
        w.header(m.stamp_ns, &m.parent);
        w.string(&m.child);
        w.pose(&m.pose);
        for _ in 0..36 {
            w.f64(0.0);
        }
        for _ in 0..6 + 36 {
            w.f64(0.0);
        }
        w.finish()
    }

    /// A `tf2_msgs/TFMessage`.
    pub fn transforms(ts: &[FramePose], wire: Wire) -> Vec<u8> {
        let mut w = Writer::new(wire);
        w.u32(ts.len() as u32);
        for t in ts {
            w.header(t.stamp_ns, &t.parent);
            w.string(&t.child);
            w.pose(&t.pose);
        }
        w.finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_read_back_in_both_serialisations() {
        let scan = ScanMsg {
            stamp_ns: 1_500_000_123,
            frame: "laser".into(),
            angle_min: -1.5,
            angle_max: 1.5,
            angle_increment: 1.0,
            range_min: 0.1,
            range_max: 30.0,
            ranges: vec![1.0, f32::INFINITY, 2.5, 0.0],
        };
        let odom = FramePose {
            stamp_ns: 7,
            parent: "odom".into(),
            child: "base_link".into(),
            pose: Pose2::new(1.0, -2.0, 0.75),
        };
        for wire in [Wire::Ros1, Wire::Cdr] {
            let back = laser_scan(&encode::laser_scan(&scan, wire), wire).unwrap();
            assert_eq!(back, scan);
            let o = odometry(&encode::odometry(&odom, wire), wire).unwrap();
            assert_eq!(
                (o.stamp_ns, &o.parent[..], &o.child[..]),
                (7, "odom", "base_link")
            );
            assert!((o.pose.x - 1.0).abs() < 1e-12 && (o.pose.theta - 0.75).abs() < 1e-12);
            let t = transforms(&encode::transforms(&[odom.clone(), odom.clone()], wire), wire).unwrap();
            assert_eq!(t.len(), 2);
            assert_eq!(t[1].child, "base_link");
        }
    }

    #[test]
    fn bad_messages_are_refused() {
        let bytes = encode::laser_scan(
            &ScanMsg {
                stamp_ns: 0,
                frame: "l".into(),
                angle_min: 0.0,
                angle_max: 1.0,
                angle_increment: 1.0,
                range_min: 0.0,
                range_max: 1.0,
                ranges: vec![1.0; 10],
            },
            Wire::Ros1,
        );
        assert!(laser_scan(&bytes[..bytes.len() - 8], Wire::Ros1)
            .unwrap_err()
            .contains("cut short"));
        let mut huge = bytes.clone();
        // The frame string's length.
        huge[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(laser_scan(&huge, Wire::Ros1).unwrap_err().contains("length"));
        assert!(laser_scan(&[0, 7, 0, 0], Wire::Cdr)
            .unwrap_err()
            .contains("representation"));
    }
}
