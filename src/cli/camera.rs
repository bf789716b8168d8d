//! `pirouette camera`.

use anyhow::{bail, Result};
use pirouette::camera_report::compare;
use std::path::PathBuf;

/// Arguments of `pirouette camera`.
#[derive(clap::Args, Debug)]
pub struct CameraArgs {
    /// The dataset folder.
    dataset: PathBuf,
    /// Rows per band of the report.
    #[arg(long, default_value_t = 20)]
    band_rows: u32,
    /// Compare only floor points within this range (default: twice the dataset's max range), metres.
    #[arg(long)]
    range_limit: Option<f64>,
    /// JSON Lines on stdout, one band per line.
    #[arg(long)]
    json: bool,
}

/// `pirouette camera`.
pub fn camera(a: CameraArgs) -> Result<()> {
    if a.band_rows == 0 {
        bail!("--band-rows must be at least 1");
    }
    if let Some(limit) = a.range_limit {
        if !(limit.is_finite() && limit > 0.0) {
            bail!("--range-limit {limit} m must be a positive number");
        }
    }
    let ds = super::open_dataset(&a.dataset)?;
    let cam = &ds.manifest.camera;
    let Some(pinhole) = cam.pinhole_model() else {
        bail!(
            "{}: camera.pinhole is absent, so there is nothing to compare the paper's model with",
            ds.manifest_path().display()
        );
    };
    let limit = a.range_limit.unwrap_or(2.0 * ds.manifest.max_range);
    let bands = compare(&cam.ipm_model(), &pinhole, a.band_rows, limit);
    if a.json {
        for b in &bands {
            outln!("{}", serde_json::to_string(b)?)?;
        }
        return Ok(());
    }
    outln!("paper model (b, h, d, w) against pinhole, floor within {limit:.2} m")?;
    outln!(
        "{:>9} {:>9} {:>11} {:>11} {:>11} {:>8}",
        "rows",
        "range m",
        "median cm",
        "max cm",
        "range bias",
        "pixels"
    )?;
    for b in &bands {
        outln!(
            "{:>4}-{:<4} {:>9.3} {:>11.2} {:>11.2} {:>10.2}% {:>8}",
            b.v_start,
            b.v_end - 1,
            b.median_range_m,
            b.median_gap_m * 100.0,
            b.max_gap_m * 100.0,
            b.median_range_bias * 100.0,
            b.pixels
        )?;
    }
    Ok(())
}
