//! Why the detector could not load or run.

use std::path::PathBuf;

/// Detector errors. `ort`'s own error is not `Send`, so its message is kept as text.
#[derive(Debug, thiserror::Error)]
pub enum DetectError {
    /// The model card (JSON beside the ONNX file) is missing or wrong.
    #[error("model card {}: {reason}", path.display())]
    Card {
        /// The card file.
        path: PathBuf,
        /// What is wrong, naming the field.
        reason: String,
    },
    /// The inference runtime could not start, load the model or run it.
    #[error("{context}: {reason}")]
    Runtime {
        /// What was being done (and on which file).
        context: String,
        /// The runtime's message.
        reason: String,
    },
    /// The network's output does not have the shape its card promises.
    #[error("model output: {0}")]
    Output(String),
    /// The image cannot be fed to the network.
    #[error("image: {0}")]
    Image(String),
}

impl DetectError {
    /// Wraps an `ort` error with what was being done.
    pub(crate) fn runtime<R>(context: impl Into<String>, err: &ort::Error<R>) -> Self {
        Self::Runtime {
            context: context.into(),
            reason: err.to_string(),
        }
    }
}
