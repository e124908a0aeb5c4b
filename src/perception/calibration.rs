//! Measuring on the end-face plane through the calibrated camera: a bore fitted in the image,
//! back-projected and fitted again in metres.

pub use crate::camera::CameraCalibration;
use crate::perception::bore::Bore;
use crate::perception::circle_fit::fit_geometric_over_angle;
use crate::perception::error::PerceptionError;
use crate::perception::roundness_noise::noise_adjusted_roundness_bridged;
use nalgebra::Point3;

/// A bore measured on the end-face plane, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneBore {
    /// Centre on the end-face plane, world frame.
    pub centre_in_world: Point3<f64>,
    /// Diameter of the fitted circle.
    pub diameter_m: f64,
    /// `Rmax - Rmin` about the fitted centre, of the profile low-passed to the cutoff with the
    /// edge noise taken out of each harmonic ([`crate::perception::roundness_noise`]).
    pub roundness_m: f64,
    /// `Rmax - Rmin` about the fitted centre of the profile low-passed to the cutoff, the edge
    /// noise left in: the image's `roundness` on the plane (what `twincell measure` reports).
    pub raw_roundness_m: f64,
    /// One-sigma uncertainty of each centre coordinate.
    pub centre_sigma_m: f64,
    /// One-sigma uncertainty of the diameter.
    pub diameter_sigma_m: f64,
    /// One-sigma uncertainty of the roundness.
    pub roundness_sigma_m: f64,
}

/// A [`PlaneBore`] in millimetres, for reports.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PlaneBoreReportMm {
    /// Centre x, world frame.
    pub x_mm: f64,
    /// Centre y, world frame.
    pub y_mm: f64,
    /// Diameter.
    pub diameter_mm: f64,
    /// Roundness.
    pub roundness_mm: f64,
    /// One-sigma centre uncertainty.
    pub centre_sigma_mm: f64,
    /// One-sigma diameter uncertainty.
    pub diameter_sigma_mm: f64,
    /// One-sigma roundness uncertainty.
    pub roundness_sigma_mm: f64,
}

impl PlaneBore {
    /// The same measurement in millimetres.
    pub fn report_mm(&self) -> PlaneBoreReportMm {
        PlaneBoreReportMm {
            x_mm: self.centre_in_world.x * 1e3,
            y_mm: self.centre_in_world.y * 1e3,
            diameter_mm: self.diameter_m * 1e3,
            roundness_mm: self.roundness_m * 1e3,
            centre_sigma_mm: self.centre_sigma_m * 1e3,
            diameter_sigma_mm: self.diameter_sigma_m * 1e3,
            roundness_sigma_mm: self.roundness_sigma_m * 1e3,
        }
    }
}

/// Measurement of a fitted bore on a calibrated camera's end-face plane.
pub trait MeasureOnPlane {
    /// Measures `bore` on the end-face plane: its edge points (and bridge points) are
    /// back-projected onto the plane and fitted there, so perspective and camera tilt do not
    /// distort the result.
    fn measure_on_plane(&self, bore: &Bore, max_upr: usize) -> Result<PlaneBore, PerceptionError>;
}

impl MeasureOnPlane for CameraCalibration {
    fn measure_on_plane(&self, bore: &Bore, max_upr: usize) -> Result<PlaneBore, PerceptionError> {
        let on_plane = |points: &[[f64; 2]]| -> Result<Vec<[f64; 2]>, PerceptionError> {
            points
                .iter()
                .map(|p| {
                    self.pixel_to_plane(p[0], p[1])
                        .map(|q| [q.x, q.y])
                        .map_err(PerceptionError::from)
                })
                .collect()
        };
        let points_on_plane = on_plane(&bore.edge_points_px)?;
        let bridges_on_plane = on_plane(&bore.bridge_points_px)?;
        let fit = fit_geometric_over_angle(&points_on_plane)?;
        let (profile, roundness) = noise_adjusted_roundness_bridged(
            &points_on_plane,
            &bridges_on_plane,
            fit.centre,
            max_upr,
        )?;
        let n = points_on_plane.len() as f64;
        let sigma = profile.noise_sigma();
        Ok(PlaneBore {
            centre_in_world: Point3::new(fit.centre[0], fit.centre[1], self.end_face_height_m),
            diameter_m: 2.0 * fit.radius,
            roundness_m: roundness,
            raw_roundness_m: profile.roundness,
            centre_sigma_m: sigma * (2.0 / n).sqrt(),
            diameter_sigma_m: 2.0 * sigma / n.sqrt(),
            roundness_sigma_m: profile.roundness_sigma(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::overhead_camera;
    use crate::perception::roundness::DEFAULT_MAX_UPR;

    #[test]
    fn a_circle_on_the_plane_measures_its_diameter() {
        let calibration = overhead_camera();
        let (centre, radius_m) = (Point3::new(0.12, -0.03, 0.1), 0.02);
        let edge_points_px: Vec<[f64; 2]> = (0..720)
            .filter_map(|i| {
                let t = std::f64::consts::TAU * f64::from(i) / 720.0;
                calibration.project(&Point3::new(
                    centre.x + radius_m * t.cos(),
                    centre.y + radius_m * t.sin(),
                    0.1,
                ))
            })
            .collect();
        let bore = Bore {
            centre_px: [0.0, 0.0],
            radius_px: 0.0,
            roundness_px: 0.0,
            centre_sigma_px: 0.0,
            radius_sigma_px: 0.0,
            roundness_sigma_px: 0.0,
            edge_points_px,
            bridge_points_px: Vec::new(),
            coverage: 1.0,
            contrast_ratio: 1.0,
            outer_ratio: 1.5,
            outer_edge_points_px: Vec::new(),
        };
        let Ok(measured) = calibration.measure_on_plane(&bore, DEFAULT_MAX_UPR) else {
            panic!("measure failed");
        };
        assert!((measured.diameter_m - 0.04).abs() < 1e-9);
        assert!((measured.centre_in_world - centre).norm() < 1e-9);
        assert!(measured.roundness_m < 1e-9);
        let report = measured.report_mm();
        assert!((report.diameter_mm - 40.0).abs() < 1e-6);
    }
}
