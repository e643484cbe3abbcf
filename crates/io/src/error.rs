//! Errors of reading and writing files: the method's own errors pass through, and the
//! ones a file adds name the file and, for text, the line.

use std::path::PathBuf;

/// Errors of isoline-io.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The data or parameters are wrong for the method (a non-finite point, an invalid
    /// scan, a bad parameter).
    #[error(transparent)]
    Core(#[from] isoline_core::Error),
    /// The world map failed: its tile store, or a pose beyond its reach.
    #[error(transparent)]
    Map(#[from] isoline_map::Error),
    /// A text input could not be parsed; `line` is 1-based.
    #[error("{source_name}, line {line}: {message}")]
    Parse {
        /// The file or stream.
        source_name: String,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A recording (an MCAP bag, a CARMEN log) cannot be read as a whole: not the
    /// format, or none of the chosen topics in it.
    #[error("{path}: {message}")]
    Recording {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

/// `Result` with isoline-io's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// Reading or writing `path` failed with `source`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    /// A frame's beams or pose are malformed.
    pub(crate) fn scan(message: impl Into<String>) -> Self {
        Error::Core(isoline_core::Error::Scan(message.into()))
    }
}
