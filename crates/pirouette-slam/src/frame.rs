//! The back end's input, whatever the sensor: a frame is the profiles of
//! one observation and the motion that brought the robot there.
//!
//! A camera dataset makes frames with [`camera_frames`], a laser log's
//! scans with [`laser_frame`]. Nothing after the frames knows which sensor
//! made them.

use pirouette_geom::Pose2;
use pirouette_io::{Dataset, LaserScan, Motion};
use pirouette_profile::matching::MatchView;
use pirouette_profile::sweep::Sweep;
use pirouette_profile::Rop;
use pirouette_vision::compass::{profile_turn, BearingProfile, MIN_CORRELATION};

/// The largest turn the visual compass looks for between frames of
/// unknown motion, degrees: about half a 60° camera's view, beyond which
/// too little of the two views is shared.
pub const COMPASS_MAX_TURN_DEG: f64 = 30.0;

/// How the robot got from the previous frame to this one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Step {
    /// A commanded in-place turn or straight move (a camera dataset's
    /// manifest).
    Commanded(Motion),
    /// A measured relative pose (raw odometry), in the previous frame.
    Odometry(Pose2),
    /// No motion given, and this turn (radians, left positive) seen by
    /// the visual compass ([`pirouette_vision::compass`]) since the
    /// previous frame; the shift is unknown.
    SeenTurn(f64),
}

/// One observation: its profiles, each for one use, and the motion since
/// the previous frame.
#[derive(Debug, Clone)]
pub struct Frame {
    /// A name for reports: the image's path in its dataset.
    pub label: String,
    /// The sweep it belongs to, as the sensor's log numbers them (a
    /// camera manifest's sweep; a laser scan's own position in its log).
    pub sweep: u32,
    /// The motion since the previous frame; `None` for the first, and
    /// where the sensor's log holds none.
    pub motion: Option<Step>,
    /// The profile the grid fuses.
    pub rop: Rop,
    /// The profile registration compares with the map of other frames.
    pub compared: Rop,
    /// The profile turns are verified on.
    pub matched: Rop,
    /// A sensor's intermittent cue beside `matched`, one range per bin
    /// (vision's texture cue; see
    /// [`MatchView::cue_m`](pirouette_profile::matching::MatchView::cue_m)):
    /// empty where the sensor has none.
    pub cue_m: Vec<f32>,
}

/// One profile per frame for each use, in manifest order.
pub struct FrameProfiles {
    /// As the settings give it: for the map's grid.
    pub rops: Vec<Rop>,
    /// For comparing views (a sweep registered against the map of the
    /// others): the settings'
    /// [`VisionConfig::for_comparing`](pirouette_vision::VisionConfig::for_comparing);
    /// a copy of `rops` where those are the same.
    pub compared: Vec<Rop>,
    /// To verify turns on: the settings'
    /// [`VisionConfig::for_matching`](pirouette_vision::VisionConfig::for_matching);
    /// a copy of `compared` where those are the same.
    pub matched: Vec<Rop>,
    /// The intermittent cue beside `matched`: the ranges of `compared`
    /// where the matching settings leave out the texture cue (see
    /// [`MatchView::cue_m`](pirouette_profile::matching::MatchView::cue_m));
    /// empty where they do not.
    pub cues: Vec<Vec<f32>>,
    /// Each frame's bearing profile for the visual compass, where some
    /// frame's motion is unknown (none where every motion is given, or
    /// the camera has no pinhole model).
    pub compass: Vec<Option<BearingProfile>>,
}

/// The frames of a camera dataset, from its profiles: one of each kind per
/// manifest frame, in capture order (see
/// [`SweepProfiles`](crate::pipeline::SweepProfiles)).
/// A frame whose motion is unknown takes the turn the visual compass
/// sees from the previous frame (within [`COMPASS_MAX_TURN_DEG`], the
/// profiles correlating at least
/// [`MIN_CORRELATION`]).
pub fn camera_frames(ds: &Dataset, profiles: FrameProfiles) -> Vec<Frame> {
    let FrameProfiles {
        rops,
        compared,
        matched,
        cues,
        compass,
    } = profiles;
    let seen_turn = |k: usize| -> Option<Step> {
        let (a, b) = (
            compass.get(k.checked_sub(1)?)?.as_ref()?,
            compass.get(k)?.as_ref()?,
        );
        let (turn_deg, score) = profile_turn(a, b, COMPASS_MAX_TURN_DEG)?;
        (score >= MIN_CORRELATION).then(|| Step::SeenTurn(turn_deg.to_radians()))
    };
    // No cue where the profiles have none.
    let cues = cues.into_iter().chain(std::iter::repeat_with(Vec::new));
    ds.manifest
        .frames
        .iter()
        .zip(rops.into_iter().zip(compared).zip(matched).zip(cues))
        .enumerate()
        .map(|(k, (f, (((rop, compared), matched), cue_m)))| Frame {
            label: f.image.clone(),
            sweep: f.sweep,
            motion: f.motion.map(Step::Commanded).or_else(|| seen_turn(k)),
            rop,
            compared,
            matched,
            cue_m,
        })
        .collect()
}

impl Frame {
    /// The profile turns are verified on, with its cue.
    pub fn match_view(&self) -> MatchView<'_> {
        MatchView {
            rop: &self.matched,
            cue_m: &self.cue_m,
        }
    }
}

impl Frame {
    /// The commanded motion since the previous frame, where it was one.
    pub fn commanded(&self) -> Option<Motion> {
        match self.motion {
            Some(Step::Commanded(m)) => Some(m),
            _ => None,
        }
    }

    /// The measured motion (raw odometry) since the previous frame, in its
    /// frame, where the sensor's log holds one.
    pub fn odometry(&self) -> Option<Pose2> {
        match self.motion {
            Some(Step::Odometry(p)) => Some(p),
            _ => None,
        }
    }
}

/// A laser scan as a frame: one profile (a bin per beam, centred on it;
/// no-return beams read "nothing within `max_range_m`") serving every
/// use, and the raw odometry since the previous scan.
pub fn laser_frame(scan: &LaserScan, max_range_m: f32) -> Frame {
    let step = scan.beam_step_rad;
    let mut rop = Rop::empty(
        scan.first_bearing_rad - 0.5 * step,
        step,
        scan.ranges_m.len(),
        max_range_m,
    );
    rop.range_m.clone_from(&scan.ranges_m);
    Frame {
        label: format!("scan {}", scan.scan),
        sweep: u32::try_from(scan.scan).unwrap_or(u32::MAX),
        motion: scan.odometry.map(Step::Odometry),
        compared: rop.clone(),
        matched: rop.clone(),
        cue_m: Vec::new(),
        rop,
    }
}

/// The motions of a camera dataset's frames, from its manifest alone.
pub fn camera_motions(ds: &Dataset) -> Vec<Option<Motion>> {
    ds.manifest.frames.iter().map(|f| f.motion).collect()
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
