//! `pirouette graph optimise`: a g2o pose graph in, the optimised graph out.

use anyhow::{bail, Context, Result};
use pirouette::graph::{init, optimise as solve, Kernel, OptimiseConfig, Residual, Solver};
use pirouette::io::{read_g2o, write_g2o};
use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;

/// Arguments of `pirouette graph optimise`.
#[derive(clap::Args, Debug)]
pub struct GraphOptimiseArgs {
    /// The g2o file to optimise (VERTEX_SE2, EDGE_SE2, FIX lines).
    input: PathBuf,
    /// The g2o file to write: every vertex, optimised, and the same edges.
    #[arg(long)]
    out: PathBuf,
    /// One JSON line of statistics on stdout instead of the summary.
    #[arg(long)]
    json: bool,
    /// gn: Gauss-Newton; lm: Levenberg-Marquardt.
    #[arg(long, default_value = "lm", value_parser = ["gn", "lm"])]
    solver: String,
    /// A robust kernel on the loop closures (every edge but those joining
    /// consecutive poses i → i+1): huber or cauchy.
    #[arg(long, value_parser = ["huber", "cauchy"])]
    robust: Option<String>,
    /// The robust kernel's width, in whitened residual units (standard
    /// deviations).
    #[arg(long, default_value_t = 1.0)]
    robust_width: f64,
    /// At most this many linearise-and-solve steps.
    #[arg(long, default_value_t = 100)]
    max_iterations: usize,
    /// Stop when a step lowers the cost by less than this share of it.
    #[arg(long, default_value_t = 1e-6)]
    relative_decrease: f64,
    /// Starting poses: file (the file's vertices; odometry chaining where
    /// it has none), chain (odometry chaining from the edges) or chordal
    /// (rotations first, then positions, from the edges: for graphs whose
    /// odometry drifts far).
    #[arg(long, default_value = "file", value_parser = ["file", "chain", "chordal"])]
    init: String,
    /// The residual minimised: g2o ((x, y, θ) of z⁻¹·xi⁻¹·xj) or log (its
    /// SE(2) logarithm, as GTSAM takes it). χ² is reported in g2o's either
    /// way; `cost_final` in the one minimised.
    #[arg(long, default_value = "g2o", value_parser = ["g2o", "log"])]
    residual: String,
}

/// Runs `pirouette graph optimise`.
pub fn optimise(a: GraphOptimiseArgs) -> Result<()> {
    if !(a.robust_width.is_finite() && a.robust_width > 0.0) {
        bail!("--robust-width must be a positive number, not {}", a.robust_width);
    }
    if !(a.relative_decrease.is_finite() && a.relative_decrease >= 0.0) {
        bail!(
            "--relative-decrease must be a number at least 0, not {}",
            a.relative_decrease
        );
    }
    super::check_output_file(&a.out)?;
    let start = Instant::now();
    let mut g = read_g2o(&a.input)?;
    let read_s = start.elapsed().as_secs_f64();
    if a.residual == "log" {
        g.graph.residual = Residual::Log;
    }
    if let Some(kind) = &a.robust {
        let kernel = match kind.as_str() {
            "huber" => Kernel::Huber {
                delta: a.robust_width,
            },
            _ => Kernel::Cauchy { c: a.robust_width },
        };
        for e in &mut g.graph.edges {
            if e.to != e.from + 1 {
                e.kernel = kernel;
            }
        }
    }
    let config = OptimiseConfig {
        solver: if a.solver == "gn" {
            Solver::GaussNewton
        } else {
            Solver::LevenbergMarquardt
        },
        max_iterations: a.max_iterations,
        relative_decrease: a.relative_decrease,
        ..OptimiseConfig::default()
    };
    let t0 = Instant::now();
    let what = || format!("{}", a.input.display());
    match a.init.as_str() {
        "chordal" => init::chordal(&mut g.graph).with_context(what)?,
        "chain" => init::chain(&mut g.graph).with_context(what)?,
        _ if !g.has_vertices => init::chain(&mut g.graph).with_context(what)?,
        _ => {}
    }
    let summary = solve(&mut g.graph, &config).with_context(what)?;
    let time_s = t0.elapsed().as_secs_f64();
    write_g2o(&a.out, &g)?;
    if a.json {
        outln!(
            "{}",
            json!({
                "poses": g.graph.poses.len(),
                "edges": g.graph.edges.len(),
                "chi2_initial": summary.chi2_initial,
                "chi2_final": summary.chi2_final,
                "cost_final": summary.cost_final,
                "residual": a.residual,
                "iterations": summary.iterations,
                "time_s": time_s,
                "read_s": read_s,
                "converged": summary.converged,
                "solver": a.solver,
                "init": a.init,
            })
        )?;
    } else {
        outln!(
            "{}: {} poses, {} edges; χ² {:.6e} → {:.6e} in {} iterations ({}), {:.3} s; written to {}",
            a.input.display(),
            g.graph.poses.len(),
            g.graph.edges.len(),
            summary.chi2_initial,
            summary.chi2_final,
            summary.iterations,
            if summary.converged {
                "converged"
            } else {
                "NOT converged: the iteration cap"
            },
            time_s,
            a.out.display()
        )?;
    }
    Ok(())
}
