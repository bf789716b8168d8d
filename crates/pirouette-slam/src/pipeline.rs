//! The engine's run of a dataset, as library functions.
//!
//! [`map_dataset`] is the whole data path: frames in, profiles, verified
//! turns and sweeps ([`sweep_dataset`]), registration, the grid. The
//! command line and the tests call these; [`PipelineConfig`] holds every
//! setting, each default in one place. The stages below them
//! ([`sweep_profiles`], [`sweeps`], [`crate::mapping::build_map`]) are
//! public for benchmarks and for callers that need one stage alone.

use crate::error::{Result, SlamError};
use crate::frame::{camera_frames, camera_motions, DatasetSweep, Frame, FrameProfiles};
use crate::mapping::{build_map, check_extent, MapConfig, MapRun};
use pirouette_camera::ModelKind;
use pirouette_io::{Dataset, Motion};
use pirouette_profile::matching::MatchView;
use pirouette_profile::sweep::{assemble_views, join, pivot_from_turns, SweepConfig};
use pirouette_profile::Rop;
use pirouette_vision::compass::{self, BearingProfile};
use pirouette_vision::{RopExtractor, VisionConfig};
use rayon::prelude::*;

/// The bin width of the profiles that sweeps and maps are made of,
/// degrees: one image column spans about 0.2°, and bins that fine let
/// matching resolve a fraction of a degree.
pub const SWEEP_BIN_DEG: f64 = 0.25;

/// Every setting of a run.
#[derive(Debug, Clone)]
pub struct PipelineConfig {
    /// The camera model: `None` for the most accurate the dataset allows.
    pub model: Option<ModelKind>,
    /// Profiles from images; its bin width is the sweeps' and the map's.
    pub vision: VisionConfig,
    /// Turn verification and sweep assembly.
    pub sweep: SweepConfig,
    /// Registration and the grid. Its sweep settings are replaced by those
    /// the sweeps were assembled with (the pivot they measured).
    pub map: MapConfig,
}

impl Default for PipelineConfig {
    /// The most accurate camera model; vision's defaults with
    /// [`SWEEP_BIN_DEG`] bins; sweeps' and maps' defaults.
    fn default() -> Self {
        Self {
            model: None,
            vision: VisionConfig {
                bin_width_rad: SWEEP_BIN_DEG.to_radians(),
                ..VisionConfig::default()
            },
            sweep: SweepConfig::default(),
            map: MapConfig::default(),
        }
    }
}

impl PipelineConfig {
    /// Refuses settings that cannot work together, before any data is
    /// read: the vision settings' own checks, a turn window wider than one
    /// bin (turns are matched bin against bin, all at the vision settings'
    /// width), a far reach of at least the soft limit, and a grid that can
    /// be made.
    pub fn check(&self) -> Result<()> {
        self.vision.validate()?;
        let bin = self.vision.bin_width_rad;
        let window = self.sweep.matching.window_rad;
        if !(window.is_finite() && window >= bin) {
            return Err(SlamError::settings(
                "pipeline",
                format!(
                    "the turn window ±{:.3}° is narrower than one profile bin ({:.3}°)",
                    window.to_degrees(),
                    bin.to_degrees()
                ),
            ));
        }
        if !(self.map.far_reach.is_finite() && self.map.far_reach >= 1.0) {
            return Err(SlamError::settings(
                "pipeline",
                format!("far reach {} is not a factor of at least 1", self.map.far_reach),
            ));
        }
        if !self.map.revisit.is_valid() {
            return Err(SlamError::settings(
                "pipeline",
                format!(
                    "the revisit test needs a matched share in [0, 1], a rival gap of 0 or more and positive tolerances: {:?}",
                    self.map.revisit
                ),
            ));
        }
        pirouette_grid::OccupancyGrid::new(self.map.grid.clone())?;
        Ok(())
    }
}

/// What a run reports as it goes: a camera's once per frame profiled
/// (from several threads), once per step of the map
/// ([`crate::mapping::progress_steps`] of them); a laser log's once per
/// scan read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// A frame's profiles are made.
    Profiled,
    /// A step of registration is done.
    Placed,
    /// A laser scan is read and registered (or left out by the motion
    /// filter).
    Scan,
}

