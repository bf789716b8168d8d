//! ROS bags as laser logs: ROS 1 bags ([`ros1`]), and ROS 2 bags in
//! MCAP ([`mcap`]) or sqlite3 ([`sqlite`]) storage, streamed message by
//! message into the same [`LaserScan`]s as a CARMEN log.
//!
//! - Scans: `sensor_msgs/LaserScan` (bearings `angle_min + i·increment`;
//!   NaN, ±∞ and readings above `range_max` are no return, readings below
//!   `range_min` are not ranges).
//! - Motion: `nav_msgs/Odometry`, or where a bag has none the `/tf`
//!   transform from the odometry frame to the robot's base, interpolated
//!   at each scan's header stamp.
//! - The laser's mount on the robot: `/tf_static` (the laser frame's
//!   chain up to the base), read before the first scan; without one, the
//!   laser sits at the robot's centre. Scans and their odometry are given
//!   in the laser's frame; [`LogInfo::mount`] turns laser poses into
//!   robot poses.
//! - Topics are found by type where there is one of a kind; otherwise
//!   [`BagOptions`] names them.
//!
//! Skips, each counted in [`LogInfo::skipped`]: scans and odometry stamped
//! before the previous one of their topic, and transforms of other frames.
//! Everything else that is wrong is an error naming the file, and the
//! topic or byte offset.

pub mod camera;
pub mod mcap;
pub mod ros1;
pub mod sqlite;
pub mod wire;
pub mod write;

use crate::carmen::{CarmenReader, LaserScan, OdometrySource, MAX_BEAMS};
use crate::IoError;
use pirouette_geom::Pose2;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use wire::{FramePose, Wire};

/// A topic of a bag (a ROS 1 connection, a ROS 2 topic or channel).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Connection {
    /// The topic's name.
    pub topic: String,
    /// Its message type, ROS 1 style (`sensor_msgs/LaserScan`; ROS 2's
    /// `/msg/` dropped).
    pub msg_type: String,
}

impl Connection {
    /// A topic, its type's name made ROS 1 style.
    pub fn new(topic: String, msg_type: &str) -> Self {
        Self {
            topic,
            msg_type: msg_type.replace("/msg/", "/"),
        }
    }
}

/// One message as a bag stores it.
#[derive(Debug, Clone)]
pub struct RawMessage {
    /// Its connection (an index into [`MessageSource::connections`]).
    pub connection: usize,
    /// The time it was logged, nanoseconds.
    pub log_time_ns: u64,
    /// Its serialised bytes.
    pub data: Vec<u8>,
    /// Where it is in the file (the chunk's offset, or a row id).
    pub offset: u64,
}

/// A bag read message by message.
pub trait MessageSource {
    /// Every topic of the bag.
    fn connections(&self) -> &[Connection];
    /// What kind of bag.
    fn format(&self) -> &'static str;
    /// How its messages are serialised.
    fn wire(&self) -> Wire;
    /// The next message in the bag's order; `None` at the end. After an
    /// error the reader is not asked again ([`BagScans`] stops).
    fn next_message(&mut self) -> Result<Option<RawMessage>, IoError>;
    /// Damage read past so far, one line each naming the file (a ROS 1
    /// bag cut short, chunks skipped).
    fn warnings(&self) -> Vec<String> {
        Vec::new()
    }
}

/// Which topics to read where a bag has several of a kind.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct BagOptions {
    /// The `sensor_msgs/LaserScan` topic.
    pub scan_topic: Option<String>,
    /// The `nav_msgs/Odometry` topic.
    pub odom_topic: Option<String>,
}

/// What a laser log's reader found.
#[derive(Debug, Clone, PartialEq)]
pub struct LogInfo {
    /// The kind of file.
    pub format: &'static str,
    /// The scans' topic (bags).
    pub scan_topic: Option<String>,
    /// Where the motion comes from (bags: a topic, `/tf` or nothing).
    pub motion: Option<String>,
    /// The laser on the robot, `robot_from_laser`.
    pub mount: Pose2,
    /// Messages skipped, and why.
    pub skipped: Vec<(String, usize)>,
    /// Damage read past (a bag cut short, chunks skipped), one line each.
    pub warnings: Vec<String>,
}

