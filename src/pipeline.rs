//! Whole-dataset runs of the engine.

use anyhow::{Context, Result};
use pirouette_camera::ModelKind;
use pirouette_io::{Dataset, Motion};
use pirouette_profile::sweep::{assemble, join, pivot_from_turns, Sweep, SweepConfig};
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
    let mut sets = profiles_with(ds, &[extractor], progress)?;
    Ok(sets.pop().expect("one extractor"))
}

/// The profile of every frame by each of `extractors` (one list per
/// extractor, in capture order), each image read once.
fn profiles_with(
    ds: &Dataset,
    extractors: &[&RopExtractor],
    progress: impl Fn() + Sync,
) -> Result<Vec<Vec<Rop>>> {
    let frames: Vec<Vec<Rop>> = (0..ds.manifest.frames.len())
        .into_par_iter()
        .map(|i| {
            let img = ds.load_image(i)?;
            let name = || ds.image_path(i).display().to_string();
            let rops = extractors
                .iter()
                .map(|e| e.rop(&img).with_context(name))
                .collect::<Result<Vec<Rop>>>()?;
            progress();
            Ok(rops)
        })
        .collect::<Result<_>>()?;
    let mut sets: Vec<Vec<Rop>> = extractors
        .iter()
        .map(|_| Vec::with_capacity(frames.len()))
        .collect();
    for rops in frames {
        for (set, rop) in sets.iter_mut().zip(rops) {
            set.push(rop);
        }
    }
    Ok(sets)
}

/// Every frame's profiles for sweeps and maps (see [`sweep_profiles`]).
pub struct SweepProfiles {
    /// The extractor of `rops` (camera tables, settings).
    pub extractor: RopExtractor,
    /// One profile per frame, as the settings give it: for the map's grid.
    pub rops: Vec<Rop>,
    /// One profile per frame for comparing views (a sweep registered
    /// against the map of the others): the settings'
    /// [`VisionConfig::for_comparing`]; a copy of `rops` where those are
    /// the same.
    pub compared: Vec<Rop>,
    /// One profile per frame to verify turns on: the settings'
    /// [`VisionConfig::for_matching`], with the ranges of `compared` as
    /// the intermittent cue's (`Rop::intermittent_m`); a copy of
    /// `compared` where the matching settings are the same.
    pub matched: Vec<Rop>,
}

/// Profiles every frame with `config` for the map, with its comparing
/// settings for registration and with its matching settings for the turns,
/// each image read once; `progress` is called once per finished frame.
pub fn sweep_profiles(
    ds: &Dataset,
    model: Option<ModelKind>,
    config: VisionConfig,
    progress: impl Fn() + Sync,
) -> Result<SweepProfiles> {
    let comparing = config
        .for_comparing()
        .map(|c| extractor(ds, model, c))
        .transpose()?;
    let matching = config
        .for_matching()
        .map(|c| extractor(ds, model, c))
        .transpose()?;
    let extractor = extractor(ds, model, config)?;
    let extractors: Vec<&RopExtractor> = [Some(&extractor), comparing.as_ref(), matching.as_ref()]
        .into_iter()
        .flatten()
        .collect();
    let mut sets = profiles_with(ds, &extractors, progress)?.into_iter();
    let rops = sets.next().expect("the map's extractor");
    let compared = match comparing {
        Some(_) => sets.next().expect("the comparing extractor"),
        None => rops.clone(),
    };
    // The cue left out of the matched profiles is an intermittent one:
    // its ranges go with them, compared only where both views have one.
    let matched = match matching {
        Some(_) => {
            let mut matched = sets.next().expect("the matching extractor");
            for (m, r) in matched.iter_mut().zip(&compared) {
                m.intermittent_m = r.range_m.clone();
            }
            matched
        }
        None => compared.clone(),
    };
    Ok(SweepProfiles {
        extractor,
        rops,
        compared,
        matched,
    })
}

/// One sweep of a dataset: its frames (indices into the manifest, in
/// capture order) and their assembly.
#[derive(Debug, Clone)]
pub struct DatasetSweep {
    /// The sweep's id in the manifest.
    pub id: u32,
    /// Frame indices of the sweep.
    pub frames: Vec<usize>,
    /// Verified turns, headings, loop closure and the 360° profile.
    pub sweep: Sweep,
}

