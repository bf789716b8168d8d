//! ROS 2 bags in MCAP storage, read with the `mcap` crate's sans-I/O
//! linear reader: once through for the channels, then the records front
//! to back, a chunk at a time. Only schema, channel and message records
//! are parsed, each after its length fields are checked against it.

use super::{Connection, MessageSource, RawMessage};
use crate::IoError;
use mcap::records::{op, Record};
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
use std::collections::HashMap;
use std::io::{Read, Seek};
use std::path::{Path, PathBuf};

/// An MCAP file's first bytes.
pub const MAGIC: &[u8] = mcap::MAGIC;

/// The longest record read, bytes.
const MAX_RECORD_BYTES: usize = 256 << 20;

/// Whether the length-prefixed fields of a schema, channel or message
/// record fit in it (the crate allocates a field's stated length before
/// reading it).
fn lengths_fit(opcode: u8, data: &[u8]) -> bool {
    // Skips a `u32`-length-prefixed field at `at`; the offset after it.
    let field = |at: usize| -> Option<usize> {
        let b = data.get(at..at + 4)?;
        let len = u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize;
        let end = at.checked_add(4)?.checked_add(len)?;
        (end <= data.len()).then_some(end)
    };
    let fits = || -> Option<()> {
        match opcode {
            // id, name, encoding, data.
            op::SCHEMA => field(field(field(2)?)?).map(|_| ()),
            // id, schema id, topic, encoding, then a map of string pairs.
            op::CHANNEL => {
                let map = field(field(4)?)?;
                let end = field(map)?;
                let mut at = map + 4;
                while at < end {
                    at = field(field(at)?)?;
                }
                (at == end).then_some(())
            }
            // A fixed header, then the data to the end.
            _ => (data.len() >= 22).then_some(()),
        }
    };
    fits().is_some()
}

/// The reader of an MCAP bag.
pub struct McapBag {
    path: PathBuf,
    file: std::fs::File,
    reader: LinearReader,
    connections: Vec<Connection>,
    /// A channel's id → its place in `connections`.
    ids: HashMap<u16, usize>,
    /// Schema names by id, as declared.
    schemas: HashMap<u16, String>,
    /// Bytes read so far (for errors).
    read: u64,
}

fn linear() -> LinearReader {
    LinearReader::new_with_options(LinearReaderOptions::default().with_record_length_limit(MAX_RECORD_BYTES))
}

impl McapBag {
    /// Opens an MCAP file and reads its channels: one pass through the
    /// file (the summary section is not trusted: the crate's summary
    /// reader parses every index record it holds, and a damaged length
    /// there would be allocated before it is checked).
    pub fn open(path: &Path) -> Result<Self, IoError> {
        let file = std::fs::File::open(path).map_err(|e| IoError::io(path, e))?;
        let mut bag = Self {
            path: path.to_owned(),
            file,
            reader: linear(),
            connections: Vec::new(),
            ids: HashMap::new(),
            schemas: HashMap::new(),
            read: 0,
        };
        while bag.next_raw()?.is_some() {}
        bag.file.rewind().map_err(|e| IoError::io(path, e))?;
        bag.reader = linear();
        bag.read = 0;
        Ok(bag)
    }

    fn file_channel(&mut self, id: u16, topic: &str, schema: &str, encoding: &str) {
        if self.ids.contains_key(&id) {
            return;
        }
        self.ids.insert(id, self.connections.len());
        // Only CDR is decoded: another encoding shows in the type, which
        // then matches none the reader takes.
        let msg_type = if encoding == "cdr" {
            schema.to_owned()
        } else {
            format!("{schema} ({encoding})")
        };
        self.connections
            .push(Connection::new(topic.to_owned(), &msg_type));
    }

    /// The next message (channels filed on the way); `None` at the end.
    fn next_raw(&mut self) -> Result<Option<RawMessage>, IoError> {
        loop {
            let Some(event) = self.reader.next_event() else {
                return Ok(None);
            };
            let at = self.read;
            let event = event.map_err(|e| IoError::invalid(&self.path, format!("near byte {at}: {e}")))?;
            match event {
                LinearReadEvent::ReadRequest(n) => {
                    let got =
                        (self.file.read(self.reader.insert(n))).map_err(|e| IoError::io(&self.path, e))?;
                    self.reader.notify_read(got);
                    self.read += got as u64;
                }
                LinearReadEvent::Record { data, opcode } => {
                    // Only the records read here are parsed, and only once
                    // their lengths are known to fit.
                    if !matches!(opcode, op::SCHEMA | op::CHANNEL | op::MESSAGE) {
                        continue;
                    }
                    if !lengths_fit(opcode, data) {
                        return Err(IoError::invalid(
                            &self.path,
                            format!("near byte {at}: a record whose lengths run past its end"),
                        ));
                    }
                    let record = mcap::parse_record(opcode, data)
                        .map_err(|e| IoError::invalid(&self.path, format!("near byte {at}: {e}")))?;
                    match record {
                        Record::Schema { header, .. } => {
                            self.schemas.insert(header.id, header.name);
                        }
                        Record::Channel(c) => {
                            let schema = self.schemas.get(&c.schema_id).cloned().unwrap_or_default();
                            self.file_channel(c.id, &c.topic, &schema, &c.message_encoding);
                        }
                        Record::Message { header, data } => {
                            let Some(&connection) = self.ids.get(&header.channel_id) else {
                                return Err(IoError::invalid(
                                    &self.path,
                                    format!(
                                        "near byte {at}: a message on channel {}, never declared",
                                        header.channel_id
                                    ),
                                ));
                            };
                            return Ok(Some(RawMessage {
                                connection,
                                log_time_ns: header.log_time,
                                data: data.into_owned(),
                                offset: at,
                            }));
                        }
                        _ => {}
                    }
                }
            }
        }
    }
}

impl MessageSource for McapBag {
    fn connections(&self) -> &[Connection] {
        &self.connections
    }

    fn format(&self) -> &'static str {
        "ROS 2 bag (MCAP)"
    }

    fn wire(&self) -> super::wire::Wire {
        super::wire::Wire::Cdr
    }

    fn next_message(&mut self) -> Result<Option<RawMessage>, IoError> {
        self.next_raw()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hex(s: &str) -> Vec<u8> {
        (0..s.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
            .collect()
    }

    #[test]
    fn a_damaged_index_record_is_an_error_not_an_allocation() {
        // A fuzzed file whose attachment index claimed a 2 GB string.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("damaged.mcap");
        let mut bytes = MAGIC.to_vec();
        bytes.extend(hex("0a3000000000000000000000000000000000000000000000000000000000000000000000007d00ffffffffffffff00000000000080007dff02fffff70000ff0000000000000000000000000000000000000d0a0000894d434150300d0a"));
        std::fs::write(&path, bytes).unwrap();
        let e = McapBag::open(&path).err().expect("refused").to_string();
        assert!(e.contains("damaged.mcap"), "{e}");
    }

    #[test]
    fn lengths_are_checked_before_parsing() {
        // A schema: id, then a name of 3 bytes, an encoding of 0, data of 1.
        let mut schema = vec![1, 0];
        for field in [&b"abc"[..], b"", b"x"] {
            schema.extend((field.len() as u32).to_le_bytes());
            schema.extend(field);
        }
        assert!(lengths_fit(op::SCHEMA, &schema));
        schema[2] = 200;
        assert!(!lengths_fit(op::SCHEMA, &schema));
        assert!(!lengths_fit(op::MESSAGE, &[0; 21]));
    }
}
