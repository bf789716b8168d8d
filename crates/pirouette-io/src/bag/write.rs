//! Writing bags: ROS 1 (chunks uncompressed, bz2 or lz4, with their
//! index), ROS 2 MCAP (zstd chunks) and ROS 2 sqlite3, each as a bag
//! folder with its `metadata.yaml` for ROS 2; and [`convert`], which
//! copies the messages a laser map reads (scans, odometry, transforms)
//! from any bag into another format. Tests use them to check that one
//! recording gives the same poses in every format.

use super::wire::{self, Wire};
use super::{log_kind, mcap as mcap_reader, ros1, sqlite, Connection, LogKind, MessageSource};
use crate::IoError;
use std::collections::BTreeMap;
use std::io::{Seek, SeekFrom, Write};
use std::path::Path;

/// A message to write: its topic (an index into the connections), log
/// time and serialised bytes.
#[derive(Debug, Clone)]
pub struct OutMessage {
    /// Index into the connections written.
    pub connection: usize,
    /// Log time, nanoseconds.
    pub time_ns: u64,
    /// The bytes, in the target format's serialisation.
    pub data: Vec<u8>,
}

/// How a ROS 1 bag's chunks are compressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ros1Compression {
    /// Stored as they are.
    None,
    /// bzip2.
    Bz2,
    /// LZ4 frames.
    Lz4,
}

impl Ros1Compression {
    fn name(self) -> &'static str {
        match self {
            Ros1Compression::None => "none",
            Ros1Compression::Bz2 => "bz2",
            Ros1Compression::Lz4 => "lz4",
        }
    }
}

/// A target format of [`convert`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BagFormat {
    /// A ROS 1 bag file.
    Ros1(Ros1Compression),
    /// A ROS 2 bag folder with MCAP storage.
    Mcap,
    /// A ROS 2 bag folder with sqlite3 storage.
    Sqlite,
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> IoError + '_ {
    move |e| IoError::io(path, e)
}

/// A ROS 1 header: `len name=value` fields.
fn ros1_header(fields: &[(&str, &[u8])]) -> Vec<u8> {
    let mut out = Vec::new();
    for (name, value) in fields {
        let len = (name.len() + 1 + value.len()) as u32;
        out.extend_from_slice(&len.to_le_bytes());
        out.extend_from_slice(name.as_bytes());
        out.push(b'=');
        out.extend_from_slice(value);
    }
    out
}

fn ros1_record(out: &mut Vec<u8>, header: &[(&str, &[u8])], data: &[u8]) {
    let h = ros1_header(header);
    out.extend_from_slice(&(h.len() as u32).to_le_bytes());
    out.extend_from_slice(&h);
    out.extend_from_slice(&(data.len() as u32).to_le_bytes());
    out.extend_from_slice(data);
}

fn ros1_time(ns: u64) -> [u8; 8] {
    let sec = (ns / 1_000_000_000) as u32;
    let nsec = (ns % 1_000_000_000) as u32;
    let mut t = [0u8; 8];
    t[..4].copy_from_slice(&sec.to_le_bytes());
    t[4..].copy_from_slice(&nsec.to_le_bytes());
    t
}

fn ros1_connection(out: &mut Vec<u8>, id: u32, c: &Connection) {
    let data = ros1_header(&[
        ("topic", c.topic.as_bytes()),
        ("type", c.msg_type.as_bytes()),
        ("md5sum", b"*"),
        ("message_definition", b""),
    ]);
    ros1_record(
        out,
        &[
            ("op", &[0x07]),
            ("conn", &id.to_le_bytes()),
            ("topic", c.topic.as_bytes()),
        ],
        &data,
    );
}

