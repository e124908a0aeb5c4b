//! `twincell.measure(image, calibration)`: the paper's bore metrology on one frame.

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use twincell::camera::{CameraCalibration, CameraJson};
use twincell::perception::PerceptionError;
use twincell::perception::bore::{BoreDetector, BoreDetectorParams};
use twincell::perception::calibration::MeasureOnPlane;
use twincell::perception::roundness::DEFAULT_MAX_UPR;

use crate::arrays::{bad_type, bad_value, floats, gray_image};

/// The keys of a calibration dict, as `twincell render` writes its `shot.json` `calibration`,
/// plus the end faces' height.
const CALIBRATION_KEYS: [&str; 8] = [
    "width_px",
    "height_px",
    "fx_px",
    "fy_px",
    "cx_px",
    "cy_px",
    "world_from_camera",
    "plane_height_m",
];

/// One number of the calibration dict.
fn number(dict: &Bound<'_, PyDict>, key: &str) -> PyResult<f64> {
    let arg = format!("calibration[{key:?}]");
    let Some(value) = dict.get_item(key)? else {
        return Err(bad_value("calibration", format!("missing key {key:?}")));
    };
    let v: f64 = value
        .extract()
        .map_err(|_| bad_type(&arg, format!("expected a number, got {}", value.get_type())))?;
    if !v.is_finite() {
        return Err(bad_value(&arg, format!("{v} is not a finite number")));
    }
    Ok(v)
}

/// One image size of the calibration dict.
fn size(dict: &Bound<'_, PyDict>, key: &str) -> PyResult<u32> {
    let v = number(dict, key)?;
    if v < 1.0 || v.fract() != 0.0 || v > f64::from(u32::MAX) {
        return Err(bad_value(
            &format!("calibration[{key:?}]"),
            format!("{v} is not a whole number of pixels"),
        ));
    }
    Ok(v as u32)
}

/// The camera the dict describes, its image size, with the end-face plane at its height.
fn calibration_of(value: &Bound<'_, PyAny>) -> PyResult<(CameraCalibration, u32, u32)> {
    let Ok(dict) = value.cast::<PyDict>() else {
        return Err(bad_type(
            "calibration",
            format!("expected a dict or None, got {}", value.get_type()),
        ));
    };
    for key in dict.keys() {
        let name: String = key.extract().unwrap_or_else(|_| key.to_string());
        if !CALIBRATION_KEYS.contains(&name.as_str()) {
            return Err(bad_value(
                "calibration",
                format!(
                    "unknown key {name:?} (known: {})",
                    CALIBRATION_KEYS.join(", ")
                ),
            ));
        }
    }
    let Some(pose) = dict.get_item("world_from_camera")? else {
        return Err(bad_value(
            "calibration",
            "missing key \"world_from_camera\"",
        ));
    };
    let m = floats("calibration[\"world_from_camera\"]", &pose)?;
    if m.len() != 16 {
        return Err(bad_value(
            "calibration[\"world_from_camera\"]",
            format!("expected a 4 x 4 matrix, got {} numbers", m.len()),
        ));
    }
    let camera = CameraJson {
        width_px: size(dict, "width_px")?,
        height_px: size(dict, "height_px")?,
        fx_px: number(dict, "fx_px")?,
        fy_px: number(dict, "fy_px")?,
        cx_px: number(dict, "cx_px")?,
        cy_px: number(dict, "cy_px")?,
        world_from_camera: std::array::from_fn(|r| std::array::from_fn(|c| m[r * 4 + c])),
    };
    let calibration = camera
        .calibration()
        .map_err(|(field, why)| bad_value(&format!("calibration[{field:?}]"), why))?;
    let height_m = number(dict, "plane_height_m")?;
    Ok((
        calibration.with_end_face_height(height_m),
        camera.width_px,
        camera.height_px,
    ))
}

/// Measures every bore in `image` (numpy uint8, H x W grey or H x W x 3 RGB, converted to luma
/// as `twincell measure` converts colour files).
///
/// Returns `{"circles": [...], "skipped": [...]}` as `twincell measure --json` does: each circle
/// has `cx`, `cy`, `r`, `roundness` (`Rmax - Rmin` about the fitted centre) and their one-sigma
/// uncertainties `sigma_c`, `sigma_r`, `sigma_roundness`, in pixels (x right, y down, pixel
/// centres at integers). With `calibration` (a dict: `width_px`, `height_px`, `fx_px`, `fy_px`,
/// `cx_px`, `cy_px`, `world_from_camera` as a 4 x 4 matrix, and `plane_height_m`, the end faces'
/// height in that world), each circle also has `cx_mm`, `cy_mm` (world frame), `r_mm`,
/// `roundness_mm` and `sigma_roundness_mm`, measured on the end-face plane.
#[pyfunction]
#[pyo3(signature = (image, calibration = None))]
pub fn measure<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
    calibration: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let gray = gray_image("image", image)?;
    let camera = match calibration {
        Some(value) if !value.is_none() => Some(calibration_of(value)?),
        _ => None,
    };
    if let Some((_, w, h)) = camera
        && gray.dimensions() != (w, h)
    {
        return Err(bad_value(
            "image",
            format!(
                "the image is {}x{} px but the calibration's width_px x height_px is {w}x{h}",
                gray.width(),
                gray.height()
            ),
        ));
    }
    let params = BoreDetectorParams::for_image(gray.width(), gray.height());
    let report = py
        .detach(|| BoreDetector::new(params).detect_report(&gray))
        .map_err(|e| match e {
            PerceptionError::ImageTooSmall { .. } => bad_value("image", e),
            other => PyRuntimeError::new_err(format!("the metrology failed: {other}")),
        })?;
    let circles = report
        .bores
        .iter()
        .map(|b| {
            let out = PyDict::new(py);
            out.set_item("cx", b.centre_px[0])?;
            out.set_item("cy", b.centre_px[1])?;
            out.set_item("r", b.radius_px)?;
            out.set_item("roundness", b.roundness_px)?;
            out.set_item("sigma_c", b.centre_sigma_px)?;
            out.set_item("sigma_r", b.radius_sigma_px)?;
            out.set_item("sigma_roundness", b.roundness_sigma_px)?;
            if let Some((camera, _, _)) = &camera
                && let Ok(plane) = camera.measure_on_plane(b, DEFAULT_MAX_UPR)
            {
                out.set_item("cx_mm", plane.centre_in_world.x * 1e3)?;
                out.set_item("cy_mm", plane.centre_in_world.y * 1e3)?;
                out.set_item("r_mm", plane.diameter_m * 0.5e3)?;
                out.set_item("roundness_mm", plane.raw_roundness_m * 1e3)?;
                out.set_item("sigma_roundness_mm", plane.roundness_sigma_m * 1e3)?;
            }
            Ok(out)
        })
        .collect::<PyResult<Vec<_>>>()?;
    let skipped = report
        .skipped
        .iter()
        .map(|s| {
            let out = PyDict::new(py);
            out.set_item("cx", s.centre_px[0])?;
            out.set_item("cy", s.centre_px[1])?;
            out.set_item("r", s.radius_px)?;
            out.set_item("visible_share", s.visible_share)?;
            out.set_item("reason", s.reason.describe())?;
            Ok(out)
        })
        .collect::<PyResult<Vec<_>>>()?;
    let out = PyDict::new(py);
    out.set_item("circles", circles)?;
    out.set_item("skipped", skipped)?;
    Ok(out)
}
