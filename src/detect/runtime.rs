//! The process-wide `ort` environment, made once, over the backend the build chose: tract (pure
//! Rust; feature `tract`, the default) or a native ONNX Runtime that ort loads at run time from
//! `ORT_DYLIB_PATH` (feature `onnxruntime`).

use std::sync::OnceLock;

use ort::environment::Environment;
use ort::session::Session;
use ort::session::builder::{GraphOptimizationLevel, SessionBuilder};

use super::DetectError;

#[cfg(not(any(feature = "tract", feature = "onnxruntime")))]
compile_error!(
    "the detector needs a runtime: enable feature `tract` (the default) or `onnxruntime`"
);
#[cfg(all(feature = "tract", feature = "onnxruntime"))]
compile_error!(
    "features `tract` and `onnxruntime` are exclusive: for the native runtime build with \
     `--no-default-features --features onnxruntime,record`"
);

/// The environment variable naming the native ONNX Runtime library.
#[cfg(feature = "onnxruntime")]
const DYLIB_VARIABLE: &str = "ORT_DYLIB_PATH";

/// The backend's name in messages.
const BACKEND: &str = if cfg!(feature = "onnxruntime") {
    "native ONNX Runtime"
} else {
    "tract"
};

static ENVIRONMENT: OnceLock<Result<Environment, String>> = OnceLock::new();

/// The shared environment: starts the backend on first use.
fn environment() -> Result<&'static Environment, DetectError> {
    ENVIRONMENT
        .get_or_init(start)
        .as_ref()
        .map_err(|reason| DetectError::Runtime {
            context: format!("starting the ONNX runtime ({BACKEND})"),
            reason: reason.clone(),
        })
}

/// A session builder on the shared environment with the graph optimised; `context` says what is
/// being loaded, for errors.
pub(crate) fn session_builder(context: impl Fn() -> String) -> Result<SessionBuilder, DetectError> {
    let builder = Session::builder(environment()?)
        .map_err(|e| DetectError::runtime(context(), &e))?
        // tract runs the graph as parsed unless asked to optimise it (fold batch normalisation,
        // fuse activations, pick packed kernels): about 3x faster.
        .with_optimization_level(GraphOptimizationLevel::Level3)
        .map_err(|e| DetectError::runtime(context(), &e))?;
    // tract runs on one thread; ONNX Runtime would take every core for each session, while the
    // cell already runs one detector per trial in parallel.
    #[cfg(feature = "onnxruntime")]
    let builder = builder
        .with_intra_threads(1)
        .map_err(|e| DetectError::runtime(context(), &e))?;
    Ok(builder)
}

#[cfg(feature = "tract")]
fn start() -> Result<Environment, String> {
    ort::set_api(ort_tract::api());
    ort::init().build().map_err(|e| e.to_string())
}

#[cfg(all(feature = "onnxruntime", not(feature = "tract")))]
fn start() -> Result<Environment, String> {
    load_native(std::env::var_os(DYLIB_VARIABLE).filter(|path| !path.is_empty()))
}

/// Loads the native library at `path` (the value of `ORT_DYLIB_PATH`) and starts it.
#[cfg(feature = "onnxruntime")]
fn load_native(path: Option<std::ffi::OsString>) -> Result<Environment, String> {
    let Some(path) = path else {
        return Err(format!(
            "{DYLIB_VARIABLE} is not set; point it at libonnxruntime.so (ONNX Runtime 1.24 or \
             newer; PyPI's onnxruntime wheel has one in onnxruntime/capi/)"
        ));
    };
    ort::init_from(&path)
        .map_err(|e| format!("{DYLIB_VARIABLE}: {e}"))?
        .build()
        .map_err(|e| e.to_string())
}

#[cfg(all(test, feature = "onnxruntime"))]
mod tests {
    use super::*;

    #[test]
    fn a_missing_native_library_is_named_in_the_error() {
        let Err(e) = load_native(None) else {
            panic!("started without a library");
        };
        assert!(e.contains("ORT_DYLIB_PATH is not set"), "{e}");
        let path = "/nonexistent/twincell/libonnxruntime.so";
        let Err(e) = load_native(Some(path.into())) else {
            panic!("started from a missing file");
        };
        assert!(e.contains("ORT_DYLIB_PATH") && e.contains(path), "{e}");
    }
}