/// Writes a ROS 1 bag (format 2.0) of `messages` (in time order), chunks
/// of about `chunk_bytes`, with its index.
pub fn write_ros1(
    path: &Path,
    connections: &[Connection],
    messages: impl IntoIterator<Item = OutMessage>,
    compression: Ros1Compression,
    chunk_bytes: usize,
) -> Result<(), IoError> {
    let e = io(path);
    let mut file = std::io::BufWriter::new(std::fs::File::create(path).map_err(&e)?);
    file.write_all(ros1::MAGIC).map_err(&e)?;
    let header_at = ros1::MAGIC.len() as u64;
    // The bag header, rewritten at the end: a 4096-byte record.
    let bag_header = |index_pos: u64, chunks: u32| {
        let mut r = Vec::new();
        ros1_record(
            &mut r,
            &[
                ("op", &[0x03]),
                ("index_pos", &index_pos.to_le_bytes()),
                ("conn_count", &(connections.len() as u32).to_le_bytes()),
                ("chunk_count", &chunks.to_le_bytes()),
            ],
            &[],
        );
        // Padding in the data field.
        let pad = 4096 - r.len();
        let h_len = u32::from_le_bytes([r[0], r[1], r[2], r[3]]) as usize;
        r.truncate(4 + h_len);
        r.extend_from_slice(&(pad as u32).to_le_bytes());
        r.extend(std::iter::repeat_n(b' ', pad));
        r
    };
    file.write_all(&bag_header(0, 0)).map_err(&e)?;
    let mut pos = header_at + 4096;
    // Per chunk: position, start, end, counts per connection.
    let mut infos: Vec<(u64, u64, u64, BTreeMap<u32, u32>)> = Vec::new();
    let mut messages = messages.into_iter().peekable();
    while messages.peek().is_some() {
        let mut inner = Vec::new();
        let mut declared = vec![false; connections.len()];
        let mut index: BTreeMap<u32, Vec<(u64, u32)>> = BTreeMap::new();
        let (mut start, mut end) = (u64::MAX, 0);
        while inner.len() < chunk_bytes {
            let Some(m) = messages.next() else { break };
            let id = m.connection as u32;
            if !declared[m.connection] {
                ros1_connection(&mut inner, id, &connections[m.connection]);
                declared[m.connection] = true;
            }
            index.entry(id).or_default().push((m.time_ns, inner.len() as u32));
            ros1_record(
                &mut inner,
                &[
                    ("op", &[0x02]),
                    ("conn", &id.to_le_bytes()),
                    ("time", &ros1_time(m.time_ns)),
                ],
                &m.data,
            );
            start = start.min(m.time_ns);
            end = end.max(m.time_ns);
        }
        let data = match compression {
            Ros1Compression::None => inner.clone(),
            Ros1Compression::Bz2 => {
                let mut enc = bzip2::write::BzEncoder::new(Vec::new(), bzip2::Compression::default());
                enc.write_all(&inner).map_err(&e)?;
                enc.finish().map_err(&e)?
            }
            Ros1Compression::Lz4 => {
                let mut enc = lz4_flex::frame::FrameEncoder::new(Vec::new());
                enc.write_all(&inner).map_err(&e)?;
                enc.finish()
                    .map_err(|x| IoError::invalid(path, format!("lz4: {x}")))?
            }
        };
        let mut chunk = Vec::new();
        ros1_record(
            &mut chunk,
            &[
                ("op", &[0x05]),
                ("compression", compression.name().as_bytes()),
                ("size", &(inner.len() as u32).to_le_bytes()),
            ],
            &data,
        );
        for (id, entries) in &index {
            let mut d = Vec::new();
            for (t, off) in entries {
                d.extend_from_slice(&ros1_time(*t));
                d.extend_from_slice(&off.to_le_bytes());
            }
            ros1_record(
                &mut chunk,
                &[
                    ("op", &[0x04]),
                    ("ver", &1u32.to_le_bytes()),
                    ("conn", &id.to_le_bytes()),
                    ("count", &(entries.len() as u32).to_le_bytes()),
                ],
                &d,
            );
        }
        let counts = index.iter().map(|(id, v)| (*id, v.len() as u32)).collect();
        infos.push((pos, start, end, counts));
        file.write_all(&chunk).map_err(&e)?;
        pos += chunk.len() as u64;
    }
    let index_pos = pos;
    let mut tail = Vec::new();
    for (id, c) in connections.iter().enumerate() {
        ros1_connection(&mut tail, id as u32, c);
    }
    for (chunk_pos, start, end, counts) in &infos {
        let mut d = Vec::new();
        for (id, n) in counts {
            d.extend_from_slice(&id.to_le_bytes());
            d.extend_from_slice(&n.to_le_bytes());
        }
        ros1_record(
            &mut tail,
            &[
                ("op", &[0x06]),
                ("ver", &1u32.to_le_bytes()),
                ("chunk_pos", &chunk_pos.to_le_bytes()),
                ("start_time", &ros1_time(*start)),
                ("end_time", &ros1_time(*end)),
                ("count", &(counts.len() as u32).to_le_bytes()),
            ],
            &d,
        );
    }
    file.write_all(&tail).map_err(&e)?;
    file.seek(SeekFrom::Start(header_at)).map_err(&e)?;
    file.write_all(&bag_header(index_pos, infos.len() as u32))
        .map_err(&e)?;
    file.flush().map_err(&e)
}

