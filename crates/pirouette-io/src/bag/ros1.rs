//! ROS 1 bags, format 2.0, read as a stream of records.
//!
//! A record is `header_len: u32, header, data_len: u32, data`, the header
//! a run of `field_len: u32, name=value` fields, one of them `op`. The
//! file is read front to back: a chunk (`op` 5) is read and decompressed
//! (none, bz2 or lz4) into one buffer, and its records (connections, `op`
//! 7, and messages, `op` 2) are handed out in order; index records are
//! skipped. Messages are handed out in the order of their time: a
//! chunk's messages are sorted, and those at or after the start of a
//! later chunk (the chunk infos give each chunk's first time) wait for
//! it. Memory holds a chunk or two, whatever the bag's size. The
//! connections and chunk infos are first read from the index section at
//! the end (the bag header's `index_pos`); a bag without one (its
//! recording cut short) is read once through for its connections, and
//! its messages are sorted within each chunk only.
//!
//! Damage: a bag cut short inside a record ends there: the messages
//! before the cut are handed out, and [`MessageSource::warnings`] names
//! the byte. A chunk that fails to decompress, or whose records do not
//! fit in it, is skipped whole, each such chunk named in the warnings; a
//! bag whose every chunk fails is refused. (docs/bags.md)

use super::{Connection, MessageSource, RawMessage};
use crate::IoError;
use std::collections::HashMap;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// The first line of a version 2.0 bag.
pub const MAGIC: &[u8] = b"#ROSBAG V2.0\n";

/// The largest record header read, bytes.
const MAX_HEADER_BYTES: u32 = 16 << 20;
/// The largest record data read (a chunk, compressed), bytes.
const MAX_DATA_BYTES: u32 = 1 << 30;
/// The largest chunk once decompressed, bytes.
const MAX_CHUNK_BYTES: u32 = 1 << 30;
/// The most connections a bag may declare.
const MAX_CONNECTIONS: usize = 100_000;

const OP_MESSAGE: u8 = 0x02;
const OP_BAG_HEADER: u8 = 0x03;
const OP_CHUNK: u8 = 0x05;
const OP_CHUNK_INFO: u8 = 0x06;
const OP_CONNECTION: u8 = 0x07;

/// A record header's fields.
struct Fields<'a>(Vec<(&'a str, &'a [u8])>);

impl<'a> Fields<'a> {
    fn parse(bytes: &'a [u8]) -> Result<Self, String> {
        let mut out = Vec::new();
        let mut rest = bytes;
        while !rest.is_empty() {
            let len = u32_at(rest, 0).ok_or("a header field's length is cut short")? as usize;
            let field = rest
                .get(4..4 + len)
                .ok_or("a header field runs past its header")?;
            let eq = field
                .iter()
                .position(|&b| b == b'=')
                .ok_or("a header field without `=`")?;
            let name = std::str::from_utf8(&field[..eq]).map_err(|_| "a header field's name is not text")?;
            out.push((name, &field[eq + 1..]));
            rest = &rest[4 + len..];
        }
        Ok(Self(out))
    }

    fn get(&self, name: &str) -> Option<&'a [u8]> {
        self.0.iter().find(|(n, _)| *n == name).map(|(_, v)| *v)
    }

    fn op(&self) -> Result<u8, String> {
        match self.get("op") {
            Some([op]) => Ok(*op),
            _ => Err("a record without its `op` field".into()),
        }
    }

    fn u32(&self, name: &str) -> Result<u32, String> {
        self.get(name)
            .and_then(|v| <[u8; 4]>::try_from(v).ok())
            .map(u32::from_le_bytes)
            .ok_or_else(|| format!("the `{name}` field is missing or not 4 bytes"))
    }

    fn u64(&self, name: &str) -> Result<u64, String> {
        self.get(name)
            .and_then(|v| <[u8; 8]>::try_from(v).ok())
            .map(u64::from_le_bytes)
            .ok_or_else(|| format!("the `{name}` field is missing or not 8 bytes"))
    }

    fn text(&self, name: &str) -> Result<String, String> {
        let v = self
            .get(name)
            .ok_or_else(|| format!("the `{name}` field is missing"))?;
        String::from_utf8(v.to_vec()).map_err(|_| format!("the `{name}` field is not text"))
    }
}

