//! Errors of the perception layer.

/// Why a perception step could not produce a result (as opposed to finding nothing).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PerceptionError {
    /// The image is too small for the filters and the ring tests.
    #[error(
        "image is {width_px}x{height_px} px; the pipeline needs at least {min_side_px} px a side"
    )]
    ImageTooSmall {
        /// Image width.
        width_px: u32,
        /// Image height.
        height_px: u32,
        /// Smallest accepted side.
        min_side_px: u32,
    },
    /// A parameter is outside its valid range.
    #[error("invalid parameter {name}: {reason}")]
    InvalidParam {
        /// Parameter name.
        name: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// A circle fit got too few points or points on a line.
    #[error("circle fit is degenerate with {point_count} points")]
    DegenerateFit {
        /// Number of points given to the fit.
        point_count: usize,
    },
    /// A pixel's viewing ray does not meet the end-face plane in front of the camera.
    #[error("the ray through pixel ({x_px:.2}, {y_px:.2}) does not meet the end-face plane")]
    RayMissesPlane {
        /// Pixel x.
        x_px: f64,
        /// Pixel y.
        y_px: f64,
    },
}

impl From<crate::camera::RayMissesPlane> for PerceptionError {
    fn from(e: crate::camera::RayMissesPlane) -> Self {
        Self::RayMissesPlane {
            x_px: e.x_px,
            y_px: e.y_px,
        }
    }
}
