//! Writing pictures to a folder.

use anyhow::{Context, Result};
use pirouette::io::{atomic_write, Dataset};
use pirouette::plot;
use pirouette::profile::Rop;
use pirouette::vision::RopExtractor;
use rayon::prelude::*;
use std::path::Path;

fn save_png(img: &image::RgbImage, path: &Path) -> Result<()> {
    let mut bytes = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png)?;
    atomic_write(path, &bytes)?;
    Ok(())
}

/// Per frame: `<sweep>-<k>-rop.png` (the ROP diagram, with the truth when
/// the dataset has it), `<sweep>-<k>-floor.png` (the top-down floor view) and
/// `<sweep>-<k>-boundary.png` (the image with the boundary drawn).
pub fn profile_plots(
    ds: &Dataset,
    ex: &RopExtractor,
    camera: &pirouette::camera::Camera,
    rops: &[Rop],
    dir: &Path,
) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let bar = super::progress(rops.len(), "plot");
    (0..rops.len()).into_par_iter().try_for_each(|i| -> Result<()> {
        let stem = Path::new(&ds.manifest.frames[i].image)
            .strip_prefix("frames")
            .unwrap_or(Path::new(&ds.manifest.frames[i].image))
            .with_extension("")
            .to_string_lossy()
            .replace(['/', '\\'], "-");
        let img = ds.load_image(i)?;
        let truth = ds.truth_rop(i)?.map(|t| t.to_rop(ds.manifest.max_range as f32));
        let frame = &ds.manifest.frames[i].image;
        save_png(
            &plot::rop_figure(&rops[i], truth.as_ref(), frame),
            &dir.join(format!("{stem}-rop.png")),
        )?;
        save_png(
            &plot::floor_figure(camera, &img, &rops[i], frame),
            &dir.join(format!("{stem}-floor.png")),
        )?;
        let boundaries = ex.boundaries(&img)?;
        save_png(
            &plot::boundary_figure(&img, &boundaries, frame),
            &dir.join(format!("{stem}-boundary.png")),
        )?;
        bar.inc(1);
        Ok(())
    })?;
    bar.finish_and_clear();
    Ok(())
}

/// One top-down diagram per sweep: `sweep-<id>.png`.
pub fn sweep_plots(sweeps: &[pirouette::frame::DatasetSweep], dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    for s in sweeps {
        save_png(
            &plot::sweep_figure(&s.sweep.rop, &s.id.to_string()),
            &dir.join(format!("sweep-{:02}.png", s.id)),
        )?;
    }
    Ok(())
}
