//! The engine's error type.

use pirouette_grid::GridError;
use pirouette_io::IoError;
use pirouette_places::PlacesError;
use pirouette_register::RegisterError;
use pirouette_vision::VisionError;

/// What stopped a run. The settings, file or frame it is about are named
/// by the error or by [`SlamError::In`] around it.
#[derive(Debug, thiserror::Error)]
pub enum SlamError {
    /// Settings that cannot work, refused before any data is read.
    #[error("{what} settings: {problem}")]
    Settings {
        /// Which settings (`laser`, `pipeline`, ...).
        what: &'static str,
        /// What is wrong, naming the setting.
        problem: String,
    },
    /// A grid that cannot be made from its settings.
    #[error(transparent)]
    Grid(#[from] GridError),
    /// A file that could not be read or holds bad data (the error names it).
    #[error(transparent)]
    Io(#[from] IoError),
    /// The camera's tables or an image's segmentation.
    #[error(transparent)]
    Vision(#[from] VisionError),
    /// A frame that registration refused to match (bad settings or input).
    #[error(transparent)]
    Register(#[from] RegisterError),
    /// A place index that could not take or answer a sweep.
    #[error(transparent)]
    Places(#[from] PlacesError),
    /// Input that holds nothing to map or whose parts disagree (wrapped
    /// [`SlamError::at`] the file or dataset where the caller knows it).
    #[error("{problem}")]
    Input {
        /// What is wrong.
        problem: String,
    },
    /// A map that outgrew the grid's cell budget.
    #[error("the map outgrew its budget of {} million cells: {hint}", max_cells / 1_000_000)]
    Budget {
        /// The budget ([`pirouette_grid::GridConfig::max_cells`]).
        max_cells: usize,
        /// The likely cause, or what to change.
        hint: &'static str,
    },
    /// An error of the run of a dataset or log, with its name.
    #[error("{at}: {source}")]
    In {
        /// The dataset or log.
        at: String,
        /// What went wrong in it.
        source: Box<SlamError>,
    },
}

/// The engine's results.
pub type Result<T, E = SlamError> = std::result::Result<T, E>;

impl SlamError {
    /// `self`, said to have happened in `at` (a dataset or log).
    pub fn at(self, at: impl Into<String>) -> SlamError {
        SlamError::In {
            at: at.into(),
            source: Box::new(self),
        }
    }

    /// Settings `what` refused for `problem`.
    pub(crate) fn settings(what: &'static str, problem: impl Into<String>) -> SlamError {
        SlamError::Settings {
            what,
            problem: problem.into(),
        }
    }
}
