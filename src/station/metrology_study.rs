//! The metrology's measurement-system study (`twincell calibrate`): shots of parts whose sizes
//! are known, measured the way the closed loop measures its target (the part's area of
//! interest read at the sensor's full pitch, the bore found in it and measured on the end-face
//! plane at the type's height), and the errors summed up as bias and expanded uncertainty.
//!
//! The study locates each part from its known pose (the box its silhouette projects to), not
//! through the detector: it studies the metrology, and a part the detector misses is the
//! detector's failure, counted by `run`.

use image::imageops::grayscale;
use serde::Serialize;

use super::bore_floor::station_bore_params;
use super::camera_percept::{bore_detector_at, find_in_window, measure_found, part_window};
use crate::perception::BoreDetector;
use crate::perception::identify::read_on_plane;
use crate::render::{CameraRig, RenderError, Renderer, Shot};
use crate::scenario::Scenario;

/// Coverage factor of the expanded uncertainty (about 95 % for a normal error).
pub const COVERAGE_K: f64 = 2.0;

/// What is known of the part a shot shows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KnownPart {
    /// Index of the part's object in the shot's scene.
    pub object_index: usize,
    /// Mean bore diameter, m.
    pub bore_diameter_m: f64,
    /// Outer diameter, m.
    pub outer_diameter_m: f64,
    /// Bore roundness `Rmax - Rmin`, m.
    pub roundness_m: f64,
    /// The end face's height in the world as the closed loop takes it (the belt's top plus the
    /// type's height), m.
    pub end_face_z_m: f64,
}

/// One shot's measurement errors (measured minus true), m; `None` where nothing was measured.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ShotErrors {
    /// Roundness error.
    pub roundness_m: Option<f64>,
    /// Bore diameter error.
    pub bore_diameter_m: Option<f64>,
    /// Outer diameter error (only where the rim's outer edge was found).
    pub outer_diameter_m: Option<f64>,
}

/// The metrology of one camera, as the closed loop runs it.
#[derive(Debug)]
pub struct MetrologyStudy {
    rig: CameraRig,
    roi_scale: u32,
    bore_detector: BoreDetector,
}

impl MetrologyStudy {
    /// The metrology of `scenario`'s camera `rig`, whose sensor reads areas of interest at the
    /// scenario's `roi_scale` pixels a frame pixel, with the closed loop's bore finder.
    pub fn new(scenario: &Scenario, rig: CameraRig) -> Self {
        let roi_scale = scenario.camera.roi_scale;
        Self {
            bore_detector: BoreDetector::new(station_bore_params(
                scenario,
                &rig.calibration,
                roi_scale,
            )),
            rig,
            roi_scale,
        }
    }

    /// Renders `part`'s area of interest in `shot` of `scenario` and measures it against the
    /// truth.
    pub fn measure(
        &self,
        renderer: &mut Renderer,
        scenario: &Scenario,
        shot: &Shot,
        part: &KnownPart,
    ) -> Result<ShotErrors, RenderError> {
        let truths = shot.truth(scenario);
        let Some(truth) = truths
            .iter()
            .find(|t| t.object_index == part.object_index && t.bore.is_some())
        else {
            return Ok(ShotErrors::default());
        };
        let [x0, y0, x1, y1] = truth.bbox_px.map(f64::from);
        // The box's last column and row are inclusive pixels: its right and bottom edges lie
        // one pixel on.
        let box_px = [x0, y0, x1 + 1.0, y1 + 1.0];
        let frame = (self.rig.width_px, self.rig.height_px);
        let Some(window) = part_window(&box_px, frame, self.roi_scale) else {
            return Ok(ShotErrors::default());
        };
        let gpu = renderer.upload(&shot.scene);
        let image = shot.render_window(renderer, &gpu, &window)?;
        let gray = grayscale(&image);
        let calibration = self.rig.calibration.with_end_face_height(part.end_face_z_m);
        // The finder as the closed loop widens it for the part's angle from the vertical.
        let finder = bore_detector_at(
            &self.bore_detector,
            &self.rig.calibration,
            &box_px,
            part.end_face_z_m,
        );
        let measured = find_in_window(&finder, &gray, &window, &box_px)
            .and_then(|bore| measure_found(bore, &window, &calibration));
        let Some((bore, plane)) = measured else {
            return Ok(ShotErrors::default());
        };
        // The outer edge read as the type reader reads it: on the end-face plane, through the
        // area of interest's camera (the bore is in frame pixels now, so the frame's).
        let outer = read_on_plane(&bore, &calibration, part.outer_diameter_m / 2.0)
            .and_then(|reading| reading.outer_m)
            .map(|outer| outer - part.outer_diameter_m);
        Ok(ShotErrors {
            roundness_m: Some(plane.roundness_m - part.roundness_m),
            bore_diameter_m: Some(plane.diameter_m - part.bore_diameter_m),
            outer_diameter_m: outer,
        })
    }
}