/// The most transforms kept from `/tf_static`.
const MAX_STATIC: usize = 10_000;
/// Odometry serves a scan this far beyond its first or last sample,
/// nanoseconds.
const ODOM_SLACK_NS: i64 = 200_000_000;
/// Scans wait for odometry past their stamp at most this many at once
/// (beyond, the oldest goes with what there is).
const MAX_PENDING: usize = 1_000;

/// Where motion is read.
#[derive(Debug, Clone, PartialEq)]
enum Motion {
    /// `nav_msgs/Odometry` messages on these connections.
    Odometry(Vec<bool>),
    /// `/tf` transforms on these connections; the base frame once known.
    Tf(Vec<bool>),
    None,
}

/// The scans of a bag, each with the odometry since the previous one.
pub struct BagScans {
    path: PathBuf,
    source: Box<dyn MessageSource>,
    wire: Wire,
    scan_topic: String,
    scans_on: Vec<bool>,
    statics_on: Vec<bool>,
    motion: Motion,
    /// The odometry's frames (`parent`, `child`), fixed by the first
    /// message used.
    frames: Option<(String, String)>,
    statics: Vec<FramePose>,
    mount: Option<Pose2>,
    /// Recent odometry, by stamp.
    odom: VecDeque<(i64, Pose2)>,
    pending: VecDeque<(usize, wire::ScanMsg)>,
    ready: VecDeque<LaserScan>,
    last_scan_stamp: Option<i64>,
    previous_odom: Option<Pose2>,
    scan_messages: usize,
    skipped_scans: usize,
    skipped_odom: usize,
    done: bool,
    failed: bool,
}

/// The connections of `source` carrying `types`, as flags.
fn flags(source: &dyn MessageSource, pick: impl Fn(&Connection) -> bool) -> Vec<bool> {
    source.connections().iter().map(pick).collect()
}

/// The topics of a kind, by name, each once.
fn topics_of(source: &dyn MessageSource, types: &[&str]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for c in source.connections() {
        if types.contains(&c.msg_type.as_str()) && !out.contains(&c.topic) {
            out.push(c.topic.clone());
        }
    }
    out
}

const SCAN_TYPES: [&str; 1] = ["sensor_msgs/LaserScan"];
const ODOM_TYPES: [&str; 1] = ["nav_msgs/Odometry"];
pub(crate) const TF_TYPES: [&str; 2] = ["tf2_msgs/TFMessage", "tf/tfMessage"];

/// The one topic of a kind, or the one asked for (checked).
fn choose(
    path: &Path,
    source: &dyn MessageSource,
    asked: Option<&str>,
    types: &[&str],
    flag: &str,
) -> Result<Option<String>, IoError> {
    let found = topics_of(source, types);
    if let Some(topic) = asked {
        let Some(c) = source.connections().iter().find(|c| c.topic == topic) else {
            let all: Vec<&str> = source.connections().iter().map(|c| c.topic.as_str()).collect();
            return Err(IoError::invalid(
                path,
                format!("no topic `{topic}` in the bag (it has {})", all.join(", ")),
            ));
        };
        if !types.contains(&c.msg_type.as_str()) {
            return Err(IoError::invalid(
                path,
                format!(
                    "topic `{topic}` carries {}, not {}",
                    c.msg_type,
                    types.join(" or ")
                ),
            ));
        }
        return Ok(Some(topic.to_owned()));
    }
    match found.len() {
        0 | 1 => Ok(found.into_iter().next()),
        _ => Err(IoError::invalid(
            path,
            format!(
                "{} topics carry {} ({}): choose one with {flag}",
                found.len(),
                types[0],
                found.join(", ")
            ),
        )),
    }
}

