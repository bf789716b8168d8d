//! The error type of the readers and writers.

use std::path::PathBuf;

/// What went wrong reading or writing a file. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The file is not valid JSON of the expected shape.
    #[error("{}: bad JSON: {source}", path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// The parser's error, with line and column.
        source: serde_json::Error,
    },
    /// The manifest declares a format this reader does not know.
    #[error("{}: unknown format `{found}` (expected `{}`)", path.display(), crate::FORMAT_VERSION)]
    UnknownFormat {
        /// The manifest.
        path: PathBuf,
        /// The declared format.
        found: String,
    },
    /// A line of a text file is malformed or holds a bad value.
    #[error("{}:{line}: {problem}", path.display())]
    Line {
        /// The file.
        path: PathBuf,
        /// The line, from 1.
        line: usize,
        /// What is wrong with it.
        problem: String,
    },
    /// A value is out of its valid range (non-finite, negative, missing).
    #[error("{}: {problem}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong, naming the field.
        problem: String,
    },
    /// An image could not be decoded.
    #[error("{}: cannot decode image: {source}", path.display())]
    Image {
        /// The image file.
        path: PathBuf,
        /// The decoder's error.
        source: image::ImageError,
    },
    /// An image has a size other than the camera's.
    #[error("{}: image is {found_width}x{found_height}, the camera is {width}x{height}", path.display())]
    ImageSize {
        /// The image file.
        path: PathBuf,
        /// The camera's width.
        width: u32,
        /// The camera's height.
        height: u32,
        /// The image's width.
        found_width: u32,
        /// The image's height.
        found_height: u32,
    },
}

impl IoError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        IoError::Io {
            path: path.into(),
            source,
        }
    }

    pub(crate) fn invalid(path: impl Into<PathBuf>, problem: impl Into<String>) -> Self {
        IoError::Invalid {
            path: path.into(),
            problem: problem.into(),
        }
    }
}
