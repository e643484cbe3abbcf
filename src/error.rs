//! The daemon's and batch jobs' errors: the file layer's pass through, and the ones the
//! daemon adds (its configuration, Kafka, its own threads).

/// Errors of the daemon, batch jobs and the commands.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be read or written, or its data are wrong for the method.
    #[error(transparent)]
    File(isoline_io::Error),
    /// The configuration is invalid; every problem found is listed.
    #[error("invalid configuration {path}:\n  {}", problems.join("\n  "))]
    Config {
        /// The file (or what the configuration came from).
        path: String,
        /// Every problem found, each naming its key path.
        problems: Vec<String>,
    },
    /// A Kafka client failed: it could not be created, or a message could not be
    /// delivered.
    #[error("Kafka: {0}")]
    Kafka(String),
    /// The run ended, but not as it should have: a source or stage failed after the
    /// records in the summary were written.
    #[error("{cause}; the run wrote: {summary}")]
    RunFailed {
        /// The run's summary line.
        summary: String,
        /// What failed.
        cause: Box<Error>,
    },
    /// An internal invariant failed: a bug in isoline, not in the input.
    #[error("internal error: {0}")]
    Internal(String),
}

/// `Result` with the daemon's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

/// An invalid configuration is the daemon's [`Error::Config`], whichever layer read it.
impl From<isoline_io::Error> for Error {
    fn from(e: isoline_io::Error) -> Self {
        match e {
            isoline_io::Error::Core(isoline_core::Error::Config { path, problems }) => {
                Error::Config { path, problems }
            }
            e => Error::File(e),
        }
    }
}

impl From<isoline_core::Error> for Error {
    fn from(e: isoline_core::Error) -> Self {
        Error::File(e.into())
    }
}

impl From<isoline_map::Error> for Error {
    fn from(e: isoline_map::Error) -> Self {
        Error::File(e.into())
    }
}
