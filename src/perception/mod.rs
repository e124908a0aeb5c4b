//! Vision metrology of tube end faces: images and calibration in, measurements out.
//!
//! The camera looks down on tubes standing upright: a bright machined annulus (the rim) around a
//! dark bore, on a dark belt. This module finds every such bore and measures its centre, radius and
//! roundness (`Rmax - Rmin` about the fitted centre, eq. 11 of the seed paper), first in pixels and,
//! given a [`calibration::CameraCalibration`], in metres on the end-face plane.
//!
//! It never touches a physics world: everything here is testable on images alone.
//!
//! Stages, one module each, following section 2.3+ of the seed paper:
//! [`filters`] (mean, median, Gaussian) -> [`threshold`] (adaptive mean/Gaussian, Otsu, isodata)
//! -> [`contours`] (border following) / [`edges`] (Canny) -> [`rim`] (the annulus around a
//! candidate: flat, and how wide) -> [`subpixel`] (radial edge refinement, on [`ray_samples`])
//! -> [`circle_fit`] (Kasa, Pratt, Gauss-Newton) -> [`roundness`] (filtered `Rmax - Rmin`);
//! [`bore`] chains them and applies the geometric tests that tell a bore from a bottle or a stain.
//! No stage assumes the part catalogue: walls of any ratio, bores from 12 px, dark or grey belts.
//! [`synthetic`] and [`scene_space`] draw test images with known truth.

pub mod border_cut;
pub mod bore;
pub mod bore_params;
pub mod calibration;
pub mod circle_fit;
pub(crate) mod contour_scan;
pub mod contours;
pub mod edges;
pub mod error;
pub mod filters;
pub mod identify;
pub mod integer_edges;
pub mod max_threshold;
pub mod ray_samples;
pub mod rim;
pub mod rim_stain;
pub mod robust_series;
pub mod roundness;
pub mod roundness_noise;
pub mod running_sums;
pub mod scene_draw;
pub mod scene_heavy;
pub mod scene_space;
pub(crate) mod segment;
pub mod subpixel;
pub mod synthetic;
pub mod threshold;

pub use bore::{
    Bore, BoreDetector, BoreDetectorParams, BoreReport, EdgeMode, SkipReason, SkippedBore,
};
pub use error::PerceptionError;