/// The ROS 2 name of a type (`sensor_msgs/msg/LaserScan`).
fn ros2_type(msg_type: &str) -> String {
    match msg_type.split_once('/') {
        Some((pkg, name)) if !name.starts_with("msg/") => format!("{pkg}/msg/{name}"),
        _ => msg_type.to_owned(),
    }
}

/// Writes `metadata.yaml` naming one storage file.
fn write_metadata(dir: &Path, storage: &str, file: &str, count: usize) -> Result<(), IoError> {
    let text = format!(
        "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: {storage}\n  relative_file_paths:\n    - {file}\n  message_count: {count}\n"
    );
    crate::atomic_write(&dir.join("metadata.yaml"), text.as_bytes())
}

/// Writes a ROS 2 bag folder with MCAP storage (CDR messages).
pub fn write_mcap(
    dir: &Path,
    connections: &[Connection],
    messages: impl IntoIterator<Item = OutMessage>,
) -> Result<(), IoError> {
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let name = format!(
        "{}_0.mcap",
        dir.file_name().map_or("bag".into(), |n| n.to_string_lossy())
    );
    let path = dir.join(&name);
    let bad = |x: mcap::McapError| IoError::invalid(&path, format!("writing MCAP: {x}"));
    let file = std::io::BufWriter::new(std::fs::File::create(&path).map_err(io(&path))?);
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .create(file)
        .map_err(bad)?;
    let mut channels = Vec::new();
    for c in connections {
        let schema = w
            .add_schema(&ros2_type(&c.msg_type), "ros2msg", b"")
            .map_err(bad)?;
        channels.push(
            w.add_channel(schema, &c.topic, "cdr", &BTreeMap::new())
                .map_err(bad)?,
        );
    }
    let mut count = 0;
    for (seq, m) in messages.into_iter().enumerate() {
        let header = mcap::records::MessageHeader {
            channel_id: channels[m.connection],
            sequence: seq as u32,
            log_time: m.time_ns,
            publish_time: m.time_ns,
        };
        w.write_to_known_channel(&header, &m.data).map_err(bad)?;
        count += 1;
    }
    w.finish().map_err(bad)?;
    write_metadata(dir, "mcap", &name, count)
}

