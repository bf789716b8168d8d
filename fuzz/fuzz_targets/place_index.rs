//! Any bytes as a place index's payload (past its header and checksum): an
//! error, or an index that answers a query, never a panic.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = std::path::Path::new("fuzzed.idx");
    if let Ok(index) = pirouette::io::decode_place_index(path, data) {
        if !index.is_empty() {
            let query = index.signature(0);
            let _ = index.query(&query, &pirouette::places::QueryConfig::default());
        }
    }
});
