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
    /// Instead of the comparison: write each image of the dataset with the
    /// floor grid its camera model projects onto it (lines every 10 cm,
    /// range rings every 25 cm, bearings every 10°), to check a
    /// calibration by eye, into this folder.
    #[arg(long)]
    overlay: Option<PathBuf>,
    /// The model the overlay draws (default: the most accurate the
    /// dataset allows).
    #[arg(long, value_enum)]
    model: Option<super::choices::Model>,
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
    if let Some(dir) = &a.overlay {
        return overlay(&ds, dir, a.model.map(Into::into));
    }
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

/// `pirouette camera --overlay DIR`: each image with its projected floor
/// grid, `DIR/<sweep>-<k>-overlay.png`.
fn overlay(
    ds: &pirouette::io::Dataset,
    dir: &std::path::Path,
    model: Option<pirouette::camera::ModelKind>,
) -> Result<()> {
    super::check_output_dir(dir)?;
    let camera = ds.camera(model)?;
    let reach = 2.0 * ds.manifest.max_range;
    let bar = super::progress(ds.manifest.frames.len(), "overlay");
    for (i, f) in ds.manifest.frames.iter().enumerate() {
        let img = ds.load_image(i)?;
        let picture = pirouette::plot::calibration_figure(&camera, &img, reach, &f.image);
        let stem = std::path::Path::new(&f.image)
            .strip_prefix("frames")
            .unwrap_or(std::path::Path::new(&f.image))
            .with_extension("")
            .to_string_lossy()
            .replace(['/', '\\'], "-");
        let mut bytes = Vec::new();
        picture.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png)?;
        pirouette::io::atomic_write(&dir.join(format!("{stem}-overlay.png")), &bytes)?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    outln!(
        "{} images with the floor grid written to {} (lines every 10 cm, rings every 25 cm, bearings every 10°)",
        ds.manifest.frames.len(),
        dir.display()
    )?;
    Ok(())
}
