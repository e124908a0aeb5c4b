//! The recording a batch writes to: a `.rrd` file or a running Rerun viewer.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use rerun::{RecordingStream, RecordingStreamBuilder};

use super::TrialRecording;
use crate::task::{TrialObserver, TrialObserverFactory};

/// The application id recordings carry (the viewer groups recordings by it).
pub const APPLICATION_ID: &str = "twincell";
/// Where a Rerun viewer listens by default (`rerun` with no arguments).
pub const DEFAULT_VIEWER_ADDR: &str = "127.0.0.1:9876";
/// How long [`RerunRecorder::finish`] waits for a viewer to take what is left.
const VIEWER_FLUSH_TIMEOUT: Duration = Duration::from_secs(20);

/// Why a recording could not be made.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The file could not be created.
    #[error("cannot create the recording: {reason}: {path}")]
    Create {
        /// What went wrong.
        reason: String,
        /// The file.
        path: PathBuf,
    },
    /// The viewer's address is not usable.
    #[error("cannot stream to the viewer: {reason}: {url}")]
    Connect {
        /// What went wrong.
        reason: String,
        /// The address as a Rerun URL.
        url: String,
    },
    /// Logging or writing failed while trials ran.
    #[error("recording failed: {reason}")]
    Write {
        /// The first failure.
        reason: String,
    },
}

/// Records every trial of a batch into one Rerun recording (one [`TrialRecording`] per trial).
///
/// The recording id is derived from the batch (`name`), so the files of a batch's shards open
/// in the viewer as one recording.
#[derive(Debug, Clone)]
pub struct RerunRecorder {
    stream: RecordingStream,
    first_error: Arc<Mutex<Option<String>>>,
    /// A file is written to the end; a viewer that is not there must not hang the run.
    flush_timeout: Duration,
}

impl RerunRecorder {
    /// A recorder writing to the `.rrd` file `path` (replaced if it exists).
    pub fn save(path: &Path, name: &str) -> Result<Self, RecordError> {
        let stream = builder(name).save(path).map_err(|e| RecordError::Create {
            reason: e.to_string(),
            path: path.to_path_buf(),
        })?;
        Ok(Self::with_stream(stream, Duration::MAX))
    }

    /// A recorder streaming to the viewer at `addr` (`HOST:PORT`, or a full
    /// `rerun+http://HOST:PORT/proxy` URL). A viewer that is not there is reported by
    /// [`Self::finish`].
    pub fn connect(addr: &str, name: &str) -> Result<Self, RecordError> {
        let url = if addr.contains("://") {
            addr.to_string()
        } else {
            format!("rerun+http://{addr}/proxy")
        };
        let stream =
            builder(name)
                .connect_grpc_opts(url.clone())
                .map_err(|e| RecordError::Connect {
                    reason: e.to_string(),
                    url,
                })?;
        Ok(Self::with_stream(stream, VIEWER_FLUSH_TIMEOUT))
    }

    fn with_stream(stream: RecordingStream, flush_timeout: Duration) -> Self {
        // Only simulated time and indices: the recording's content does not depend on the wall
        // clock or on how trials were spread over threads.
        stream.set_log_time_enabled(false);
        stream.set_log_tick_enabled(false);
        Self {
            stream,
            first_error: Arc::new(Mutex::new(None)),
            flush_timeout,
        }
    }

    /// Writes out everything logged, completes a file (its footer: nothing logged later reaches
    /// it) and reports the first failure, if any.
    pub fn finish(&self) -> Result<(), RecordError> {
        let flushed = self.stream.flush_with_timeout(self.flush_timeout);
        self.stream.finalize_deferred_sinks();
        if let Some(reason) = self.first_error() {
            return Err(RecordError::Write { reason });
        }
        flushed.map_err(|e| RecordError::Write {
            reason: e.to_string(),
        })
    }

    fn first_error(&self) -> Option<String> {
        self.first_error
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }
}

impl TrialObserverFactory for RerunRecorder {
    fn observer(&self, trial_index: u32) -> Box<dyn TrialObserver> {
        Box::new(TrialRecording::new(
            self.stream.clone(),
            Arc::clone(&self.first_error),
            trial_index,
        ))
    }
}

/// A builder for the recording `name`, enabled whatever the `RERUN` environment variable says
/// (the user asked for the recording).
fn builder(name: &str) -> RecordingStreamBuilder {
    RecordingStreamBuilder::new(APPLICATION_ID)
        .recording_id(name)
        .enabled(true)
}