/// The sweeps of a dataset: one begins at every frame that no turn
/// reaches (the first, and each after a forward move).
pub fn sweep_count(ds: &Dataset) -> usize {
    (ds.manifest.frames.iter())
        .filter(|f| !matches!(f.motion, Some(Motion::Turn { .. })))
        .count()
}

/// A dataset's profiles and sweeps ([`sweep_dataset`]).
pub struct Swept {
    /// The extractor of the map's profiles (camera tables, settings).
    pub extractor: RopExtractor,
    /// The frames, in capture order, with their profiles.
    pub frames: Vec<Frame>,
    /// The sweeps, their turns verified.
    pub sweeps: Vec<DatasetSweep>,
    /// The sweep settings they were assembled with (the pivot measured).
    pub sweep_config: SweepConfig,
    /// The camera's blind distance, metres: the floor nearer is not seen.
    pub blind_m: f64,
}

impl Swept {
    /// The map settings of `config` with the sweeps' own settings.
    pub fn map_config(&self, config: &PipelineConfig) -> MapConfig {
        MapConfig {
            sweep: self.sweep_config.clone(),
            ..config.map.clone()
        }
    }
}

/// A mapped dataset ([`map_dataset`]).
pub struct Mapped {
    /// What the map was made of.
    pub swept: Swept,
    /// The map settings used.
    pub config: MapConfig,
    /// The map, poses and registrations.
    pub map: MapRun,
}

/// Settings checked ([`PipelineConfig::check`]), then frames in,
/// profiles, verified turns and 360° sweeps.
pub fn sweep_dataset(
    ds: &Dataset,
    config: &PipelineConfig,
    progress: &(dyn Fn(Stage) + Sync),
) -> Result<Swept> {
    config.check()?;
    // Every frame's profiles: for the grid, for comparing views, for turns.
    let SweepProfiles { extractor, frames } =
        sweep_profiles(ds, config.model, config.vision.clone(), || {
            progress(Stage::Profiled)
        })?;
    // The back end's input: each frame's profiles and motion.
    let frames = camera_frames(ds, frames);
    // Turns verified and sweeps assembled, about the pivot the turns
    // measure, to a tenth of the camera's finest row step.
    let least_sigma = extractor
        .table()
        .finest_inverse_range_step()
        .map(|step| (step * SUB_PIXEL_ROWS) as f32);
    let (sweeps, sweep_config) = sweeps(&frames, least_sigma, &config.sweep);
    // The floor nearer than the bottom row is not seen.
    let blind_m = extractor.table().blind_range().ok_or_else(|| {
        SlamError::Input {
            problem: "the camera sees no floor".into(),
        }
        .at(ds.manifest_path().display().to_string())
    })?;
    Ok(Swept {
        extractor,
        frames,
        sweeps,
        sweep_config,
        blind_m,
    })
}

/// The whole run: settings checked ([`PipelineConfig::check`]), frames
/// in, profiles, sweeps, registration, the grid.
pub fn map_dataset(
    ds: &Dataset,
    config: &PipelineConfig,
    progress: &(dyn Fn(Stage) + Sync),
) -> Result<Mapped> {
    config.check()?;
    let name = || ds.manifest_path().display().to_string();
    // A route whose commands alone make too large a map, before any image.
    check_extent(
        &camera_motions(ds),
        ds.manifest.max_range * config.map.far_reach,
        &config.map.grid,
    )
    .map_err(|e| e.at(name()))?;
    // Profiles and sweeps.
    let swept = sweep_dataset(ds, config, progress)?;
    // Sweeps registered against each other, their frames fused in the grid.
    let map_config = swept.map_config(config);
    let map = map_swept(ds, &swept, &map_config, progress)?;
    Ok(Mapped {
        swept,
        config: map_config,
        map,
    })
}

/// Registration and the grid of a dataset's sweeps ([`sweep_dataset`]),
/// with map settings `config` (see [`Swept::map_config`]).
pub fn map_swept(
    ds: &Dataset,
    swept: &Swept,
    config: &MapConfig,
    progress: &(dyn Fn(Stage) + Sync),
) -> Result<MapRun> {
    build_map(&swept.frames, &swept.sweeps, swept.blind_m, config, || {
        progress(Stage::Placed)
    })
    .map_err(|e| e.at(ds.manifest_path().display().to_string()))
}