/// A bag time (`sec: u32, nsec: u32`, read as one little-endian `u64`)
/// in nanoseconds.
fn time_ns(time: u64) -> u64 {
    (time & 0xffff_ffff) * 1_000_000_000 + (time >> 32)
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at + 4)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// A record read from the file or a chunk: its header bytes and data.
struct Record {
    header: Vec<u8>,
    data: Vec<u8>,
}

/// Reads `len` bytes, refusing to read past the end (a short read means
/// the file was cut short), without allocating more than is there.
fn read_exact_bounded(input: &mut impl Read, len: u32) -> std::io::Result<Option<Vec<u8>>> {
    let mut buf = Vec::new();
    input.take(u64::from(len)).read_to_end(&mut buf)?;
    Ok((buf.len() == len as usize).then_some(buf))
}

/// Fills `buf` as far as the input goes: the bytes read, fewer than
/// `buf.len()` only at the end of the input.
fn read_up_to(input: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match input.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

/// What is wrong, without the file's name (the warning names it once).
fn problem(e: &IoError) -> String {
    match e {
        IoError::Invalid { problem, .. } => problem.clone(),
        other => other.to_string(),
    }
}

/// The reader of a ROS 1 bag.
pub struct Ros1Bag {
    path: PathBuf,
    input: BufReader<std::fs::File>,
    /// The offset of the next record in the file.
    offset: u64,
    /// The connections, in the order first declared.
    connections: Vec<Connection>,
    /// A connection's id in the bag → its place in `connections`.
    ids: HashMap<u32, usize>,
    /// The records of the chunk being handed out, and the next one's offset.
    chunk: Vec<u8>,
    chunk_at: usize,
    /// The file offset of that chunk (for errors).
    chunk_offset: u64,
    /// Each chunk's offset and the earliest start of it and every later
    /// chunk, nanoseconds (from the chunk infos), by offset.
    later_start: Vec<(u64, u64)>,
    /// Messages read, sorted by time, and those that may go: earlier than
    /// this.
    buffer: std::collections::VecDeque<RawMessage>,
    release_before: u64,
    /// Messages read so far (orders equal times by the file).
    read: u64,
    eof: bool,
    /// Where the file ends inside a record, if it does.
    cut_at: Option<u64>,
    /// Chunks skipped: offset and why.
    bad_chunks: Vec<(u64, String)>,
    /// Chunks read whole.
    good_chunks: usize,
}

impl Ros1Bag {
    /// Opens a bag and reads its connections.
    pub fn open(path: &Path) -> Result<Self, IoError> {
        let file = std::fs::File::open(path).map_err(|e| IoError::io(path, e))?;
        let file_len = file.metadata().map_err(|e| IoError::io(path, e))?.len();
        let mut input = BufReader::with_capacity(1 << 16, file);
        let mut magic = [0u8; 13];
        if input.read_exact(&mut magic).is_err() || magic != MAGIC {
            return Err(IoError::invalid(
                path,
                "not a ROS 1 bag of format 2.0 (it does not start with `#ROSBAG V2.0`)",
            ));
        }
        let mut bag = Self {
            path: path.to_owned(),
            input,
            offset: MAGIC.len() as u64,
            connections: Vec::new(),
            ids: HashMap::new(),
            chunk: Vec::new(),
            chunk_at: 0,
            chunk_offset: 0,
            later_start: Vec::new(),
            buffer: std::collections::VecDeque::new(),
            release_before: 0,
            read: 0,
            eof: false,
            cut_at: None,
            bad_chunks: Vec::new(),
            good_chunks: 0,
        };
        let first_offset = bag.offset;
        let header = bag.read_record()?.ok_or_else(|| {
            let why = if bag.cut_at.is_some() {
                "the bag is cut short in its header record"
            } else {
                "no bag header record"
            };
            bag.bad(first_offset, why)
        })?;
        let fields = Fields::parse(&header.header).map_err(|p| bag.bad(first_offset, p))?;
        if fields.op().map_err(|p| bag.bad(first_offset, p))? != OP_BAG_HEADER {
            return Err(bag.bad(first_offset, "the first record is not the bag header"));
        }
        let index_pos = fields.u64("index_pos").map_err(|p| bag.bad(first_offset, p))?;
        let data_start = bag.offset;
        if index_pos >= data_start && index_pos < file_len {
            bag.seek(index_pos)?;
            let mut starts = Vec::new();
            loop {
                let at = bag.offset;
                let Some(record) = bag.read_record()? else { break };
                bag.file_connection(&record, at)?;
                let fields = Fields::parse(&record.header).map_err(|p| bag.bad(at, p))?;
                if fields.op().map_err(|p| bag.bad(at, p))? == OP_CHUNK_INFO {
                    let pos = fields.u64("chunk_pos").map_err(|p| bag.bad(at, p))?;
                    let start = time_ns(fields.u64("start_time").map_err(|p| bag.bad(at, p))?);
                    starts.push((pos, start));
                }
            }
            starts.sort_unstable();
            let mut least = u64::MAX;
            for (_, start) in starts.iter_mut().rev() {
                least = least.min(*start);
                *start = least;
            }
            bag.later_start = starts;
        } else {
            // No index: one pass through for the connections.
            bag.seek(data_start)?;
            while bag.next_raw()?.is_some() {}
        }
        bag.seek(data_start)?;
        Ok(bag)
    }

    fn bad(&self, offset: u64, problem: impl std::fmt::Display) -> IoError {
        IoError::invalid(&self.path, format!("at byte {offset}: {problem}"))
    }

    fn seek(&mut self, offset: u64) -> Result<(), IoError> {
        self.input
            .seek(SeekFrom::Start(offset))
            .map_err(|e| IoError::io(&self.path, e))?;
        self.offset = offset;
        self.chunk.clear();
        self.chunk_at = 0;
        self.buffer.clear();
        self.release_before = 0;
        self.eof = false;
        Ok(())
    }

    /// The next record of the file; `None` at its end, or where the file
    /// ends inside a record (`cut_at` then names its offset).
    fn read_record(&mut self) -> Result<Option<Record>, IoError> {
        let at = self.offset;
        let cut = |s: &mut Self| {
            s.cut_at = Some(at);
            Ok(None)
        };
        let mut len = [0u8; 4];
        let got = read_up_to(&mut self.input, &mut len).map_err(|e| IoError::io(&self.path, e))?;
        if got == 0 {
            return Ok(None);
        } else if got < len.len() {
            return cut(self);
        }
        let header_len = u32::from_le_bytes(len);
        if header_len > MAX_HEADER_BYTES {
            return Err(self.bad(at, format!("a record header of {header_len} bytes")));
        }
        let Some(header) =
            read_exact_bounded(&mut self.input, header_len).map_err(|e| IoError::io(&self.path, e))?
        else {
            return cut(self);
        };
        if read_up_to(&mut self.input, &mut len).map_err(|e| IoError::io(&self.path, e))? < len.len() {
            return cut(self);
        }
        let data_len = u32::from_le_bytes(len);
        if data_len > MAX_DATA_BYTES {
            return Err(self.bad(at, format!("a record of {data_len} bytes")));
        }
        let Some(data) =
            read_exact_bounded(&mut self.input, data_len).map_err(|e| IoError::io(&self.path, e))?
        else {
            return cut(self);
        };
        self.offset = at + 8 + u64::from(header_len) + u64::from(data_len);
        Ok(Some(Record { header, data }))
    }

    /// Files a connection record (ignoring other records); `offset` names
    /// where it was found.
    fn file_connection(&mut self, record: &Record, offset: u64) -> Result<(), IoError> {
        let fields = Fields::parse(&record.header).map_err(|p| self.bad(offset, p))?;
        if fields.op().map_err(|p| self.bad(offset, p))? != OP_CONNECTION {
            return Ok(());
        }
        let id = fields.u32("conn").map_err(|p| self.bad(offset, p))?;
        if self.ids.contains_key(&id) {
            return Ok(());
        }
        if self.connections.len() >= MAX_CONNECTIONS {
            return Err(self.bad(offset, format!("more than {MAX_CONNECTIONS} connections")));
        }
        let topic = fields.text("topic").map_err(|p| self.bad(offset, p))?;
        let inner = Fields::parse(&record.data).map_err(|p| self.bad(offset, p))?;
        let msg_type = inner.text("type").map_err(|p| self.bad(offset, p))?;
        self.ids.insert(id, self.connections.len());
        self.connections.push(Connection::new(topic, &msg_type));
        Ok(())
    }

    /// Decompresses a chunk record's data.
    fn open_chunk(&mut self, record: Record, offset: u64) -> Result<(), IoError> {
        let fields = Fields::parse(&record.header).map_err(|p| self.bad(offset, p))?;
        let compression = fields.text("compression").map_err(|p| self.bad(offset, p))?;
        let size = fields.u32("size").map_err(|p| self.bad(offset, p))?;
        if size > MAX_CHUNK_BYTES {
            return Err(self.bad(offset, format!("a chunk of {size} bytes")));
        }
        let failed = |s: &Self, e: &dyn std::fmt::Display| {
            s.bad(
                offset,
                format!("the chunk ({compression}) fails to decompress: {e}"),
            )
        };
        let mut out = Vec::new();
        let limit = u64::from(size) + 1;
        match compression.as_str() {
            "none" => out = record.data,
            "bz2" => {
                let r = bzip2::read::BzDecoder::new(&record.data[..])
                    .take(limit)
                    .read_to_end(&mut out);
                r.map_err(|e| failed(self, &e))?;
            }
            "lz4" => {
                let r = lz4_flex::frame::FrameDecoder::new(&record.data[..])
                    .take(limit)
                    .read_to_end(&mut out);
                r.map_err(|e| failed(self, &e))?;
            }
            other => {
                return Err(self.bad(
                    offset,
                    format!("chunk compression `{other}` (known: none, bz2, lz4)"),
                ));
            }
        }
        if out.len() != size as usize {
            return Err(self.bad(
                offset,
                format!("the chunk holds {} bytes where its header says {size}", out.len()),
            ));
        }
        self.chunk = out;
        self.chunk_at = 0;
        self.chunk_offset = offset;
        Ok(())
    }

    /// The next record inside the current chunk.
    fn next_in_chunk(&mut self) -> Result<Option<Record>, IoError> {
        let c = &self.chunk;
        let at = self.chunk_at;
        if at >= c.len() {
            return Ok(None);
        }
        let bad = |p: &str| {
            IoError::invalid(
                &self.path,
                format!(
                    "in the chunk at byte {}, at its byte {at}: {p}",
                    self.chunk_offset
                ),
            )
        };
        let hl = u32_at(c, at).ok_or_else(|| bad("a record's length is cut short"))? as usize;
        let header = c
            .get(at + 4..at + 4 + hl)
            .ok_or_else(|| bad("a record header runs past the chunk"))?;
        let dl = u32_at(c, at + 4 + hl).ok_or_else(|| bad("a record's data length is cut short"))? as usize;
        let start = at + 8 + hl;
        let data = c
            .get(start..start + dl)
            .ok_or_else(|| bad("a record runs past the chunk"))?;
        let record = Record {
            header: header.to_vec(),
            data: data.to_vec(),
        };
        self.chunk_at = start + dl;
        Ok(Some(record))
    }

    /// Reads the records of the current chunk: connections filed,
    /// messages into the buffer.
    fn drain_chunk(&mut self) -> Result<(), IoError> {
        let mut messages = Vec::new();
        while let Some(record) = self.next_in_chunk()? {
            let at = self.chunk_offset;
            let fields = Fields::parse(&record.header).map_err(|p| self.bad(at, p))?;
            match fields.op().map_err(|p| self.bad(at, p))? {
                OP_CONNECTION => self.file_connection(&record, at)?,
                OP_MESSAGE => {
                    let id = fields.u32("conn").map_err(|p| self.bad(at, p))?;
                    let time = fields.u64("time").map_err(|p| self.bad(at, p))?;
                    let Some(&connection) = self.ids.get(&id) else {
                        return Err(self.bad(at, format!("a message on connection {id}, never declared")));
                    };
                    messages.push(RawMessage {
                        connection,
                        log_time_ns: time_ns(time),
                        data: record.data,
                        offset: at,
                    });
                    self.read += 1;
                }
                _ => {}
            }
        }
        self.buffer.extend(messages);
        // Stable: equal times keep the file's order.
        self.buffer.make_contiguous().sort_by_key(|m| m.log_time_ns);
        Ok(())
    }

    /// Reads the next chunk (or message outside chunks) of the file into
    /// the buffer; false at the end of the data.
    fn load(&mut self) -> Result<bool, IoError> {
        loop {
            let at = self.offset;
            let Some(record) = self.read_record()? else {
                return Ok(false);
            };
            let fields = Fields::parse(&record.header).map_err(|p| self.bad(at, p))?;
            match fields.op().map_err(|p| self.bad(at, p))? {
                OP_CHUNK => {
                    // A damaged chunk is skipped whole (none of its
                    // messages handed out), and named in the warnings.
                    if let Err(e) = self.open_chunk(record, at).and_then(|()| self.drain_chunk()) {
                        self.chunk.clear();
                        self.chunk_at = 0;
                        self.bad_chunks.push((at, problem(&e)));
                        continue;
                    }
                    self.good_chunks += 1;
                    // What starts a later chunk waits for it.
                    let i = self.later_start.partition_point(|&(pos, _)| pos <= at);
                    self.release_before = self.later_start.get(i).map_or(u64::MAX, |&(_, t)| t);
                    return Ok(true);
                }
                OP_CONNECTION => self.file_connection(&record, at)?,
                OP_MESSAGE => {
                    // A message outside chunks (unchunked writers).
                    let mut whole = Vec::with_capacity(8 + record.header.len() + record.data.len());
                    whole.extend_from_slice(&(record.header.len() as u32).to_le_bytes());
                    whole.extend_from_slice(&record.header);
                    whole.extend_from_slice(&(record.data.len() as u32).to_le_bytes());
                    whole.extend_from_slice(&record.data);
                    self.chunk = whole;
                    self.chunk_at = 0;
                    self.chunk_offset = at;
                    self.drain_chunk()?;
                    self.release_before = u64::MAX;
                    return Ok(true);
                }
                _ => {}
            }
        }
    }

    /// The next message in time order (connections filed on the way);
    /// `None` at the end of the data.
    fn next_raw(&mut self) -> Result<Option<RawMessage>, IoError> {
        loop {
            if let Some(m) = self.buffer.front() {
                if self.eof || m.log_time_ns < self.release_before {
                    return Ok(self.buffer.pop_front());
                }
            } else if self.eof {
                return Ok(None);
            }
            if !self.load()? {
                self.eof = true;
                if self.good_chunks == 0 && !self.bad_chunks.is_empty() {
                    let (at, why) = &self.bad_chunks[0];
                    return Err(self.bad(*at, format!("no chunk of the bag can be read (the first: {why})")));
                }
            }
        }
    }
}

impl MessageSource for Ros1Bag {
    fn connections(&self) -> &[Connection] {
        &self.connections
    }

    fn format(&self) -> &'static str {
        "ROS 1 bag"
    }

    fn wire(&self) -> super::wire::Wire {
        super::wire::Wire::Ros1
    }

    fn next_message(&mut self) -> Result<Option<RawMessage>, IoError> {
        self.next_raw()
    }

    fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if let Some(at) = self.cut_at {
            w.push(format!(
                "{}: the bag is cut short inside the record at byte {at} (or that record's length is damaged): what came before it is read",
                self.path.display()
            ));
        }
        if let Some((at, why)) = self.bad_chunks.first() {
            w.push(format!(
                "{}: {} chunk(s) skipped, their messages lost; the first at byte {at}: {why}",
                self.path.display(),
                self.bad_chunks.len()
            ));
        }
        w
    }
}
