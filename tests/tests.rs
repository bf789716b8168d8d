//! End-to-end tests of the pipeline and the `pirouette` binary.

mod util;

mod bags;
mod cli;
mod datasets;
mod graph;
mod hostile;
mod laser;
mod map;
mod places;
mod profile;
mod real;
mod sweep;
mod truth;