/// Groups the frames of a dataset into sweeps (a new sweep starts at a
/// frame without a commanded turn: the first frame or a forward move) and
/// assembles each from its profiles, about the point the robot turns
/// about as its own turns measure it ([`pivot_from_turns`]): assembled
/// about `config`'s pivot, then again about the one their verified turns'
/// shifts give, until it moves less than a tenth of a millimetre (each
/// round refines the turns from the shifts the last round's pivot
/// predicts, and their robust fits keep the inliers near there). The turns
/// are verified on `matched` (one profile per frame, as `rops`: see
/// [`sweep_profiles`]; `rops` itself where there are no others), and
/// each sweep's 360° profile is joined from `rops`. The least noise a
/// match may measure
/// ([`pirouette_profile::matching::MatchConfig::min_inverse_range_sigma`])
/// is a tenth of the least change of inverse range between two adjacent
/// rows of `extractor`'s camera, in place of `config`'s: a boundary is
/// found to about a tenth of a row. Returns the sweeps and the settings
/// they were assembled with.
///
/// # Panics
/// When `matched` and `rops` differ in length.
pub fn sweeps(
    ds: &Dataset,
    extractor: &RopExtractor,
    rops: &[Rop],
    matched: &[Rop],
    config: &SweepConfig,
) -> (Vec<DatasetSweep>, SweepConfig) {
    assert_eq!(rops.len(), matched.len(), "one matched profile per frame");
    let mut config = config.clone();
    if let Some(step) = extractor.table().finest_inverse_range_step() {
        config.matching.min_inverse_range_sigma = (step * SUB_PIXEL_ROWS) as f32;
    }
    // Each sweep's frames, commands and profiles, gathered once for every
    // round.
    let mut groups: Vec<(u32, Vec<usize>)> = Vec::new();
    for (i, f) in ds.manifest.frames.iter().enumerate() {
        let turn = matches!(f.motion, Some(Motion::Turn { .. }));
        match groups.last_mut() {
            Some((_, frames)) if turn => frames.push(i),
            _ => groups.push((f.sweep, vec![i])),
        }
    }
    let inputs: Vec<(Vec<Option<f64>>, Vec<Rop>)> = groups
        .iter()
        .map(|(_, frames)| {
            (
                commanded_turns(ds, frames),
                frames.iter().map(|&i| matched[i].clone()).collect(),
            )
        })
        .collect();
    let assemble_all = |config: &SweepConfig| -> Vec<DatasetSweep> {
        groups
            .par_iter()
            .zip(&inputs)
            .map(|((id, frames), (commanded, sweep_rops))| DatasetSweep {
                id: *id,
                frames: frames.clone(),
                sweep: assemble(sweep_rops, commanded, config),
            })
            .collect()
    };
    let mut sweeps = assemble_all(&config);
    for _ in 0..PIVOT_ROUNDS {
        let turns = sweeps.iter().flat_map(|s| s.sweep.turns.iter().flatten());
        let Some(pivot) = pivot_from_turns(turns, TURN_SHIFT_FLOOR_M) else {
            break;
        };
        let old = config.matching.pivot_m;
        config.matching.pivot_m = pivot;
        sweeps = assemble_all(&config);
        if (pivot[0] - old[0]).hypot(pivot[1] - old[1]) < 1e-4 {
            break;
        }
    }
    // Assembly joined the matched profiles; where the map's differ, the
    // 360° profile is theirs.
    if !std::ptr::eq(rops, matched) {
        for s in &mut sweeps {
            let own: Vec<Rop> = s.frames.iter().map(|&i| rops[i].clone()).collect();
            s.sweep.rop = join(&own, &s.sweep.heading_rad);
        }
    }
    (sweeps, config)
}

/// How finely a boundary is found, in image rows: the least noise
/// [`sweeps`] lets a match measure.
const SUB_PIXEL_ROWS: f64 = 0.1;

/// The most rounds of [`sweeps`]' pivot estimate.
const PIVOT_ROUNDS: usize = 10;

/// The least error of one turn's measured shift, metres (each way): the
/// profiles' information about it counts only bin noise, but their range
/// errors of a few millimetres are shared by neighbouring frames.
const TURN_SHIFT_FLOOR_M: f64 = 0.002;

/// The commanded turn before each of a sweep's frames, radians: `None` for
/// its first frame (which starts the sweep, whatever its motion).
pub fn commanded_turns(ds: &Dataset, frames: &[usize]) -> Vec<Option<f64>> {
    frames
        .iter()
        .enumerate()
        .map(|(k, &i)| match (k, ds.manifest.frames[i].motion) {
            (1.., Some(Motion::Turn { turn_deg })) => Some(turn_deg.to_radians()),
            _ => None,
        })
        .collect()
}
