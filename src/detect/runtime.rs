//! The process-wide `ort` environment over the tract backend, made once.

use std::sync::OnceLock;

use super::DetectError;

static ENVIRONMENT: OnceLock<Result<ort::environment::Environment, String>> = OnceLock::new();

/// The shared environment: installs tract as `ort`'s backend on first use.
pub(crate) fn environment() -> Result<&'static ort::environment::Environment, DetectError> {
    ENVIRONMENT
        .get_or_init(|| {
            ort::set_api(ort_tract::api());
            ort::init().build().map_err(|e| e.to_string())
        })
        .as_ref()
        .map_err(|reason| DetectError::Runtime {
            context: "starting the ONNX runtime (tract)".into(),
            reason: reason.clone(),
        })
}
