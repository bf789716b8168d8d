//! The back end's input, whatever the sensor: a frame is the profiles of
//! one observation and the motion that brought the robot there.
//!
//! A camera dataset makes frames with [`camera_frames`]; a laser log will
//! be one more constructor. Nothing after the frames knows which sensor
//! made them.

use pirouette_io::{Dataset, Motion};
use pirouette_profile::Rop;

/// One observation: its profiles, each for one use, and the motion since
/// the previous frame.
#[derive(Debug, Clone)]
pub struct Frame {
    /// A name for reports: the image's path in its dataset.
    pub label: String,
    /// The commanded motion since the previous frame; `None` for the first.
    pub motion: Option<Motion>,
    /// The profile the grid fuses.
    pub rop: Rop,
    /// The profile registration compares with the map of other frames.
    pub compared: Rop,
    /// The profile turns are verified on; a sensor's extra cue, such as
    /// vision's texture ranges, travels in it
    /// ([`Rop::intermittent_m`](pirouette_profile::Rop::intermittent_m)).
    pub matched: Rop,
}

/// The frames of a camera dataset, from its profiles: one of each kind per
/// manifest frame, in capture order (see
/// [`SweepProfiles`](crate::pipeline::SweepProfiles)).
pub fn camera_frames(ds: &Dataset, rops: Vec<Rop>, compared: Vec<Rop>, matched: Vec<Rop>) -> Vec<Frame> {
    ds.manifest
        .frames
        .iter()
        .zip(rops.into_iter().zip(compared).zip(matched))
        .map(|(f, ((rop, compared), matched))| Frame {
            label: f.image.clone(),
            motion: f.motion,
            rop,
            compared,
            matched,
        })
        .collect()
}

/// The motions of a camera dataset's frames, from its manifest alone.
pub fn camera_motions(ds: &Dataset) -> Vec<Option<Motion>> {
    ds.manifest.frames.iter().map(|f| f.motion).collect()
}
