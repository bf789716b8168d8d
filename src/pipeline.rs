//! Whole-dataset runs of the engine.

use anyhow::{Context, Result};
use pirouette_camera::ModelKind;
use pirouette_io::Dataset;
use pirouette_profile::Rop;
use pirouette_vision::{RopExtractor, VisionConfig};
use rayon::prelude::*;

/// The extractor for a dataset's camera (`model`, or the most accurate
/// one) and soft range limit.
pub fn extractor(ds: &Dataset, model: Option<ModelKind>, config: VisionConfig) -> Result<RopExtractor> {
    let camera = ds.camera(model)?;
    RopExtractor::try_new(&camera, ds.manifest.max_range, config)
        .with_context(|| format!("{}: camera", ds.manifest_path().display()))
}

/// The profile of every frame, in capture order (frames in parallel).
/// `progress` is called once per finished frame.
pub fn profiles(ds: &Dataset, extractor: &RopExtractor, progress: impl Fn() + Sync) -> Result<Vec<Rop>> {
    (0..ds.manifest.frames.len())
        .into_par_iter()
        .map(|i| {
            let img = ds.load_image(i)?;
            let rop = extractor
                .rop(&img)
                .with_context(|| ds.image_path(i).display().to_string())?;
            progress();
            Ok(rop)
        })
        .collect()
}