impl BagScans {
    /// Reads the scans of `source`, the bag at `path`.
    pub fn new(path: &Path, source: Box<dyn MessageSource>, options: &BagOptions) -> Result<Self, IoError> {
        let s = source.as_ref();
        let Some(scan_topic) = choose(
            path,
            s,
            options.scan_topic.as_deref(),
            &SCAN_TYPES,
            "--scan-topic",
        )?
        else {
            let all: Vec<String> = (s.connections().iter())
                .map(|c| format!("{} ({})", c.topic, c.msg_type))
                .collect();
            let camera = !topics_of(s, &["sensor_msgs/Image", "sensor_msgs/CompressedImage"]).is_empty();
            let hint = if camera {
                ": a camera bag is read through a rig file that names it (docs/image-folders.md)"
            } else {
                ""
            };
            return Err(IoError::invalid(
                path,
                format!(
                    "no sensor_msgs/LaserScan topic in the bag (it has {}){hint}",
                    all.join(", ")
                ),
            ));
        };
        let motion = match choose(
            path,
            s,
            options.odom_topic.as_deref(),
            &ODOM_TYPES,
            "--odom-topic",
        )? {
            Some(t) => Motion::Odometry(flags(s, |c| c.topic == t)),
            None => {
                let tf = flags(s, |c| c.topic == "/tf" && TF_TYPES.contains(&c.msg_type.as_str()));
                if tf.iter().any(|&b| b) {
                    Motion::Tf(tf)
                } else {
                    Motion::None
                }
            }
        };
        Ok(Self {
            path: path.to_owned(),
            wire: s.wire(),
            scans_on: flags(s, |c| c.topic == scan_topic),
            statics_on: flags(s, |c| {
                c.topic == "/tf_static" && TF_TYPES.contains(&c.msg_type.as_str())
            }),
            scan_topic,
            motion,
            frames: None,
            statics: Vec::new(),
            mount: None,
            odom: VecDeque::new(),
            pending: VecDeque::new(),
            ready: VecDeque::new(),
            last_scan_stamp: None,
            previous_odom: None,
            scan_messages: 0,
            skipped_scans: 0,
            skipped_odom: 0,
            done: false,
            failed: false,
            source,
        })
    }

    /// What the reader found so far.
    pub fn info(&self) -> LogInfo {
        let motion = match &self.motion {
            Motion::Odometry(on) => (self.source.connections().iter().zip(on))
                .find(|(_, &b)| b)
                .map(|(c, _)| c.topic.clone()),
            Motion::Tf(_) => Some(match &self.frames {
                Some((p, c)) => format!("/tf ({p} → {c})"),
                None => "/tf".to_owned(),
            }),
            Motion::None => None,
        };
        let mut skipped = Vec::new();
        if self.skipped_scans > 0 {
            skipped.push((
                "scans stamped before the previous scan".to_owned(),
                self.skipped_scans,
            ));
        }
        if self.skipped_odom > 0 {
            skipped.push((
                "odometry stamped before the previous".to_owned(),
                self.skipped_odom,
            ));
        }
        LogInfo {
            format: self.source.format(),
            scan_topic: Some(self.scan_topic.clone()),
            motion,
            mount: self.mount.unwrap_or(Pose2::IDENTITY),
            skipped,
            warnings: self.source.warnings(),
        }
    }

    fn bad(&self, topic: &str, offset: u64, problem: impl std::fmt::Display) -> IoError {
        IoError::invalid(
            &self.path,
            format!("topic {topic}, message at byte {offset} (sqlite3: row {offset}): {problem}"),
        )
    }

    /// Takes one message; false at the end of the bag.
    fn pump(&mut self) -> Result<bool, IoError> {
        let Some(m) = self.source.next_message()? else {
            return Ok(false);
        };
        let topic = || self.source.connections()[m.connection].topic.clone();
        if self.scans_on[m.connection] {
            let scan = wire::laser_scan(&m.data, self.wire).map_err(|p| self.bad(&topic(), m.offset, p))?;
            let k = self.scan_messages;
            self.scan_messages += 1;
            if self.last_scan_stamp.is_some_and(|t| scan.stamp_ns < t) {
                self.skipped_scans += 1;
            } else {
                self.last_scan_stamp = Some(scan.stamp_ns);
                self.pending.push_back((k, scan));
            }
        } else if self.statics_on[m.connection] {
            let ts = wire::transforms(&m.data, self.wire).map_err(|p| self.bad(&topic(), m.offset, p))?;
            for t in ts {
                if self.statics.len() < MAX_STATIC {
                    self.statics.push(t);
                }
            }
        } else {
            let poses = match &self.motion {
                Motion::Odometry(on) if on[m.connection] => {
                    vec![wire::odometry(&m.data, self.wire).map_err(|p| self.bad(&topic(), m.offset, p))?]
                }
                Motion::Tf(on) if on[m.connection] => {
                    wire::transforms(&m.data, self.wire).map_err(|p| self.bad(&topic(), m.offset, p))?
                }
                _ => Vec::new(),
            };
            for p in poses {
                self.take_odometry(p);
            }
        }
        Ok(true)
    }

