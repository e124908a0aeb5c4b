//! What one exposure brings besides the scene: the camera as it stands and the light on the
//! scene; and the options fixed for a renderer's life.

use nalgebra::{Point3, Vector3};

use crate::camera::CameraCalibration;

/// Most lights a frame may use.
pub const MAX_LIGHTS: usize = 4;
/// Most stain blobs a frame may use.
pub const MAX_STAIN_BLOBS: usize = 32;

/// A directional light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Light {
    /// Direction the light travels, world frame, unit length.
    pub direction_in_world: Vector3<f64>,
    /// Intensity (1 lights a white surface facing it fully).
    pub intensity: f64,
}

/// A soft dark blob on a stainable surface: one lobe of an oil stain or a speck of dirt.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StainBlob {
    /// Centre, world frame (on the surface).
    pub centre_in_world: Point3<f64>,
    /// Radius, m.
    pub radius_m: f64,
    /// Share of light the stain lets through at its core.
    pub transmission: f64,
    /// Share of the radius over which the stain fades out.
    pub soft_edge: f64,
}

/// Everything about one exposure besides the scene: the camera and the light on the scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Exposure {
    /// The camera as it really stands (calibration plus any pose jitter).
    pub camera: CameraCalibration,
    /// Image width, pixels.
    pub width_px: u32,
    /// Image height, pixels.
    pub height_px: u32,
    /// Ambient light, a share of full light.
    pub ambient: f64,
    /// Directional lights (at most [`MAX_LIGHTS`]).
    pub lights: Vec<Light>,
    /// Stains and dirt (at most [`MAX_STAIN_BLOBS`]).
    pub stains: Vec<StainBlob>,
}

/// Options fixed for a renderer's life.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RendererOptions {
    /// MSAA samples per pixel: 1 or 4.
    pub msaa_samples: u32,
    /// Supersampling per axis (1 to 4) on top of MSAA.
    pub supersample: u32,
}

impl Default for RendererOptions {
    fn default() -> Self {
        Self {
            msaa_samples: 4,
            supersample: 1,
        }
    }
}
