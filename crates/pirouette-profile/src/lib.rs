//! The Radial Obstacle Profile (ROP): range to the nearest obstacle per
//! bearing bin, from a camera image or a laser scan alike.
//!
//! - [`Rop`]: the profile, its bins and colour tags.
//! - [`ColourTag`]: an obstacle colour normalised for lighting.
//! - [`filter`]: outlier filters (the paper's 3-bin mean, a robust median).
//! - [`matching`]: rotation verification by sliding one profile over another.
//! - [`sweep`]: the profiles of a pirouette joined into a 360° radial sweep.
//!
//! ```
//! use pirouette_profile::Rop;
//! let mut rop = Rop::covering(-0.5, 0.5, 1f64.to_radians(), 0.9)?;
//! rop.insert(0.0, 0.42, None);
//! let centre = rop.bin_of(0.0).ok_or("no bin at 0")?;
//! assert_eq!(rop.reliable(centre), Some(0.42));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod filter;
pub mod matching;
mod rop;
pub mod sweep;

pub use rop::{ColourTag, ProfileError, Rop};
