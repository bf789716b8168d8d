//! The command line's closed choices: clap checks each value and lists
//! the choices in `--help`; each turns into the library's own type.

use pirouette::camera::ModelKind;
use pirouette::graph::{Residual, Solver};
use pirouette::profile::filter::OutlierFilter;
use pirouette::profile::matching::Measure;

/// A camera model.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Model {
    /// The paper's inverse perspective mapping from four tape measurements.
    Paper,
    /// The exact pinhole model.
    Pinhole,
}

impl From<Model> for ModelKind {
    fn from(m: Model) -> Self {
        match m {
            Model::Paper => ModelKind::Paper,
            Model::Pinhole => ModelKind::Pinhole,
        }
    }
}

/// An outlier filter over a profile's bins.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Filter {
    /// The median of three neighbouring bins (robust; keeps edges sharp).
    Median3,
    /// The mean of three neighbouring bins (the paper's).
    Mean3,
    /// None: the profile as measured.
    None,
}

impl From<Filter> for OutlierFilter {
    fn from(f: Filter) -> Self {
        match f {
            Filter::Median3 => OutlierFilter::Median3,
            Filter::Mean3 => OutlierFilter::Mean3,
            Filter::None => OutlierFilter::None,
        }
    }
}

/// A dissimilarity of two profiles' stretches.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dissimilarity {
    /// Truncated quadratic: bins beyond three standard deviations cost alike.
    Robust,
    /// Mean absolute difference.
    Absolute,
    /// Mean squared difference.
    Squared,
    /// Low-pass DCT coefficients compared (the paper's).
    Dct,
}

impl From<Dissimilarity> for Measure {
    fn from(d: Dissimilarity) -> Self {
        match d {
            Dissimilarity::Robust => Measure::Robust,
            Dissimilarity::Absolute => Measure::Absolute,
            Dissimilarity::Squared => Measure::Squared,
            Dissimilarity::Dct => Measure::Dct,
        }
    }
}

/// A least-squares solver.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolverChoice {
    /// Gauss-Newton.
    Gn,
    /// Levenberg-Marquardt.
    Lm,
}

impl From<SolverChoice> for Solver {
    fn from(s: SolverChoice) -> Self {
        match s {
            SolverChoice::Gn => Solver::GaussNewton,
            SolverChoice::Lm => Solver::LevenbergMarquardt,
        }
    }
}

/// A robust kernel on loop closures.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum RobustKernel {
    /// Huber's: quadratic near zero, linear beyond the width.
    Huber,
    /// Cauchy's: logarithmic beyond the width.
    Cauchy,
}

/// What to do with wrong loop closures.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outliers {
    /// Found by graduated non-convexity and left out of the solve.
    Reject,
    /// Plain least squares over every edge.
    Keep,
}

/// Where a graph's solve starts.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Init {
    /// The file's vertices and the chordal start both solved, the lower
    /// cost kept.
    Best,
    /// The file's vertices (odometry chaining where it has none).
    File,
    /// Odometry chaining from the edges.
    Chain,
    /// Rotations first, then positions, from the edges.
    Chordal,
}

/// The residual a graph's solve minimises.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResidualChoice {
    /// g2o's: (x, y, θ) of z⁻¹·xi⁻¹·xj.
    G2o,
    /// Its SE(2) logarithm, as GTSAM takes it.
    Log,
}

impl From<ResidualChoice> for Residual {
    fn from(r: ResidualChoice) -> Self {
        match r {
            ResidualChoice::G2o => Residual::G2o,
            ResidualChoice::Log => Residual::Log,
        }
    }
}

/// A choice's name, as it is given on the command line.
pub fn name(choice: impl clap::ValueEnum) -> String {
    choice
        .to_possible_value()
        .map_or_else(String::new, |v| v.get_name().to_owned())
}
