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
//! -> [`contours`] (border following) / [`edges`] (Canny) -> [`subpixel`] (radial edge refinement)
//! -> [`circle_fit`] (Kasa, Pratt, Gauss-Newton) -> [`roundness`] (filtered `Rmax - Rmin`);
//! [`bore`] chains them and applies the geometric tests that tell a bore from a bottle or a stain.

pub mod bore;
pub mod calibration;
pub mod circle_fit;
pub mod contours;
pub mod edges;
pub mod error;
pub mod filters;
pub mod roundness;
pub mod subpixel;
pub mod synthetic;
pub mod threshold;

pub use bore::{Bore, BoreDetector, BoreDetectorParams, EdgeMode};
pub use error::PerceptionError;
