//! `twincell.detect(image)`: the part detector on one RGB frame.

use std::path::PathBuf;
use std::sync::Mutex;

use image::RgbImage;
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use twincell::detect::{Detection, Detector};

use crate::arrays::{bad_value, rgb_image};

/// The shipped network, loaded on first use and kept: loading it costs far more than one frame.
static SHIPPED: Mutex<Option<Detector>> = Mutex::new(None);

/// The shipped detector's answer on `image`, loading it the first time. Called without the
/// GIL: a thread waiting here for another's frame must not hold the GIL that one needs back.
fn detect_shipped(image: &RgbImage) -> Result<Vec<Detection>, String> {
    let mut slot = SHIPPED
        .lock()
        .map_err(|_| "the detector was poisoned by an earlier failure".to_owned())?;
    if slot.is_none() {
        let detector = Detector::load_default()
            .map_err(|e| format!("cannot load the shipped detector: {e}"))?;
        *slot = Some(detector);
    }
    let Some(detector) = slot.as_mut() else {
        return Err("the shipped detector is not loaded".to_owned());
    };
    detector
        .detect(image)
        .map_err(|e| format!("the detector failed: {e}"))
}

/// Finds parts and bottles in `image` (numpy uint8, H x W x 3, RGB as the camera delivers it).
///
/// Returns a list of dicts, best first: `class` (a part type or `bottle`), `class_id`, `score`
/// (0..1) and `box` (`[x0, y0, x1, y1]`, image pixels, x right, y down), as `twincell detect`
/// prints them. `model` is another ONNX network with its model card beside it.
#[pyfunction]
#[pyo3(signature = (image, model = None))]
pub fn detect<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    model: Option<PathBuf>,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let rgb = rgb_image("image", image)?;
    let found = match model {
        None => py
            .detach(|| detect_shipped(&rgb))
            .map_err(PyRuntimeError::new_err)?,
        Some(path) => {
            let mut detector = Detector::load(&path)
                .map_err(|e| bad_value("model", format!("{e}: {}", path.display())))?;
            py.detach(|| detector.detect(&rgb))
                .map_err(|e| PyRuntimeError::new_err(format!("the detector failed: {e}")))?
        }
    };
    found
        .iter()
        .map(|d| {
            let out = PyDict::new(py);
            out.set_item("class", &d.class_name)?;
            out.set_item("class_id", d.class_id)?;
            out.set_item("score", d.score)?;
            out.set_item("box", d.box_px.to_vec())?;
            Ok(out)
        })
        .collect()
}
