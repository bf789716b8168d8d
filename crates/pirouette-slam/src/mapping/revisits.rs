//! Revisits recognised by the place index: each sweep, as it is placed,
//! is looked up among the sweeps before it (the one just before aside),
//! and a place it is recognised at becomes a candidate loop edge for the
//! joint adjustment, whatever the drift says of where the two lie.

use super::placed::Placed;
use crate::error::{Result, SlamError};
use crate::frame::DatasetSweep;
use crate::localise::{localise_signature, LocaliseConfig};
use pirouette_geom::Pose2;
use pirouette_places::{PlaceIndex, PlaceMeta, PlacesError, SignatureConfig, StoredProfile};

/// A sweep recognised at the place of an earlier one.
#[derive(Debug, Clone, PartialEq)]
pub struct Revisit {
    /// The earlier sweep (its position among the sweeps).
    pub earlier: usize,
    /// The sweep that came back.
    pub later: usize,
    /// The place index's score of the match (0-1).
    pub score: f64,
    /// The later sweep's pose in the earlier one's frame, as the place
    /// index's registration found it (sweep frames, as the graph uses).
    pub relative: Pose2,
    /// Whether the pairwise search would not have tried the pair (the two
    /// lie farther apart, as placed, than either sees).
    pub beyond_reach: bool,
    /// Whether the pair's registration, started from `relative`, was
    /// trusted and became an edge.
    pub registered: bool,
    /// Whether the adjustment kept the edge (it agreed with the rest).
    pub kept: bool,
}

/// The sweeps' revisits: sweep `s` looked up in an index of sweeps
/// `0..s−1`. Sweeps that saw too little of the circle are neither filed
/// nor looked up.
pub(super) fn recognise(
    sweeps: &[DatasetSweep],
    placed: &[Placed],
    config: &LocaliseConfig,
) -> Result<Vec<Revisit>> {
    let mut index = PlaceIndex::new(SignatureConfig::default())?;
    let dataset = index.dataset_id("map");
    // Index place → sweep.
    let mut sweep_of: Vec<usize> = Vec::new();
    let mut pending: Option<(usize, pirouette_places::Signature)> = None;
    let mut out = Vec::new();
    for (s, sweep) in sweeps.iter().enumerate() {
        let rop = &sweep.sweep.rop;
        let signature = match index.transforms().signature(rop) {
            Ok(sig) => Some(sig),
            Err(PlacesError::IncompleteSweep { .. }) => None,
            Err(e) => return Err(SlamError::from(e).at(format!("sweep {}", sweep.id))),
        };
        if let Some(sig) = &signature {
            if !index.is_empty() && index.check_signature(sig, rop.max_range_m).is_ok() {
                let answer = localise_signature(&index, sig, rop, config);
                if let Some(m) = answer.trusted() {
                    let earlier = sweep_of[m.place];
                    // Frame 0 of each sweep in its sweep frame.
                    let relative = placed[earlier].rel(0) * m.pose * placed[s].rel(0).inverse();
                    out.push(Revisit {
                        earlier,
                        later: s,
                        score: m.score,
                        relative,
                        beyond_reach: false,
                        registered: false,
                        kept: false,
                    });
                }
            }
        }
        // The sweep just before is filed only now: a revisit is of a
        // sweep before that one.
        if let Some((p, sig)) = pending.take() {
            let prev = &sweeps[p].sweep.rop;
            let meta = PlaceMeta {
                dataset,
                sweep: sweeps[p].id,
                truth: None,
                profile: Some(StoredProfile::from_rop(prev)),
                map_pose: None,
                look_alike: None,
            };
            if index.insert(&sig, prev.max_range_m, meta).is_ok() {
                sweep_of.push(p);
            }
        }
        pending = signature.map(|sig| (s, sig));
    }
    Ok(out)
}