    /// The base frame a `/tf` odometry should place: the parent of the
    /// laser's static chain's root, or a conventional name.
    fn is_base(&self, frame: &str) -> bool {
        let mounted = self.statics.iter().any(|s| s.parent == frame);
        mounted || (self.statics.is_empty() && matches!(frame, "base_link" | "base_footprint"))
    }

    fn take_odometry(&mut self, p: FramePose) {
        match &self.frames {
            Some((parent, child)) if *parent != p.parent || *child != p.child => return,
            Some(_) => {}
            None => {
                if matches!(self.motion, Motion::Tf(_)) && !self.is_base(&p.child) {
                    return;
                }
                self.frames = Some((p.parent.clone(), p.child.clone()));
            }
        }
        if self.odom.back().is_some_and(|&(t, _)| p.stamp_ns < t) {
            self.skipped_odom += 1;
            return;
        }
        self.odom.push_back((p.stamp_ns, p.pose));
    }

    /// The odometry pose at `t`: interpolated between the samples about
    /// it, or the nearest end's within [`ODOM_SLACK_NS`].
    fn odometry_at(&self, t: i64) -> Option<Pose2> {
        let i = self.odom.partition_point(|&(s, _)| s < t);
        match (i.checked_sub(1).map(|j| self.odom[j]), self.odom.get(i).copied()) {
            (Some((ta, a)), Some((tb, b))) => {
                let f = if tb > ta {
                    (t - ta) as f64 / (tb - ta) as f64
                } else {
                    0.0
                };
                let d = a.between(&b);
                Some(a * Pose2::new(d.x * f, d.y * f, d.theta * f))
            }
            (Some((ta, a)), None) => (t - ta <= ODOM_SLACK_NS).then_some(a),
            (None, Some((tb, b))) => (tb - t <= ODOM_SLACK_NS).then_some(b),
            (None, None) => None,
        }
    }

    /// The laser's mount: its frame's static chain up to the base.
    fn find_mount(&self, laser_frame: &str) -> Pose2 {
        let mut pose = Pose2::IDENTITY;
        let mut frame = laser_frame.to_owned();
        let base = self.frames.as_ref().map(|(_, c)| c.clone());
        for _ in 0..16 {
            if Some(&frame) == base.as_ref() {
                break;
            }
            let Some(s) = self.statics.iter().find(|s| s.child == frame) else {
                break;
            };
            pose = s.pose * pose;
            frame = s.parent.clone();
        }
        pose
    }

    /// Turns the oldest waiting scan into a [`LaserScan`].
    fn emit(&mut self) -> Result<(), IoError> {
        let Some((k, msg)) = self.pending.pop_front() else {
            return Ok(());
        };
        let mount = match self.mount {
            Some(m) => m,
            None => {
                let m = self.find_mount(&msg.frame);
                self.mount = Some(m);
                m
            }
        };
        let odom = self.odometry_at(msg.stamp_ns);
        let odometry = match (self.previous_odom, odom) {
            (Some(a), Some(b)) => Some(mount.inverse() * a.between(&b) * mount),
            _ => None,
        };
        self.previous_odom = odom;
        // Samples older than the one before this stamp are no longer needed.
        while self.odom.len() > 2 && self.odom[1].0 <= msg.stamp_ns {
            self.odom.pop_front();
        }
        let scan = self.laser_scan(k, msg, odom.map(|o| o * mount), odometry)?;
        self.ready.push_back(scan);
        Ok(())
    }

