//! Pose-graph optimisation: one Gauss-Newton step (linearise, numeric
//! Cholesky with the symbolic analysis reused, solve, update) on the
//! standard M3500 graph (`$PIROUETTE_SHARED/posegraph/manhattan.g2o`,
//! chained from its odometry; skipped with a message without it), and
//! the same step on synthetic grid worlds of 10k, 100k and 1M poses, whose
//! time should grow about linearly with the number of edges.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use pirouette::graph::{init, synthetic, GaussNewton, PoseGraph};
use std::hint::black_box;

fn step_bench(c: &mut Criterion, group_name: &str, name: &str, graph: &PoseGraph) {
    let mut group = c.benchmark_group(group_name);
    group.sample_size(10);
    group.throughput(Throughput::Elements(graph.edges.len() as u64));
    let mut stepper = GaussNewton::new(graph).expect("graph");
    group.bench_function(BenchmarkId::from_parameter(name), |b| {
        b.iter_batched(
            || graph.clone(),
            |mut g| stepper.step(black_box(&mut g)).expect("step"),
            criterion::BatchSize::LargeInput,
        )
    });
    group.finish();
}

fn benches(c: &mut Criterion) {
    match std::env::var_os("PIROUETTE_SHARED") {
        Some(shared) => {
            let path = std::path::Path::new(&shared).join("posegraph/manhattan.g2o");
            let mut g = pirouette::io::read_g2o(&path).expect("manhattan.g2o").graph;
            init::chain(&mut g).expect("chained");
            step_bench(c, "graph_step", "manhattan", &g);
        }
        None => eprintln!("graph_step/manhattan skipped: set PIROUETTE_SHARED to the shared folder"),
    }
    for n in [10_000, 100_000, 1_000_000] {
        let (mut g, _) = synthetic::grid_world(n, 0.05, 0.01, 1);
        init::chain(&mut g).expect("chained");
        step_bench(
            c,
            "graph_scaling",
            &format!("{n}_poses_{}_edges", g.edges.len()),
            &g,
        );
    }
}

criterion_group!(graph_benches, benches);
criterion_main!(graph_benches);
