//! ROS 2 bags in MCAP storage, read with the `mcap` crate's sans-I/O
//! readers: the channels from the summary section at the end (a file
//! without one is read once through for them), then the records front to
//! back, a chunk at a time.

use super::{Connection, MessageSource, RawMessage};
use crate::IoError;
use mcap::records::Record;
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
use mcap::sans_io::summary_reader::{SummaryReadEvent, SummaryReader};
use std::collections::HashMap;
use std::io::{Read, Seek};
use std::path::{Path, PathBuf};

/// An MCAP file's first bytes.
pub const MAGIC: &[u8] = mcap::MAGIC;

/// The longest record read, bytes.
const MAX_RECORD_BYTES: usize = 1 << 30;

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
    /// Opens an MCAP file and reads its channels.
    pub fn open(path: &Path) -> Result<Self, IoError> {
        let mut file = std::fs::File::open(path).map_err(|e| IoError::io(path, e))?;
        let bad = |e: mcap::McapError| IoError::invalid(path, format!("not a readable MCAP file: {e}"));
        let mut summary = SummaryReader::new();
        while let Some(event) = summary.next_event() {
            match event.map_err(bad)? {
                SummaryReadEvent::ReadRequest(n) => {
                    let got = file.read(summary.insert(n)).map_err(|e| IoError::io(path, e))?;
                    summary.notify_read(got);
                }
                SummaryReadEvent::SeekRequest(to) => {
                    let at = file.seek(to).map_err(|e| IoError::io(path, e))?;
                    summary.notify_seeked(at);
                }
            }
        }
        file.rewind().map_err(|e| IoError::io(path, e))?;
        let mut bag = Self {
            path: path.to_owned(),
            file,
            reader: linear(),
            connections: Vec::new(),
            ids: HashMap::new(),
            schemas: HashMap::new(),
            read: 0,
        };
        match summary.finish() {
            Some(s) => {
                let mut channels: Vec<_> = s.channels.values().collect();
                channels.sort_by_key(|c| c.id);
                for c in channels {
                    let schema = c.schema.as_ref().map_or("", |s| s.name.as_str());
                    bag.file_channel(c.id, &c.topic, schema, &c.message_encoding);
                }
            }
            None => {
                // No summary: one pass through for the channels.
                while bag.next_raw()?.is_some() {}
                bag.file.rewind().map_err(|e| IoError::io(path, e))?;
                bag.reader = linear();
                bag.read = 0;
            }
        }
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
