//! The place index: one query (key search, then the shift search and
//! colour check of its 16 nearest places) at 1,000, 100,000 and 1,000,000
//! random places, the k-d tree beside a scan of every key; and filing a
//! place (signature and insert). The memory the 1,000,000-place index
//! holds is printed (the process's resident size before and after
//! building it, Linux only) beside its contents' own size.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use pirouette::places::synthetic::{random_index, random_sweep, SYNTHETIC_LIMIT_M};
use pirouette::places::{PlaceIndex, PlaceMeta, QueryConfig, Signature, SignatureConfig};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;
use std::time::Duration;

/// Query signatures from rooms the index has never seen.
fn queries(index: &PlaceIndex, count: usize) -> Vec<Signature> {
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    (0..count)
        .map(|_| {
            let rop = random_sweep(&mut rng, SYNTHETIC_LIMIT_M);
            index.transforms().signature(&rop).expect("a full sweep")
        })
        .collect()
}

/// The resident size of this process, bytes (Linux), or `None`.
fn resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Criterion reports means; a query's latency is skewed (a query far from
/// every stored key searches a wide ball), so the distribution over 200
/// unseen rooms is printed beside it: each query timed alone, the best of
/// 20 runs.
fn latency_percentiles(index: &PlaceIndex, places: usize, config: &QueryConfig) {
    let mut rng = ChaCha8Rng::seed_from_u64(1234);
    let mut times: Vec<f64> = (0..200)
        .map(|_| {
            let rop = random_sweep(&mut rng, SYNTHETIC_LIMIT_M);
            let q = index.transforms().signature(&rop).expect("a full sweep");
            (0..20)
                .map(|_| {
                    let t = std::time::Instant::now();
                    black_box(index.query(&q, config));
                    t.elapsed().as_secs_f64() * 1e6
                })
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    times.sort_by(f64::total_cmp);
    let at = |p: usize| times[(times.len() - 1) * p / 100];
    eprintln!(
        "places/query: {places} places, k-d tree, per-query latency over 200 unseen rooms: p50 {:.0} µs, p90 {:.0} µs, p99 {:.0} µs",
        at(50),
        at(90),
        at(99)
    );
}

fn query(c: &mut Criterion) {
    let mut group = c.benchmark_group("places/query");
    group
        .sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4));
    let config = QueryConfig::default();
    for places in [1_000usize, 100_000, 1_000_000] {
        let before = resident_bytes();
        let index = random_index(places, 7).expect("synthetic index");
        if let (Some(a), Some(b)) = (before, resident_bytes()) {
            let c = index.contents();
            let own = c.keys.len() * std::mem::size_of_val(&c.keys[0])
                + c.dct.len() * std::mem::size_of_val(&c.dct[0])
                + c.colour.len() * std::mem::size_of_val(&c.colour[0])
                + c.colour_seen.len() * std::mem::size_of_val(&c.colour_seen[0])
                + c.meta.len() * std::mem::size_of::<PlaceMeta>();
            eprintln!(
                "places/query: {places} places hold {:.1} MB resident ({:.1} MB of contents, {} bytes a place)",
                b.saturating_sub(a) as f64 / 1e6,
                own as f64 / 1e6,
                b.saturating_sub(a) / places as u64,
            );
        }
        let qs = queries(&index, 64);
        latency_percentiles(&index, places, &config);
        let mut k = 0;
        group.bench_with_input(BenchmarkId::new("kd-tree", places), &index, |b, index| {
            b.iter(|| {
                k = (k + 1) % qs.len();
                black_box(index.query(&qs[k], &config))
            })
        });
        group.bench_with_input(BenchmarkId::new("brute force", places), &index, |b, index| {
            b.iter(|| {
                k = (k + 1) % qs.len();
                black_box(index.query_brute(&qs[k], &config))
            })
        });
    }
    group.finish();
}

fn build(c: &mut Criterion) {
    let mut group = c.benchmark_group("places/build");
    group.sample_size(10);
    let places = 1_000;
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let sweeps: Vec<_> = (0..places)
        .map(|_| random_sweep(&mut rng, SYNTHETIC_LIMIT_M))
        .collect();
    group.throughput(Throughput::Elements(places as u64));
    group.bench_function(BenchmarkId::new("signature and insert", places), |b| {
        b.iter(|| {
            let mut index = PlaceIndex::new(SignatureConfig::default()).expect("defaults");
            let dataset = index.dataset_id("synthetic");
            for (sweep, rop) in sweeps.iter().enumerate() {
                let signature = index.transforms().signature(rop).expect("a full sweep");
                let meta = PlaceMeta {
                    dataset,
                    sweep: sweep as u32,
                    truth: None,
                    profile: None,
                    map_pose: None,
                    look_alike: None,
                };
                index
                    .insert(&signature, SYNTHETIC_LIMIT_M, meta)
                    .expect("same settings");
            }
            black_box(index.len())
        })
    });
    group.finish();
}

criterion_group!(benches, query, build);
criterion_main!(benches);
