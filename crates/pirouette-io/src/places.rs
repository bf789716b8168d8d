//! Place index files.
//!
//! A file is a 24-byte header and a payload:
//!
//! | bytes | content |
//! | --- | --- |
//! | 0-7 | `PIRPLACE` |
//! | 8-11 | format version, `u32` little-endian ([`PLACE_INDEX_FORMAT`]) |
//! | 12-19 | payload length in bytes, `u64` little-endian |
//! | 20-23 | CRC-32 (IEEE) of the payload, `u32` little-endian |
//! | 24- | the index's [`IndexContents`], postcard-encoded |

use crate::{atomic_write, IoError};
use pirouette_places::{IndexContents, PlaceIndex};
use std::io::Read;
use std::path::Path;

/// The magic bytes a place index file starts with.
pub const PLACE_INDEX_MAGIC: &[u8; 8] = b"PIRPLACE";

/// The format version written, and the newest read.
pub const PLACE_INDEX_FORMAT: u32 = 3;

/// The oldest format read: format 1 held no map poses of its places (a
/// query cannot tell a place's look-alike from the place filed twice
/// without them), format 2 no look-alikes of a place in its own map.
pub const OLDEST_PLACE_INDEX_FORMAT: u32 = 3;

/// Header bytes before the payload.
pub const PLACE_INDEX_HEADER_BYTES: usize = 24;

/// The largest payload read, bytes (about 20 million places with their
/// profiles).
pub const MAX_PLACE_INDEX_BYTES: u64 = 1 << 36;

/// Writes an index atomically.
pub fn write_place_index(path: &Path, index: &PlaceIndex) -> Result<(), IoError> {
    let payload = postcard::to_stdvec(index.contents())
        .map_err(|e| IoError::invalid(path, format!("cannot encode the index: {e}")))?;
    let mut bytes = Vec::with_capacity(PLACE_INDEX_HEADER_BYTES + payload.len());
    bytes.extend_from_slice(PLACE_INDEX_MAGIC);
    bytes.extend_from_slice(&PLACE_INDEX_FORMAT.to_le_bytes());
    bytes.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
    bytes.extend_from_slice(&payload);
    atomic_write(path, &bytes)
}

/// What a place index file's header says, checked against its payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlaceIndexHeader {
    /// Format version.
    pub format: u32,
    /// Payload bytes.
    pub payload_bytes: u64,
    /// The whole file's bytes.
    pub file_bytes: u64,
}

/// Reads an index: the header checked (magic, a format this build reads,
/// the payload's length and checksum) before the payload is decoded, and
/// the decoded index checked for consistency.
pub fn read_place_index(path: &Path) -> Result<(PlaceIndex, PlaceIndexHeader), IoError> {
    let mut file = std::fs::File::open(path).map_err(|e| IoError::io(path, e))?;
    let file_bytes = file.metadata().map_err(|e| IoError::io(path, e))?.len();
    let mut head = [0u8; PLACE_INDEX_HEADER_BYTES];
    file.read_exact(&mut head).map_err(|e| match e.kind() {
        std::io::ErrorKind::UnexpectedEof => IoError::invalid(
            path,
            format!("not a place index: {file_bytes} bytes, shorter than its header"),
        ),
        _ => IoError::io(path, e),
    })?;
    let header = parse_header(path, &head, file_bytes)?;
    let mut payload = Vec::new();
    file.take(header.payload_bytes)
        .read_to_end(&mut payload)
        .map_err(|e| IoError::io(path, e))?;
    let stored_crc = u32::from_le_bytes([head[20], head[21], head[22], head[23]]);
    if crc32fast::hash(&payload) != stored_crc {
        return Err(IoError::invalid(
            path,
            "place index is corrupt: its checksum does not match",
        ));
    }
    Ok((decode_place_index(path, &payload)?, header))
}