    fn laser_scan(
        &self,
        k: usize,
        m: wire::ScanMsg,
        recorded: Option<Pose2>,
        odometry: Option<Pose2>,
    ) -> Result<LaserScan, IoError> {
        let n = m.ranges.len();
        let inc = f64::from(m.angle_increment);
        let (min, max) = (f64::from(m.angle_min), f64::from(m.angle_max));
        let bad = |p: String| {
            IoError::invalid(
                &self.path,
                format!("topic {}, scan message {k}: {p}", self.scan_topic),
            )
        };
        if !(2..=MAX_BEAMS).contains(&n) {
            return Err(bad(format!("{n} ranges (2 to {MAX_BEAMS} are read)")));
        }
        let tau = std::f64::consts::TAU;
        let span = inc * (n - 1) as f64;
        if !(inc.is_finite()
            && inc != 0.0
            && min.abs() <= tau
            && max.abs() <= tau
            && span.abs() <= tau + 1e-3)
            || (min + span - max).abs() > 1.01 * inc.abs() + 1e-6
        {
            return Err(bad(format!(
                "its ranges and angles disagree: {n} ranges from {min} to {max} rad every {inc} rad"
            )));
        }
        let (lo, hi) = (m.range_min.max(0.0), m.range_max);
        let mut ranges: Vec<f32> = (m.ranges.iter())
            .map(|&r| {
                if !r.is_finite() || r > hi {
                    f32::INFINITY
                } else if r < lo {
                    f32::NAN
                } else {
                    r
                }
            })
            .collect();
        let (first, step) = if inc > 0.0 {
            (min, inc)
        } else {
            ranges.reverse();
            (min + span, -inc)
        };
        Ok(LaserScan {
            scan: k,
            line: 0,
            t: m.stamp_ns as f64 * 1e-9,
            first_bearing_rad: first,
            beam_step_rad: step,
            ranges_m: ranges,
            recorded: recorded.unwrap_or(Pose2::IDENTITY),
            odometry,
            odometry_source: odometry.map(|_| OdometrySource::Bag),
        })
    }

    fn next_scan(&mut self) -> Result<Option<LaserScan>, IoError> {
        loop {
            if let Some(s) = self.ready.pop_front() {
                return Ok(Some(s));
            }
            // The oldest waiting scan goes once odometry passed its stamp
            // (or there is none to wait for).
            let newest = self.odom.back().map(|&(t, _)| t);
            if let Some((_, m)) = self.pending.front() {
                let covered = newest.is_some_and(|t| t >= m.stamp_ns) || self.motion == Motion::None;
                if covered || self.done || self.pending.len() > MAX_PENDING {
                    self.emit()?;
                    continue;
                }
            }
            if self.done {
                return Ok(None);
            }
            if !self.pump()? {
                self.done = true;
            }
        }
    }
}

impl Iterator for BagScans {
    type Item = Result<LaserScan, IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        let next = self.next_scan().transpose();
        if matches!(next, Some(Err(_))) {
            self.failed = true;
        }
        next
    }
}

/// A laser log of any kind the engine reads, scan by scan.
pub enum LaserLog {
    /// A CARMEN text log.
    Carmen(Box<CarmenReader<std::io::BufReader<std::fs::File>>>),
    /// A ROS bag.
    Bag(Box<BagScans>),
}

impl LaserLog {
    /// What the reader found so far (complete once it has been read).
    pub fn info(&self) -> LogInfo {
        match self {
            LaserLog::Carmen(_) => LogInfo {
                format: "CARMEN log",
                scan_topic: None,
                motion: None,
                mount: Pose2::IDENTITY,
                skipped: Vec::new(),
                warnings: Vec::new(),
            },
            LaserLog::Bag(b) => b.info(),
        }
    }
}

impl Iterator for LaserLog {
    type Item = Result<LaserScan, IoError>;

    fn next(&mut self) -> Option<Self::Item> {
        match self {
            LaserLog::Carmen(r) => r.next(),
            LaserLog::Bag(b) => b.next(),
        }
    }
}

