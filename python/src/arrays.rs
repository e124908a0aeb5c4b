//! numpy arrays in, checked: images and poses.

use image::{GrayImage, RgbImage};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};
use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// A `ValueError` that names the argument.
pub fn bad_value(arg: &str, reason: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("{arg}: {reason}"))
}

/// A `TypeError` that names the argument.
pub fn bad_type(arg: &str, reason: impl std::fmt::Display) -> PyErr {
    PyTypeError::new_err(format!("{arg}: {reason}"))
}

/// The shape and element type of `value` as numpy would print them, for messages.
fn describe(value: &Bound<'_, PyAny>) -> String {
    match (value.getattr("shape"), value.getattr("dtype")) {
        (Ok(shape), Ok(dtype)) => format!("an array of shape {shape} and dtype {dtype}"),
        _ => format!("a {}", value.get_type()),
    }
}

/// The uint8 array `value`, whatever its memory layout, as rows of pixels with `channels`
/// values each; `(width, height, bytes)`.
fn image_bytes(
    arg: &str,
    value: &Bound<'_, PyAny>,
    channels: usize,
) -> PyResult<(u32, u32, Vec<u8>)> {
    let Ok(array) = value.cast::<PyArrayDyn<u8>>() else {
        return Err(bad_type(
            arg,
            format!("expected a numpy uint8 array, got {}", describe(value)),
        ));
    };
    let shape = array.shape().to_vec();
    let (height, width) = match (shape.as_slice(), channels) {
        ([h, w], 1) => (*h, *w),
        ([h, w, c], _) if *c == channels => (*h, *w),
        _ => {
            let want = if channels == 1 { "H x W" } else { "H x W x 3" };
            return Err(bad_value(
                arg,
                format!("expected shape {want}, got {shape:?}"),
            ));
        }
    };
    if height == 0 || width == 0 {
        return Err(bad_value(arg, format!("the image is empty ({shape:?})")));
    }
    let (Ok(w), Ok(h)) = (u32::try_from(width), u32::try_from(height)) else {
        return Err(bad_value(
            arg,
            format!("the image is too large ({shape:?})"),
        ));
    };
    let readonly = array.try_readonly().map_err(|e| bad_value(arg, e))?;
    // Iterating the view in logical order copies any strided or non-contiguous layout.
    let bytes: Vec<u8> = readonly.as_array().iter().copied().collect();
    Ok((w, h, bytes))
}

/// An RGB image from a numpy uint8 array of shape H x W x 3.
pub fn rgb_image(arg: &str, value: &Bound<'_, PyAny>) -> PyResult<RgbImage> {
    let (w, h, bytes) = image_bytes(arg, value, 3)?;
    RgbImage::from_raw(w, h, bytes).ok_or_else(|| bad_value(arg, "inconsistent image size"))
}

/// A grey image from a numpy uint8 array of shape H x W, or H x W x 3 converted to luma as the
/// command line converts colour files.
pub fn gray_image(arg: &str, value: &Bound<'_, PyAny>) -> PyResult<GrayImage> {
    let ndim = value
        .cast::<PyArrayDyn<u8>>()
        .map(|a| a.ndim())
        .unwrap_or(0);
    if ndim == 2 {
        let (w, h, bytes) = image_bytes(arg, value, 1)?;
        return GrayImage::from_raw(w, h, bytes)
            .ok_or_else(|| bad_value(arg, "inconsistent image size"));
    }
    let rgb = rgb_image(arg, value)?;
    Ok(image::DynamicImage::ImageRgb8(rgb).to_luma8())
}

/// Finite floats from any sequence or array of numbers.
pub fn floats(arg: &str, value: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    let numpy = value.py().import("numpy")?;
    let array = numpy
        .call_method1("asarray", (value,))
        .and_then(|a| a.call_method1("astype", ("float64",)))
        .map_err(|_| bad_type(arg, format!("expected numbers, got {}", value.get_type())))?;
    let Ok(array) = array.cast::<PyArrayDyn<f64>>() else {
        return Err(bad_type(arg, "expected numbers"));
    };
    let values: Vec<f64> = array.readonly().as_array().iter().copied().collect();
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(not_finite(arg, i, values[i]));
    }
    Ok(values)
}

/// Element `i` of `arg` is `value`, not a finite number.
fn not_finite(arg: &str, i: usize, value: f64) -> PyErr {
    // Spelled as Python prints it.
    let shown = match value {
        v if v.is_nan() => "nan",
        v if v > 0.0 => "inf",
        _ => "-inf",
    };
    bad_value(arg, format!("element {i} is {shown} (not a finite number)"))
}

/// The shape of `value` as an array of numbers.
fn shape_of(value: &Bound<'_, PyAny>) -> PyResult<Vec<usize>> {
    let numpy = value.py().import("numpy")?;
    numpy.call_method1("shape", (value,))?.extract()
}

/// Six joint angles, rad.
pub fn joints(arg: &str, value: &Bound<'_, PyAny>) -> PyResult<[f64; 6]> {
    // A float64 array of six, the common case (every step of an environment), read directly.
    if let Ok(array) = value.cast::<PyArray1<f64>>()
        && let Ok(readonly) = array.try_readonly()
        && let Ok(slice) = readonly.as_slice()
        && let Ok(q) = <[f64; 6]>::try_from(slice)
    {
        if let Some(i) = q.iter().position(|v| !v.is_finite()) {
            return Err(not_finite(arg, i, q[i]));
        }
        return Ok(q);
    }
    let shape = shape_of(value).map_err(|_| bad_type(arg, "expected 6 joint angles"))?;
    if shape != [6] {
        return Err(bad_value(
            arg,
            format!("expected 6 joint angles (shape (6,)), got shape {shape:?}"),
        ));
    }
    let values = floats(arg, value)?;
    let mut q = [0.0; 6];
    q.copy_from_slice(&values);
    Ok(q)
}

/// A pose: `[x, y, z, roll, pitch, yaw]` (m, rad, R = Rz(yaw) Ry(pitch) Rx(roll), as the
/// command line's `ik`) or a 4 x 4 homogeneous matrix.
pub fn pose(arg: &str, value: &Bound<'_, PyAny>) -> PyResult<Isometry3<f64>> {
    let shape = shape_of(value).map_err(|_| bad_type(arg, "expected a pose"))?;
    let expected = "expected [x, y, z, roll, pitch, yaw] or a 4 x 4 matrix";
    match shape.as_slice() {
        [6] => {
            let v = floats(arg, value)?;
            Ok(Isometry3::from_parts(
                Translation3::new(v[0], v[1], v[2]),
                UnitQuaternion::from_euler_angles(v[3], v[4], v[5]),
            ))
        }
        [4, 4] => {
            let v = floats(arg, value)?;
            let m = |r: usize, c: usize| v[r * 4 + c];
            let rotation = Matrix3::from_fn(m);
            if (rotation.transpose() * rotation - Matrix3::identity()).norm() > 1e-6
                || rotation.determinant() < 0.0
                || [m(3, 0), m(3, 1), m(3, 2), m(3, 3)] != [0.0, 0.0, 0.0, 1.0]
            {
                return Err(bad_value(
                    arg,
                    "not a rigid transform (a rotation, a translation and the last row 0 0 0 1)",
                ));
            }
            Ok(Isometry3::from_parts(
                Translation3::new(m(0, 3), m(1, 3), m(2, 3)),
                UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rotation)),
            ))
        }
        _ => Err(bad_value(arg, format!("{expected}, got shape {shape:?}"))),
    }
}
