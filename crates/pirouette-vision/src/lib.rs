//! Floor segmentation and Radial Obstacle Profiles from camera images.
//!
//! - [`RopExtractor`]: built once per camera (lookup tables), it turns an
//!   RGB image into per-column floor/obstacle boundaries
//!   ([`RopExtractor::boundaries`]) and into a [`Rop`]
//!   ([`RopExtractor::rop`]).
//! - [`VisionConfig`]: the segmentation and profile settings, each default
//!   documented.
//! - [`ColumnBoundary`]: what one image column shows.
//!
//! The floor model comes from each image itself: every column starts from
//! its own bottom rows and follows the floor upwards with a slowly adapting
//! reference, so brightness that changes across the floor (vignetting,
//! uneven light, tonal patches) is followed while a step to an obstacle is
//! not. Thresholds scale with the noise measured in the image. A candidate
//! boundary is accepted only if the non-floor run above it is as tall as an
//! obstacle of [`VisionConfig::min_obstacle_height_m`] would appear there,
//! which rejects flat specks (lint, reflections) by geometry. Where the
//! colour changes within one row (an edge), a smaller change of
//! chromaticity is enough ([`VisionConfig::edge_fraction`]): a wall close to
//! the floor's colour still has a sharp base. Where brightness alone steps
//! sharply and the floor's grain stops above the step, the step is a
//! smooth wall's base ([`VisionConfig::texture_ratio`]); a fainter step,
//! down to a third of the brightness tolerance, counts where the texture
//! drops further ([`VisionConfig::faint_step_fraction`]). Where a column
//! still sees no base within the soft limit, the grain of the floor is
//! pooled along lines over many columns, and a line where it ends under a
//! smooth surface is a base ([`VisionConfig::line_columns`]). These cues find
//! faint walls only in stretches, so turns are matched on profiles without
//! them ([`VisionConfig::for_matching`]) and sweeps are registered on
//! profiles without the faint steps and the line cue
//! ([`VisionConfig::for_comparing`]).
//!
//! ```
//! use pirouette_camera::PinholeModel;
//! use pirouette_vision::{RopExtractor, VisionConfig};
//! let cam = PinholeModel { width: 64, height: 48, fx: 55.4, fy: 55.4, cx: 31.5, cy: 23.5,
//!     height_m: 0.1, tilt_rad: 25f64.to_radians(), mount_forward_m: 0.0, mount_left_m: 0.0,
//!     distortion: Default::default() };
//! let extractor = RopExtractor::new(&cam, 0.9, VisionConfig::default());
//! let floor_only = image::RgbImage::from_pixel(64, 48, image::Rgb([40, 40, 45]));
//! let rop = extractor.rop(&floor_only)?;
//! assert!((0..rop.len()).all(|i| rop.reliable(i).is_none()));
//! # Ok::<(), pirouette_vision::VisionError>(())
//! ```
#![deny(missing_docs)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

mod boundary;
pub mod compass;
mod config;
mod extract;
mod scan;

pub use boundary::ColumnBoundary;
pub use config::{VisionConfig, VisionError};
pub use extract::RopExtractor;
#[doc(no_inline)]
pub use pirouette_profile::Rop;
