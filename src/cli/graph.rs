//! `pirouette graph optimise`: a g2o pose graph in, the optimised graph out.

use super::choices::{Init, Outliers, ResidualChoice, RobustKernel, SolverChoice};
use anyhow::{bail, Context, Result};
use pirouette::graph::outliers::{solve_from_starts, OutlierConfig, Start};
use pirouette::graph::{Kernel, OptimiseConfig};
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
    /// The solver.
    #[arg(long, value_enum, default_value_t = SolverChoice::Lm)]
    solver: SolverChoice,
    /// A robust kernel on the loop closures (every edge but those joining
    /// consecutive poses i → i+1). In place of `--outliers reject`.
    #[arg(long, value_enum)]
    robust: Option<RobustKernel>,
    /// Wrong loop closures: reject (where a loop closure's χ² at the
    /// solution is above 16.27, χ²₃ at 99.9 %, the wrong ones are found by
    /// graduated non-convexity and left out of the solve; the output keeps
    /// every edge) or keep (plain least squares over every edge). Default:
    /// reject, keep with --robust.
    #[arg(long, value_enum)]
    outliers: Option<Outliers>,
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
    /// Starting poses: best (file and chordal both solved, the lower cost
    /// kept), file (the file's vertices; odometry chaining where it has
    /// none), chain (odometry chaining from the edges) or chordal
    /// (rotations first, then positions, from the edges: for graphs whose
    /// odometry drifts far).
    #[arg(long, value_enum, default_value_t = Init::Best)]
    init: Init,
    /// The residual minimised: g2o ((x, y, θ) of z⁻¹·xi⁻¹·xj) or log (its
    /// SE(2) logarithm, as GTSAM takes it). χ² is reported in g2o's either
    /// way; `cost_final` in the one minimised.
    #[arg(long, value_enum, default_value_t = ResidualChoice::G2o)]
    residual: ResidualChoice,
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
    if let Some(pose) = g.graph.unreached() {
        bail!(
            "{}: pose {pose} is not joined to the held pose {} by any chain of edges: where one part lies relative to the other is unknown (optimise each part as a graph of its own)",
            a.input.display(),
            g.graph.held
        );
    }
    g.graph.residual = a.residual.into();
    let reject = match (a.outliers, a.robust) {
        (Some(Outliers::Reject), Some(_)) => {
            bail!("--outliers reject and --robust are two answers to wrong loop closures: give one")
        }
        (Some(o), _) => o == Outliers::Reject,
        (None, robust) => robust.is_none(),
    };
    if let Some(kind) = a.robust {
        let kernel = match kind {
            RobustKernel::Huber => Kernel::Huber {
                delta: a.robust_width,
            },
            RobustKernel::Cauchy => Kernel::Cauchy { c: a.robust_width },
        };
        for e in &mut g.graph.edges {
            if e.to != e.from + 1 {
                e.kernel = kernel;
            }
        }
    }
    let config = OptimiseConfig {
        solver: a.solver.into(),
        max_iterations: a.max_iterations,
        relative_decrease: a.relative_decrease,
        ..OptimiseConfig::default()
    };
    let t0 = Instant::now();
    let what = || format!("{}", a.input.display());
    let given = if g.has_vertices {
        Start::Given
    } else {
        Start::Chain
    };
    let starts: Vec<Start> = match a.init {
        Init::Chordal => vec![Start::Chordal],
        Init::Chain => vec![Start::Chain],
        Init::File => vec![given],
        Init::Best => vec![given, Start::Chordal],
    };
    // Loop closures: every edge but those joining consecutive poses.
    let loops: Vec<usize> = (g.graph.edges.iter().enumerate())
        .filter(|(_, e)| e.to != e.from + 1)
        .map(|(k, _)| k)
        .collect();
    let outliers = OutlierConfig {
        solve: config.clone(),
        ..OutlierConfig::default()
    };
    let solved = solve_from_starts(
        &mut g.graph,
        &starts,
        &loops,
        reject.then_some(&outliers),
        &config,
    )
    .with_context(what)?;
    let summary = &solved.rejection.summary;
    let time_s = t0.elapsed().as_secs_f64();
    write_g2o(&a.out, &g)?;
    let rejected = solved.rejection.rejected.len();
    let chi2_all = g.graph.chi2();
    if a.json {
        let tried: serde_json::Map<String, serde_json::Value> = (solved.tried.iter())
            .map(|t| (t.start.name().to_owned(), json!(t.cost)))
            .collect();
        outln!(
            "{}",
            json!({
                "poses": g.graph.poses.len(),
                "edges": g.graph.edges.len(),
                "chi2_initial": solved.chi2_start,
                "chi2_final": chi2_all,
                "chi2_kept": summary.chi2_final,
                "cost_final": summary.cost_final,
                "residual": super::choices::name(a.residual),
                "iterations": summary.iterations,
                "time_s": time_s,
                "read_s": read_s,
                "converged": summary.converged,
                "solver": super::choices::name(a.solver),
                "init": solved.start.name(),
                "init_tried": tried,
                "outliers": if reject { "reject" } else { "keep" },
                "loop_closures": loops.len(),
                "rejected": rejected,
                "inconsistent": solved.rejection.inconsistent.len(),
                "gnc_rounds": solved.rejection.rounds,
            })
        )?;
    } else {
        let tried: Vec<String> = (solved.tried.iter())
            .map(|t| format!("{} {:.6e}", t.start.name(), t.cost))
            .collect();
        outln!(
            "{}: {} poses, {} edges; χ² {:.6e} → {:.6e} in {} iterations ({}), {:.3} s; started from {} (costs: {}); written to {}",
            a.input.display(),
            g.graph.poses.len(),
            g.graph.edges.len(),
            solved.chi2_start,
            chi2_all,
            summary.iterations,
            if summary.converged {
                "converged"
            } else {
                "NOT converged: the iteration cap"
            },
            time_s,
            solved.start.name(),
            tried.join(", "),
            a.out.display()
        )?;
        if rejected > 0 {
            outln!(
                "{rejected} of {} loop closures left out as wrong ({} inconsistent with the largest consistent set, the rest by graduated non-convexity in {} rounds); χ² over the edges kept {:.6e}",
                loops.len(),
                solved.rejection.inconsistent.len(),
                solved.rejection.rounds,
                summary.chi2_final
            )?;
        }
    }
    Ok(())
}