/// Writes a ROS 2 bag folder with sqlite3 storage (CDR messages).
pub fn write_sqlite(
    dir: &Path,
    connections: &[Connection],
    messages: impl IntoIterator<Item = OutMessage>,
) -> Result<(), IoError> {
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let name = format!(
        "{}_0.db3",
        dir.file_name().map_or("bag".into(), |n| n.to_string_lossy())
    );
    let path = dir.join(&name);
    let _ = std::fs::remove_file(&path);
    let bad = |x: rusqlite::Error| IoError::invalid(&path, format!("writing sqlite3: {x}"));
    let mut db = rusqlite::Connection::open(&path).map_err(bad)?;
    db.execute_batch(
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, \
         serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);\
         CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, \
         timestamp INTEGER NOT NULL, data BLOB NOT NULL);\
         CREATE INDEX timestamp_idx ON messages (timestamp ASC);",
    )
    .map_err(bad)?;
    let tx = db.transaction().map_err(bad)?;
    let mut count = 0;
    {
        let mut t = tx
            .prepare("INSERT INTO topics(id, name, type, serialization_format, offered_qos_profiles) VALUES (?1, ?2, ?3, 'cdr', '')")
            .map_err(bad)?;
        for (id, c) in connections.iter().enumerate() {
            t.execute((id as i64 + 1, &c.topic, ros2_type(&c.msg_type)))
                .map_err(bad)?;
        }
        let mut q = tx
            .prepare("INSERT INTO messages(topic_id, timestamp, data) VALUES (?1, ?2, ?3)")
            .map_err(bad)?;
        for m in messages {
            q.execute((m.connection as i64 + 1, m.time_ns as i64, &m.data))
                .map_err(bad)?;
            count += 1;
        }
    }
    tx.commit().map_err(bad)?;
    write_metadata(dir, "sqlite3", &name, count)
}

/// A message re-serialised for `to` (the types a laser map reads; others
/// `None`).
fn reencode(c: &Connection, data: &[u8], from: Wire, to: Wire) -> Result<Option<Vec<u8>>, String> {
    Ok(match c.msg_type.as_str() {
        "sensor_msgs/LaserScan" => Some(wire::encode::laser_scan(&wire::laser_scan(data, from)?, to)),
        "nav_msgs/Odometry" => Some(wire::encode::odometry(&wire::odometry(data, from)?, to)),
        "tf2_msgs/TFMessage" | "tf/tfMessage" => {
            Some(wire::encode::transforms(&wire::transforms(data, from)?, to))
        }
        _ => None,
    })
}

/// Copies the scans, odometry and transforms of the bag at `src` (any
/// format the readers take) into a new bag at `dst`: the messages a laser
/// map reads, re-serialised field for field (twists and covariances are
/// written as zeros); with `first_s`, only those of the recording's first
/// that many seconds. The messages are held in memory. Returns the
/// messages written.
pub fn convert(src: &Path, dst: &Path, format: BagFormat, first_s: Option<f64>) -> Result<usize, IoError> {
    let (kind, file) = log_kind(src)?;
    let mut source: Box<dyn MessageSource> = match kind {
        LogKind::Ros1 => Box::new(ros1::Ros1Bag::open(&file)?),
        LogKind::Mcap => Box::new(mcap_reader::McapBag::open(&file)?),
        LogKind::Sqlite => Box::new(sqlite::SqliteBag::open(&file)?),
        LogKind::Carmen => return Err(IoError::invalid(src, "not a bag")),
    };
    let from = source.wire();
    let to = match format {
        BagFormat::Ros1(_) => Wire::Ros1,
        _ => Wire::Cdr,
    };
    let all = source.connections().to_vec();
    let mut messages = Vec::new();
    let mut start = None;
    while let Some(m) = source.next_message()? {
        let t0 = *start.get_or_insert(m.log_time_ns);
        if first_s.is_some_and(|s| m.log_time_ns.saturating_sub(t0) as f64 * 1e-9 > s) {
            break;
        }
        let c = &all[m.connection];
        let data = reencode(c, &m.data, from, to)
            .map_err(|p| IoError::invalid(&file, format!("topic {}: {p}", c.topic)))?;
        if let Some(data) = data {
            messages.push(OutMessage {
                connection: m.connection,
                time_ns: m.log_time_ns,
                data,
            });
        }
    }
    let n = messages.len();
    match format {
        BagFormat::Ros1(c) => write_ros1(dst, &all, messages, c, 768 * 1024)?,
        BagFormat::Mcap => write_mcap(dst, &all, messages)?,
        BagFormat::Sqlite => write_sqlite(dst, &all, messages)?,
    }
    Ok(n)
}
