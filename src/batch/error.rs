//! Errors of running a batch and writing its files.

use std::io;
use std::path::PathBuf;

/// Why a batch could not run or its files could not be written.
///
/// Failed trials are not errors: they are records with a reason.
#[derive(Debug, thiserror::Error)]
pub enum BatchError {
    /// The `--min-success` rate is not a number in [0, 1].
    #[error("min success rate {value} is not in [0, 1]")]
    MinSuccess {
        /// The value given.
        value: f64,
    },
    /// The output directory could not be created.
    #[error("cannot create output directory: {source}: {}", path.display())]
    CreateDir {
        /// The directory.
        path: PathBuf,
        /// The cause.
        source: io::Error,
    },
    /// An output file could not be created or written.
    #[error("cannot write: {source}: {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: io::Error,
    },
    /// A record or report could not be serialised.
    #[error("cannot serialise JSON: {source}: {}", path.display())]
    Json {
        /// The file it was meant for.
        path: PathBuf,
        /// The cause.
        source: serde_json::Error,
    },
    /// A worker thread could not be started.
    #[error("cannot start a worker thread: {source}")]
    Spawn {
        /// The cause.
        source: io::Error,
    },
    /// The signal handlers could not be installed.
    #[error("cannot install the SIGINT/SIGTERM handler: {source}")]
    Signal {
        /// The cause.
        source: io::Error,
    },
    /// The output directory cannot be resumed (`--resume`): another batch, or damaged files.
    #[error(transparent)]
    Resume(#[from] super::ResumeError),
}

impl BatchError {
    /// Whether the fault lies in the user's input (exit code 2): a directory that cannot be
    /// resumed, a gate out of range.
    pub fn is_bad_input(&self) -> bool {
        matches!(self, Self::Resume(_) | Self::MinSuccess { .. })
    }
}
