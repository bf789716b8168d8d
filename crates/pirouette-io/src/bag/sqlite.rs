//! ROS 2 bags in sqlite3 storage (`.db3`), read with `rusqlite`: the
//! `topics` table, then the `messages` table in stamp order, a page of
//! rows at a time.

use super::{Connection, MessageSource, RawMessage};
use crate::IoError;
use rusqlite::{Connection as Db, OpenFlags};
use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};

/// Rows read per query.
const PAGE_ROWS: i64 = 512;
/// The largest message read, bytes.
const MAX_MESSAGE_BYTES: usize = 1 << 30;

/// The reader of a sqlite3 bag.
pub struct SqliteBag {
    path: PathBuf,
    db: Db,
    connections: Vec<Connection>,
    /// A topic's id → its place in `connections`.
    ids: HashMap<i64, usize>,
    page: VecDeque<RawMessage>,
    /// The last row handed out: its stamp and id.
    after: (i64, i64),
    done: bool,
}

impl SqliteBag {
    /// Opens a `.db3` file and reads its topics.
    pub fn open(path: &Path) -> Result<Self, IoError> {
        let bad =
            |e: rusqlite::Error| IoError::invalid(path, format!("not a readable ROS 2 sqlite3 bag: {e}"));
        let db = Db::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(bad)?;
        let mut connections = Vec::new();
        let mut ids = HashMap::new();
        {
            let mut q = db
                .prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id")
                .map_err(bad)?;
            let rows = q
                .query_map([], |r| {
                    Ok((
                        r.get::<_, i64>(0)?,
                        r.get::<_, String>(1)?,
                        r.get::<_, String>(2)?,
                        r.get::<_, String>(3)?,
                    ))
                })
                .map_err(bad)?;
            for row in rows {
                let (id, name, ty, format) = row.map_err(bad)?;
                let ty = if format == "cdr" {
                    ty
                } else {
                    format!("{ty} ({format})")
                };
                ids.insert(id, connections.len());
                connections.push(Connection::new(name, &ty));
            }
        }
        Ok(Self {
            path: path.to_owned(),
            db,
            connections,
            ids,
            page: VecDeque::new(),
            after: (i64::MIN, i64::MIN),
            done: false,
        })
    }

    fn fill(&mut self) -> Result<(), IoError> {
        let path = &self.path;
        let bad = |e: rusqlite::Error| IoError::invalid(path, format!("reading its messages: {e}"));
        let mut q = self
            .db
            .prepare_cached(
                "SELECT id, topic_id, timestamp, length(data) FROM messages \
                 WHERE timestamp > ?1 OR (timestamp = ?1 AND id > ?2) \
                 ORDER BY timestamp, id LIMIT ?3",
            )
            .map_err(bad)?;
        let rows: Vec<(i64, i64, i64, i64)> = q
            .query_map((self.after.0, self.after.1, PAGE_ROWS), |r| {
                Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?))
            })
            .map_err(bad)?
            .collect::<Result<_, _>>()
            .map_err(bad)?;
        let mut data_q = self
            .db
            .prepare_cached("SELECT data FROM messages WHERE id = ?1")
            .map_err(bad)?;
        for (id, topic, stamp, len) in rows {
            let Some(&connection) = self.ids.get(&topic) else {
                return Err(IoError::invalid(
                    path,
                    format!("message row {id}: topic {topic}, never declared"),
                ));
            };
            if !(0..=MAX_MESSAGE_BYTES as i64).contains(&len) {
                return Err(IoError::invalid(path, format!("message row {id}: {len} bytes")));
            }
            let data: Vec<u8> = data_q.query_row([id], |r| r.get(0)).map_err(bad)?;
            self.page.push_back(RawMessage {
                connection,
                log_time_ns: u64::try_from(stamp).unwrap_or(0),
                data,
                offset: u64::try_from(id).unwrap_or(0),
            });
            self.after = (stamp, id);
        }
        if self.page.is_empty() {
            self.done = true;
        }
        Ok(())
    }
}

impl MessageSource for SqliteBag {
    fn connections(&self) -> &[Connection] {
        &self.connections
    }

    fn format(&self) -> &'static str {
        "ROS 2 bag (sqlite3)"
    }

    fn wire(&self) -> super::wire::Wire {
        super::wire::Wire::Cdr
    }

    fn next_message(&mut self) -> Result<Option<RawMessage>, IoError> {
        if self.page.is_empty() && !self.done {
            if let Err(e) = self.fill() {
                self.done = true;
                return Err(e);
            }
        }
        Ok(self.page.pop_front())
    }
}