/// Decodes an index's payload (the bytes after the header, checksum
/// verified) and checks the index for consistency; `path` names it in
/// errors.
pub fn decode_place_index(path: &Path, payload: &[u8]) -> Result<PlaceIndex, IoError> {
    let contents: IndexContents = postcard::from_bytes(payload)
        .map_err(|e| IoError::invalid(path, format!("place index cannot be decoded: {e}")))?;
    PlaceIndex::from_contents(contents).map_err(|e| IoError::invalid(path, e.to_string()))
}

fn parse_header(
    path: &Path,
    head: &[u8; PLACE_INDEX_HEADER_BYTES],
    file_bytes: u64,
) -> Result<PlaceIndexHeader, IoError> {
    if &head[..8] != PLACE_INDEX_MAGIC {
        return Err(IoError::invalid(path, "not a place index (no PIRPLACE header)"));
    }
    let format = u32::from_le_bytes([head[8], head[9], head[10], head[11]]);
    if format > PLACE_INDEX_FORMAT {
        return Err(IoError::invalid(
            path,
            format!("place index format {format} is newer than this build reads ({PLACE_INDEX_FORMAT}): update pirouette"),
        ));
    }
    if format == 0 {
        return Err(IoError::invalid(path, "place index format 0 does not exist"));
    }
    if format < OLDEST_PLACE_INDEX_FORMAT {
        return Err(IoError::invalid(
            path,
            format!("place index format {format} holds no map poses or look-alikes of its places, which queries need to tell look-alikes apart: build it again with `pirouette places build`"),
        ));
    }
    let mut len = [0u8; 8];
    len.copy_from_slice(&head[12..20]);
    let payload_bytes = u64::from_le_bytes(len);
    if payload_bytes > MAX_PLACE_INDEX_BYTES {
        return Err(IoError::invalid(
            path,
            format!("place index declares {payload_bytes} bytes, more than the {MAX_PLACE_INDEX_BYTES} read"),
        ));
    }
    let expected = PLACE_INDEX_HEADER_BYTES as u64 + payload_bytes;
    if file_bytes != expected {
        return Err(IoError::invalid(
            path,
            format!("place index is truncated or padded: {file_bytes} bytes, its header says {expected}"),
        ));
    }
    Ok(PlaceIndexHeader {
        format,
        payload_bytes,
        file_bytes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_index_comes_back_as_written_and_damage_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("places.idx");
        let index = pirouette_places::synthetic::random_index(40, 5).unwrap();
        write_place_index(&path, &index).unwrap();
        let (back, header) = read_place_index(&path).unwrap();
        assert_eq!(back.contents(), index.contents());
        assert_eq!(header.format, PLACE_INDEX_FORMAT);
        assert_eq!(header.file_bytes, std::fs::metadata(&path).unwrap().len());
        let good = std::fs::read(&path).unwrap();
        let refused = |bytes: &[u8], what: &str| {
            std::fs::write(&path, bytes).unwrap();
            let err = read_place_index(&path).unwrap_err().to_string();
            assert!(err.contains("places.idx") && err.contains(what), "{err}");
        };
        refused(&good[..good.len() - 1], "truncated");
        refused(&good[..10], "shorter than its header");
        let mut flipped = good.clone();
        flipped[good.len() / 2] ^= 0x10;
        refused(&flipped, "checksum");
        let mut newer = good.clone();
        newer[8..12].copy_from_slice(&(PLACE_INDEX_FORMAT + 1).to_le_bytes());
        refused(&newer, "newer than this build reads");
        for format in 1..OLDEST_PLACE_INDEX_FORMAT {
            let mut older = good.clone();
            older[8..12].copy_from_slice(&format.to_le_bytes());
            refused(&older, "build it again");
        }
        let mut other = good.clone();
        other[0] = b'X';
        refused(&other, "not a place index");
        let mut huge = good;
        huge[19] = 0xff;
        refused(&huge, "more than");
    }
}