/// The kinds of laser input, told by name and first bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogKind {
    /// CARMEN text.
    Carmen,
    /// A ROS 1 bag.
    Ros1,
    /// A ROS 2 bag's MCAP storage file.
    Mcap,
    /// A ROS 2 bag's sqlite3 storage file.
    Sqlite,
}

/// What kind of laser input `path` is; a folder is a ROS 2 bag (its
/// storage file is found through `metadata.yaml`).
pub fn log_kind(path: &Path) -> Result<(LogKind, PathBuf), IoError> {
    let file = if path.is_dir() {
        ros2_storage_file(path)?
    } else {
        path.to_owned()
    };
    let mut head = [0u8; 16];
    let n = {
        use std::io::Read;
        let mut f = std::fs::File::open(&file).map_err(|e| IoError::io(&file, e))?;
        let mut n = 0;
        while n < head.len() {
            match f.read(&mut head[n..]).map_err(|e| IoError::io(&file, e))? {
                0 => break,
                k => n += k,
            }
        }
        n
    };
    let head = &head[..n];
    let kind = if head.starts_with(b"#ROSBAG") {
        LogKind::Ros1
    } else if head.starts_with(mcap::MAGIC) {
        LogKind::Mcap
    } else if head.starts_with(b"SQLite format 3\0") {
        LogKind::Sqlite
    } else {
        LogKind::Carmen
    };
    Ok((kind, file))
}

/// The storage file of a ROS 2 bag folder, from its `metadata.yaml`
/// (`relative_file_paths`; one file is read).
fn ros2_storage_file(dir: &Path) -> Result<PathBuf, IoError> {
    let meta = dir.join("metadata.yaml");
    let text = std::fs::read_to_string(&meta).map_err(|e| IoError::io(&meta, e))?;
    let mut files = Vec::new();
    let mut in_list = false;
    for line in text.lines() {
        let t = line.trim();
        if t.starts_with("relative_file_paths:") {
            in_list = true;
            continue;
        }
        if in_list {
            if let Some(item) = t.strip_prefix("- ") {
                files.push(item.trim().trim_matches(['"', '\'']).to_owned());
                continue;
            }
            in_list = false;
        }
    }
    match files.as_slice() {
        [one] => Ok(dir.join(one)),
        [] => Err(IoError::invalid(
            &meta,
            "no storage file under `relative_file_paths`",
        )),
        many => Err(IoError::invalid(
            &meta,
            format!(
                "{} storage files ({}): split bags are not read; give one storage file",
                many.len(),
                many.join(", ")
            ),
        )),
    }
}

/// Opens a laser log: a CARMEN log, a ROS 1 bag, a ROS 2 bag folder or
/// its MCAP or sqlite3 storage file.
pub fn open_laser_log(path: &Path, options: &BagOptions) -> Result<LaserLog, IoError> {
    if !path.is_dir() && !path.exists() {
        return Err(IoError::io(
            path,
            std::io::Error::from(std::io::ErrorKind::NotFound),
        ));
    }
    let (kind, file) = log_kind(path)?;
    if kind == LogKind::Carmen {
        if *options != BagOptions::default() {
            return Err(IoError::invalid(path, "a CARMEN log has no topics to choose"));
        }
        return CarmenReader::open(path).map(|r| LaserLog::Carmen(Box::new(r)));
    }
    let source = open_bag(kind, &file)?;
    Ok(LaserLog::Bag(Box::new(BagScans::new(&file, source, options)?)))
}

/// The messages of a bag of `kind` stored in `file`; `None` for a CARMEN
/// log, which is no bag.
fn open_bag(kind: LogKind, file: &Path) -> Result<Box<dyn MessageSource>, IoError> {
    Ok(match kind {
        LogKind::Carmen => {
            return Err(IoError::invalid(
                file,
                "not a ROS bag (no #ROSBAG, MCAP or SQLite header)",
            ))
        }
        LogKind::Ros1 => Box::new(ros1::Ros1Bag::open(file)?),
        LogKind::Mcap => Box::new(mcap::McapBag::open(file)?),
        LogKind::Sqlite => Box::new(sqlite::SqliteBag::open(file)?),
    })
}
