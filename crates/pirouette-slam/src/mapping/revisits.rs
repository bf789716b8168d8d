//! Revisits recognised by the place index: each sweep, as it is placed,
//! is looked up among the sweeps before it (the one just before aside),
//! and a place it is recognised at becomes a candidate loop edge for the
//! joint adjustment, whatever the drift says of where the two lie.

use super::placed::Placed;
use crate::backend::places::Places;
use crate::error::{Result, SlamError};
use crate::frame::DatasetSweep;
use crate::localise::{localise_signature, LocaliseConfig};
use pirouette_geom::Pose2;

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
    let mut places = Places::new("map")?;
    let mut pending: Option<(usize, pirouette_places::Signature)> = None;
    let mut out = Vec::new();
    for (s, sweep) in sweeps.iter().enumerate() {
        let rop = &sweep.sweep.rop;
        let signature =
            (places.signature(rop)).map_err(|e| SlamError::from(e).at(format!("sweep {}", sweep.id)))?;
        let index = places.index();
        if let Some(sig) = &signature {
            if !index.is_empty() && index.check_signature(sig, rop.max_range_m).is_ok() {
                let answer = localise_signature(index, sig, rop, config);
                if let Some(m) = answer.trusted() {
                    let earlier = places.node(m.place);
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
        // sweep before that one. (One the index refuses is not a place.)
        if let Some((p, sig)) = pending.take() {
            let _ = places.file(p, sweeps[p].id, &sig, &sweeps[p].sweep.rop, true);
        }
        pending = signature.map(|sig| (s, sig));
    }
    Ok(out)
}
