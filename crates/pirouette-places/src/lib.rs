//! The place index: each place remembered by a few hundred bytes, a query
//! sweep answered with the places it may be and its rotation.
//!
//! - [`Transforms::signature`]: a 360° sweep becomes a [`Signature`]: the
//!   first K coefficients of the DCT of its conditioned profile
//!   ([`condition`]: ranges clamped to the soft limit, no return read as
//!   the limit, unseen bins filled round the circle), a rotation-invariant
//!   key of [`KEY_DIMS`] harmonic amplitudes, and colour tags per sector
//!   normalised for the light.
//! - [`PlaceIndex`]: keys in a k-d tree (kiddo); a query's nearest keys
//!   re-ranked by a shift search on the profiles rebuilt from the DCT,
//!   which also gives the rotation; candidates whose colours disagree
//!   dropped ([`PlaceIndex::query`]).
//! - [`StoredProfile`]: the sweep kept beside the signature, two bytes a
//!   bin, for metric refinement by registration.
//! - [`synthetic`]: random places for benchmarks and tests.
//!
//! ```
//! use pirouette_places::{PlaceIndex, PlaceMeta, QueryConfig, SignatureConfig};
//! use pirouette_profile::Rop;
//! // A room seen from its centre: ranges vary with bearing.
//! let sweep = |turn: f64| {
//!     let mut rop = Rop::empty(-std::f64::consts::PI, 0.25f64.to_radians(), 1440, 2.0);
//!     for i in 0..rop.len() {
//!         let b = rop.bin_centre_rad(i) + turn;
//!         rop.range_m[i] = (1.0 + 0.3 * (2.0 * b).cos() + 0.2 * (3.0 * b).sin()) as f32;
//!     }
//!     rop
//! };
//! let mut index = PlaceIndex::new(SignatureConfig::default())?;
//! let signature = index.transforms().signature(&sweep(0.0))?;
//! let dataset = index.dataset_id("room");
//! index.insert(&signature, 2.0, PlaceMeta { dataset, sweep: 0, truth: None, profile: None, map_pose: None, look_alike: None })?;
//! // The same spot, the robot turned 40° to the left.
//! let query = index.transforms().signature(&sweep(40f64.to_radians()))?;
//! let best = &index.query(&query, &QueryConfig::default())[0];
//! assert_eq!(best.place, 0);
//! assert!((best.rotation_rad.to_degrees() - 40.0).abs() < 1.0);
//! # Ok::<(), pirouette_places::PlacesError>(())
//! ```
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

mod index;
mod signature;
mod stored;
pub mod synthetic;

pub use index::{Candidate, IndexContents, PlaceIndex, PlaceMeta, QueryConfig, TREE_DIMS};
pub use signature::{
    colour_distance, condition, dequantise_chroma, quantise_chroma, relative_chroma, ColourSectors,
    Signature, SignatureConfig, Transforms, KEY_DIMS, MAX_SAMPLES,
};
pub use stored::StoredProfile;

/// Errors of signatures and the place index.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum PlacesError {
    /// Signature settings that cannot make a signature.
    #[error("signature settings: {problem}")]
    BadConfig {
        /// What is wrong.
        problem: String,
    },
    /// The sweep saw too little of the circle to be a place.
    #[error("the sweep saw {:.0} % of the circle, {:.0} % needed", 100.0 * coverage, 100.0 * needed)]
    IncompleteSweep {
        /// Share of the circle seen.
        coverage: f64,
        /// Share needed.
        needed: f64,
    },
    /// A profile that cannot be a sweep.
    #[error("profile: {problem}")]
    BadProfile {
        /// What is wrong.
        problem: String,
    },
    /// A signature made otherwise than the index's.
    #[error("does not match the index: {problem}")]
    Mismatch {
        /// What differs.
        problem: String,
    },
    /// Saved contents that are not a consistent index.
    #[error("not a consistent place index: {problem}")]
    BadIndex {
        /// What is wrong.
        problem: String,
    },
}

#[cfg(test)]
mod tests;