/// The extractor for a dataset's camera (`model`, or the most accurate
/// one) and soft range limit.
pub fn extractor(ds: &Dataset, model: Option<ModelKind>, config: VisionConfig) -> Result<RopExtractor> {
    let camera = ds.camera(model)?;
    RopExtractor::try_new(&camera, ds.manifest.max_range, config)
        .map_err(|e| SlamError::from(e).at(format!("{}: camera", ds.manifest_path().display())))
}

/// The profile of every frame, in capture order (frames in parallel).
/// `progress` is called once per finished frame.
pub fn profiles(ds: &Dataset, extractor: &RopExtractor, progress: impl Fn() + Sync) -> Result<Vec<Rop>> {
    let mut sets = profiles_with(ds, &[extractor], progress)?;
    Ok(sets.0.pop().expect("one extractor"))
}

/// Each frame's bearing profile for the visual compass (empty where no
/// frame needs it).
type Compass = Vec<Option<BearingProfile>>;

/// The profile of every frame by each of `extractors` (one list per
/// extractor, in capture order), each image read once, and where a
/// frame's motion is unknown every frame's bearing profile.
fn profiles_with(
    ds: &Dataset,
    extractors: &[&RopExtractor],
    progress: impl Fn() + Sync,
) -> Result<(Vec<Vec<Rop>>, Compass)> {
    // The visual compass, where a frame after the first has no motion.
    let frames = &ds.manifest.frames;
    let compass_camera = frames
        .iter()
        .skip(1)
        .any(|f| f.motion.is_none())
        .then(|| ds.manifest.camera.pinhole_model())
        .flatten();
    let (frames, compass): (Vec<Vec<Rop>>, Compass) = (0..frames.len())
        .into_par_iter()
        .map(|i| {
            let img = ds.load_image(i)?;
            let name = || ds.image_path(i).display().to_string();
            let rops = extractors
                .iter()
                .map(|e| e.rop(&img).map_err(|e| SlamError::from(e).at(name())))
                .collect::<Result<Vec<Rop>>>()?;
            let bearings = (compass_camera.as_ref()).and_then(|c| compass::bearing_profile(&img, c));
            progress();
            Ok((rops, bearings))
        })
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .unzip();
    let compass = if compass_camera.is_some() {
        compass
    } else {
        Vec::new()
    };
    let mut sets: Vec<Vec<Rop>> = extractors
        .iter()
        .map(|_| Vec::with_capacity(frames.len()))
        .collect();
    for rops in frames {
        for (set, rop) in sets.iter_mut().zip(rops) {
            set.push(rop);
        }
    }
    Ok((sets, compass))
}

/// Every frame's profiles for sweeps and maps (see [`sweep_profiles`]).
pub struct SweepProfiles {
    /// The extractor of `rops` (camera tables, settings).
    pub extractor: RopExtractor,
    /// The profiles.
    pub frames: FrameProfiles,
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
    let (sets, compass) = profiles_with(ds, &extractors, progress)?;
    let mut sets = sets.into_iter();
    let rops = sets.next().expect("the map's extractor");
    let compared = match comparing {
        Some(_) => sets.next().expect("the comparing extractor"),
        None => rops.clone(),
    };
    // The cue left out of the matched profiles is an intermittent one:
    // its ranges go with them, compared only where both views have one.
    let (matched, cues) = match matching {
        Some(_) => {
            let matched = sets.next().expect("the matching extractor");
            let cues = compared.iter().map(|r| r.range_m.clone()).collect();
            (matched, cues)
        }
        None => (compared.clone(), Vec::new()),
    };
    Ok(SweepProfiles {
        extractor,
        frames: FrameProfiles {
            rops,
            compared,
            matched,
            cues,
            compass,
        },
    })
}

