//! Floor segmentation and Radial Obstacle Profiles from camera images.
#![deny(missing_docs)]
