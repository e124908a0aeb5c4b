//! Millimetres and conformity verdicts for `twincell measure` (see the parent module).

use serde::Serialize;
use std::path::Path;
use twincell::perception::calibration::CameraCalibration;
use twincell::perception::calibration::MeasureOnPlane;
use twincell::perception::roundness::DEFAULT_MAX_UPR;

use super::{CircleOut, MeasureArgs};
use crate::cli::BadInput;
use twincell::camera::CameraJson;

/// A circle in millimetres and its verdict.
#[derive(Debug, Serialize)]
pub(super) struct CircleMm {
    pub(super) cx_mm: f64,
    pub(super) cy_mm: f64,
    pub(super) r_mm: f64,
    pub(super) roundness_mm: f64,
    pub(super) sigma_roundness_mm: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) guard_band_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(super) verdict: Option<Verdict>,
}

/// Conformity of a roundness to its tolerance, given the measurement's uncertainty band.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub(super) enum Verdict {
    Conforming,
    NotConforming,
    Undecided,
}

impl Verdict {
    /// The verdict as the JSON writes it.
    pub(super) fn name(&self) -> &'static str {
        match self {
            Self::Conforming => "conforming",
            Self::NotConforming => "not_conforming",
            Self::Undecided => "undecided",
        }
    }

    fn of(roundness_mm: f64, tolerance_mm: f64, band_mm: f64) -> Self {
        if roundness_mm + band_mm <= tolerance_mm {
            Self::Conforming
        } else if roundness_mm - band_mm > tolerance_mm {
            Self::NotConforming
        } else {
            Self::Undecided
        }
    }
}

/// The detector's roundness error beyond edge noise, pixels: the model part of the default
/// guard band, beside each circle's own edge-noise sigma. The suite over the whole space
/// (`tests/metrology_space.rs`) measures a roundness MAE of 0.06 px, its heavy-noise frames
/// 0.16 px (`tests/perception_accuracy.rs`): 0.15 px covers the noisy frames.
pub const ROUNDNESS_MODEL_UNCERTAINTY_PX: f64 = 0.15;

/// How pixels become millimetres.
#[derive(Debug, Clone, Copy)]
pub(super) enum Scale {
    PxPerMm(f64),
    Camera(CameraCalibration, u32, u32),
}

pub(super) fn positive(flag: &str, value: f64) -> anyhow::Result<()> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(BadInput(format!("{flag}: {value} is not a positive number")).into())
    }
}

/// The scale the arguments ask for, if any.
pub(super) fn scale_of(args: &MeasureArgs) -> anyhow::Result<Option<Scale>> {
    if let Some(s) = args.px_per_mm {
        positive("--px-per-mm", s)?;
        return Ok(Some(Scale::PxPerMm(s)));
    }
    let (Some(path), Some(height_m)) = (&args.calibration, args.plane_height_m) else {
        return Ok(None);
    };
    if !height_m.is_finite() {
        return Err(BadInput(format!("--plane-height-m: {height_m} is not a number")).into());
    }
    let (calibration, w, h) = load_calibration(path)?;
    Ok(Some(Scale::Camera(
        calibration.with_end_face_height(height_m),
        w,
        h,
    )))
}

/// Reads a camera JSON: `shot.json` (its `calibration` object) or the object alone.
fn load_calibration(path: &Path) -> anyhow::Result<(CameraCalibration, u32, u32)> {
    let shown = path.display();
    let text = std::fs::read_to_string(path)
        .map_err(|e| BadInput(format!("{shown}: cannot read calibration: {e}")))?;
    let value: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| BadInput(format!("{shown}: bad calibration JSON: {e}")))?;
    let (key, object) = match value.get("calibration") {
        Some(inner) => ("calibration", inner.clone()),
        None => ("(top level)", value),
    };
    let camera: CameraJson = serde_json::from_value(object)
        .map_err(|e| BadInput(format!("{shown}: key `{key}`: {e}")))?;
    let calibration = camera
        .calibration()
        .map_err(|(field, why)| BadInput(format!("{shown}: key `{key}.{field}`: {why}")))?;
    Ok((calibration, camera.width_px, camera.height_px))
}

/// One circle of the output, with millimetres and a verdict when asked for.
pub(super) fn circle_out(
    b: &twincell::perception::Bore,
    scale: Option<Scale>,
    args: &MeasureArgs,
) -> CircleOut {
    let mm = scale.and_then(|scale| {
        // Millimetres per pixel at this circle, for the model uncertainty.
        let (cx_mm, cy_mm, r_mm, roundness_mm, sigma_mm, mm_per_px) = match scale {
            Scale::PxPerMm(s) => (
                b.centre_px[0] / s,
                b.centre_px[1] / s,
                b.radius_px / s,
                b.roundness_px / s,
                b.roundness_sigma_px / s,
                1.0 / s,
            ),
            Scale::Camera(calibration, _, _) => {
                let plane = calibration.measure_on_plane(b, DEFAULT_MAX_UPR).ok()?;
                let px_per_m = calibration
                    .px_per_m_at(b.centre_px[0], b.centre_px[1])
                    .ok()?;
                (
                    plane.centre_in_world.x * 1e3,
                    plane.centre_in_world.y * 1e3,
                    plane.diameter_m * 0.5e3,
                    // Rmax - Rmin on the plane, as the image's `roundness` is in pixels.
                    plane.raw_roundness_m * 1e3,
                    plane.roundness_sigma_m * 1e3,
                    1e3 / px_per_m,
                )
            }
        };
        let guard_band_mm = args.tolerance_mm.map(|_| {
            args.guard_band_mm
                .unwrap_or_else(|| 2.0 * sigma_mm.hypot(ROUNDNESS_MODEL_UNCERTAINTY_PX * mm_per_px))
        });
        let verdict = args
            .tolerance_mm
            .zip(guard_band_mm)
            .map(|(t, g)| Verdict::of(roundness_mm, t, g));
        Some(CircleMm {
            cx_mm,
            cy_mm,
            r_mm,
            roundness_mm,
            sigma_roundness_mm: sigma_mm,
            guard_band_mm,
            verdict,
        })
    });
    CircleOut {
        cx: b.centre_px[0],
        cy: b.centre_px[1],
        r: b.radius_px,
        roundness: b.roundness_px,
        sigma_c: b.centre_sigma_px,
        sigma_r: b.radius_sigma_px,
        sigma_roundness: b.roundness_sigma_px,
        mm,
    }
}