/// Bias and expanded uncertainty of one measured quantity, mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrorSummary {
    /// Shots that measured it.
    pub n: usize,
    /// Mean error (measured minus true).
    pub bias_mm: f64,
    /// Sample standard deviation of the error (repeatability and reproducibility over the
    /// drawn parts, places, lights and sensor effects).
    pub sd_mm: f64,
    /// Expanded uncertainty, `k * sqrt(bias^2 + sd^2)` with k = [`COVERAGE_K`]: the bias is
    /// not corrected, so it counts in the uncertainty.
    pub expanded_uncertainty_mm: f64,
    /// Largest error magnitude.
    pub max_abs_mm: f64,
}

impl ErrorSummary {
    /// The summary of `errors_m` (m); `None` with fewer than two.
    pub fn of(errors_m: &[f64]) -> Option<Self> {
        let n = errors_m.len();
        if n < 2 {
            return None;
        }
        let mm: Vec<f64> = errors_m.iter().map(|e| e * 1e3).collect();
        let bias = mm.iter().sum::<f64>() / n as f64;
        let var = mm.iter().map(|e| (e - bias).powi(2)).sum::<f64>() / (n - 1) as f64;
        let sd = var.sqrt();
        Some(Self {
            n,
            bias_mm: bias,
            sd_mm: sd,
            expanded_uncertainty_mm: COVERAGE_K * bias.hypot(sd),
            max_abs_mm: mm.iter().fold(0.0, |m, e| m.max(e.abs())),
        })
    }
}

/// The study's result over all shots.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StudySummary {
    /// Shots rendered.
    pub shots: usize,
    /// Shots in which no bore was measured.
    pub not_measured: usize,
    /// Roundness.
    pub roundness: Option<ErrorSummary>,
    /// Bore diameter.
    pub bore_diameter: Option<ErrorSummary>,
    /// Outer diameter.
    pub outer_diameter: Option<ErrorSummary>,
}

impl StudySummary {
    /// Sums up the shots' errors.
    pub fn of(shots: &[ShotErrors]) -> Self {
        let collect = |pick: fn(&ShotErrors) -> Option<f64>| -> Vec<f64> {
            shots.iter().filter_map(pick).collect()
        };
        Self {
            shots: shots.len(),
            not_measured: shots.iter().filter(|s| s.roundness_m.is_none()).count(),
            roundness: ErrorSummary::of(&collect(|s| s.roundness_m)),
            bore_diameter: ErrorSummary::of(&collect(|s| s.bore_diameter_m)),
            outer_diameter: ErrorSummary::of(&collect(|s| s.outer_diameter_m)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_uncertainty_counts_bias_and_spread() {
        let Some(s) = ErrorSummary::of(&[0.001e-3, 0.003e-3, 0.005e-3]) else {
            panic!("three errors give a summary");
        };
        assert!((s.bias_mm - 0.003).abs() < 1e-12);
        assert!((s.sd_mm - 0.002).abs() < 1e-12);
        assert!((s.expanded_uncertainty_mm - 2.0 * 0.003f64.hypot(0.002)).abs() < 1e-12);
        assert!((s.max_abs_mm - 0.005).abs() < 1e-12);
        assert!(ErrorSummary::of(&[0.1]).is_none());
    }
}
