//! Reading laser input: every scan of the SLAM benchmark's bags
//! (`$PIROUETTE_SHARED/laser/benchmark/*.bag`; skipped with a message
//! without it), and of one of them (aces) converted to each storage
//! format, to set beside the time `pirouette map` takes for the bag
//! (the scoreboard): reading must be a small part of mapping.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use pirouette::io::bag::write::{convert, BagFormat, Ros1Compression};
use pirouette::io::{open_laser_log, BagOptions};
use std::path::Path;

/// Reads every scan of a log; the number read.
fn read_all(path: &Path) -> usize {
    let mut n = 0;
    for scan in open_laser_log(path, &BagOptions::default()).expect("a laser log") {
        std::hint::black_box(scan.expect("a scan"));
        n += 1;
    }
    n
}

fn benches(c: &mut Criterion) {
    let Some(shared) = std::env::var_os("PIROUETTE_SHARED") else {
        eprintln!("bag_read skipped: set PIROUETTE_SHARED to the shared folder");
        return;
    };
    let dir = Path::new(&shared).join("laser/benchmark");
    let mut g = c.benchmark_group("bag_read");
    g.sample_size(10);
    for name in ["intel", "aces", "freiburg-079"] {
        let bag = dir.join(format!("{name}.bag"));
        let scans = read_all(&bag);
        g.throughput(Throughput::Elements(scans as u64));
        g.bench_with_input(BenchmarkId::new("ros1-bz2", name), &bag, |b, p| {
            b.iter(|| read_all(p))
        });
    }
    let tmp = tempfile::tempdir().expect("temporary folder");
    let aces = dir.join("aces.bag");
    for (label, format) in [
        ("ros1-none", BagFormat::Ros1(Ros1Compression::None)),
        ("ros1-lz4", BagFormat::Ros1(Ros1Compression::Lz4)),
        ("mcap-zstd", BagFormat::Mcap),
        ("sqlite3", BagFormat::Sqlite),
    ] {
        let out = tmp.path().join(label);
        convert(&aces, &out, format, None).expect("converted");
        let scans = read_all(&out);
        g.throughput(Throughput::Elements(scans as u64));
        g.bench_with_input(BenchmarkId::new(label, "aces"), &out, |b, p| {
            b.iter(|| read_all(p))
        });
    }
    g.finish();
}

criterion_group!(bag, benches);
criterion_main!(bag);
