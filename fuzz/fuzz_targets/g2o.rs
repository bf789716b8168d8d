//! Any bytes as a g2o pose graph: an error naming the line, or a graph that
//! passes its own check and initialises, never a panic.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let path = std::path::Path::new("fuzzed.g2o");
    if let Ok(mut g) = pirouette::io::parse_g2o(data, path) {
        assert!(g.graph.check().is_ok(), "a graph read must pass its check");
        if g.graph.poses.len() <= 10_000 {
            let _ = pirouette::graph::init::chain(&mut g.graph);
        }
    }
});