/// Groups frames into sweeps (a new sweep starts at a frame that did not
/// turn in place: the first frame, a forward move, a general move that
/// shifts, an unknown motion) and assembles each
/// from its profiles, about the point the robot turns about as its own
/// turns measure it ([`pivot_from_turns`]): assembled about `config`'s
/// pivot, then again about the one their verified turns' shifts give,
/// until it moves less than a tenth of a millimetre (each round refines
/// the turns from the shifts the last round's pivot predicts, and their
/// robust fits keep the inliers near there). The turns are verified on
/// each frame's `matched` profile and each sweep's 360° profile is joined
/// from its `rop`s. `least_sigma`, where given, is the least noise a match
/// may measure
/// ([`pirouette_profile::matching::MatchConfig::min_inverse_range_sigma`])
/// in place of `config`'s (what the sensor resolves). Returns the sweeps
/// and the settings they were assembled with.
pub fn sweeps(
    frames: &[Frame],
    least_sigma: Option<f32>,
    config: &SweepConfig,
) -> (Vec<DatasetSweep>, SweepConfig) {
    let mut config = config.clone();
    if let Some(sigma) = least_sigma {
        config.matching.min_inverse_range_sigma = sigma;
    }
    // Each sweep's frames, commands and profiles, gathered once for every
    // round.
    let mut groups: Vec<(u32, Vec<usize>)> = Vec::new();
    for (i, f) in frames.iter().enumerate() {
        let turn = f.commanded().is_some_and(|m| m.is_in_place_turn());
        match groups.last_mut() {
            Some((_, members)) if turn => members.push(i),
            _ => groups.push((f.sweep, vec![i])),
        }
    }
    let inputs: Vec<(Vec<Option<f64>>, Vec<MatchView>)> = groups
        .iter()
        .map(|(_, members)| {
            (
                commanded_turns(|i| frames[i].commanded(), members),
                members.iter().map(|&i| frames[i].match_view()).collect(),
            )
        })
        .collect();
    let assemble_all = |config: &SweepConfig| -> Vec<DatasetSweep> {
        groups
            .par_iter()
            .zip(&inputs)
            .map(|((id, members), (commanded, sweep_rops))| DatasetSweep {
                id: *id,
                frames: members.clone(),
                sweep: assemble_views(sweep_rops, commanded, config),
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
    for s in &mut sweeps {
        if s.frames.iter().any(|&i| frames[i].rop != frames[i].matched) {
            s.sweep.rop = join(s.frames.iter().map(|&i| &frames[i].rop), &s.sweep.heading_rad);
        }
    }
    (sweeps, config)
}

/// How finely a boundary is found, in image rows: the least noise a match
/// of camera profiles may measure, in rows of the camera's finest step.
const SUB_PIXEL_ROWS: f64 = 0.1;

/// The most rounds of [`sweeps`]' pivot estimate.
const PIVOT_ROUNDS: usize = 10;

/// The least error of one turn's measured shift, metres (each way): the
/// profiles' information about it counts only bin noise, but their range
/// errors of a few millimetres are shared by neighbouring frames.
const TURN_SHIFT_FLOOR_M: f64 = 0.002;

/// The commanded turn before each of a sweep's frames (`members`, whose
/// motions `motion` gives by frame index), radians: `None` for
/// its first frame (which starts the sweep, whatever its motion).
pub fn commanded_turns(motion: impl Fn(usize) -> Option<Motion>, members: &[usize]) -> Vec<Option<f64>> {
    members
        .iter()
        .enumerate()
        .map(|(k, &i)| match (k, motion(i)) {
            (1.., Some(m)) => m.in_place_turn_rad(),
            _ => None,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_that_cannot_work_together_are_refused() {
        assert!(PipelineConfig::default().check().is_ok());
        let mut narrow = PipelineConfig::default();
        narrow.sweep.matching.window_rad = 0.1f64.to_radians();
        let err = narrow.check().unwrap_err().to_string();
        assert!(err.contains("narrower than one profile bin"), "{err}");
        let mut grid = PipelineConfig::default();
        grid.map.grid.resolution_m = -1.0;
        assert!(grid.check().unwrap_err().to_string().contains("grid"));
        let mut vision = PipelineConfig::default();
        vision.vision.bin_width_rad = f64::NAN;
        assert!(vision.check().unwrap_err().to_string().contains("vision"));
        let mut reach = PipelineConfig::default();
        reach.map.far_reach = 0.5;
        assert!(reach.check().is_err());
    }
}
