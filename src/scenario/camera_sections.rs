//! The camera's sections of a scenario: the camera itself, the cell's lights, and the sensor's
//! realism (noise, stains, jitter).

use serde::{Deserialize, Serialize};

use super::ConveyorSection;

/// The camera: a pinhole without distortion, looking down at the pick station from anywhere in
/// the camera envelope ([`CAMERA_ENVELOPE`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraSection {
    /// Image width and height, pixels.
    pub resolution_px: [u32; 2],
    /// Horizontal field of view, degrees.
    pub horizontal_fov_deg: f64,
    /// Camera centre in the world, m (default: 0.58 m above the belt at the photo-eye).
    pub position_m: Option<[f64; 3]>,
    /// Point the optical axis passes through, m (default: the belt's top at the photo-eye).
    pub look_at_m: Option<[f64; 3]>,
    /// The camera turned about its optical axis, degrees: clockwise as seen from behind the
    /// camera (its image x axis towards its y axis). At 0 the image's x axis is as close to the
    /// world's +x, along the belt, as the view allows.
    pub roll_deg: f64,
    /// Multisample anti-aliasing samples per pixel (1 or 4).
    pub msaa_samples: u32,
    /// Supersampling factor per axis on top of MSAA (1 to 4): renders larger and box-filters.
    pub supersample: u32,
    /// Sensor pixels per frame pixel along each axis (1 to 4). The sensor delivers the whole
    /// frame at `resolution_px` (binned) for detection and reads the target part's area of
    /// interest at its full pitch for the bore metrology.
    pub roi_scale: u32,
    /// Exposure time, ms: items the belt carries during it smear along the belt's direction
    /// (`render::motion_blur`). 0: an instant frame.
    #[serde(skip_serializing_if = "is_zero")]
    pub exposure_ms: f64,
}

fn is_zero(value: &f64) -> bool {
    *value == 0.0
}

impl Default for CameraSection {
    fn default() -> Self {
        Self {
            resolution_px: [1280, 960],
            horizontal_fov_deg: 44.0,
            position_m: None,
            look_at_m: None,
            roll_deg: 0.0,
            msaa_samples: 4,
            supersample: 1,
            roi_scale: 2,
            exposure_ms: 0.0,
        }
    }
}

/// Camera height above the belt when the scenario gives no position, m.
pub const DEFAULT_CAMERA_HEIGHT_ABOVE_BELT_M: f64 = 0.58;

/// The cameras the perception is built and trained for: where a `[camera]` may be and what it
/// may be. Validation refuses a camera outside it; the detector's training data is drawn over it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraEnvelope {
    /// Largest angle between the optical axis and straight down, degrees (in any direction).
    pub max_tilt_deg: f64,
    /// Distance from the camera centre to the pick station (the belt's top at the photo-eye),
    /// least and most, m.
    pub distance_m: [f64; 2],
    /// Horizontal field of view, least and most, degrees.
    pub horizontal_fov_deg: [f64; 2],
    /// Smallest image, width and height, pixels.
    pub min_resolution_px: [u32; 2],
    /// Largest image, width and height, pixels.
    pub max_resolution_px: [u32; 2],
    /// Roll about the optical axis, least and most, degrees (any roll).
    pub roll_deg: [f64; 2],
}

/// The camera envelope (issue 24): up to 35 degrees from vertical in any direction, 0.35-1.2 m
/// from the pick station, any roll, a horizontal field of view of 35-80 degrees, 640 x 480 to
/// 2048 x 1536 pixels.
pub const CAMERA_ENVELOPE: CameraEnvelope = CameraEnvelope {
    max_tilt_deg: 35.0,
    distance_m: [0.35, 1.2],
    horizontal_fov_deg: [35.0, 80.0],
    min_resolution_px: [640, 480],
    max_resolution_px: [2048, 1536],
    roll_deg: [-180.0, 180.0],
};

impl std::fmt::Display for CameraEnvelope {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the camera envelope: optical axis at most {} degrees from vertical, {}-{} m from the \
             pick station, roll in [{}, {}] degrees, horizontal field of view {}-{} degrees, \
             {} x {} to {} x {} pixels",
            self.max_tilt_deg,
            self.distance_m[0],
            self.distance_m[1],
            self.roll_deg[0],
            self.roll_deg[1],
            self.horizontal_fov_deg[0],
            self.horizontal_fov_deg[1],
            self.min_resolution_px[0],
            self.min_resolution_px[1],
            self.max_resolution_px[0],
            self.max_resolution_px[1]
        )
    }
}

impl CameraSection {
    /// The camera centre and the point it looks at, world frame, m.
    pub fn eye_and_target(&self, conveyor: &ConveyorSection) -> ([f64; 3], [f64; 3]) {
        let [_, y, z] = conveyor.belt_center_m;
        let station = [conveyor.photo_eye_x_m, y, z];
        let eye = self.position_m.unwrap_or([
            station[0],
            station[1],
            z + DEFAULT_CAMERA_HEIGHT_ABOVE_BELT_M,
        ]);
        (eye, self.look_at_m.unwrap_or(station))
    }

    /// The pick station the camera envelope is measured from: the belt's top at the photo-eye.
    pub fn pick_station(conveyor: &ConveyorSection) -> [f64; 3] {
        let [_, y, z] = conveyor.belt_center_m;
        [conveyor.photo_eye_x_m, y, z]
    }

    /// The optical axis's angle from straight down, degrees, and the camera centre's distance
    /// from the pick station, m.
    pub fn tilt_and_distance(&self, conveyor: &ConveyorSection) -> (f64, f64) {
        let (eye, target) = self.eye_and_target(conveyor);
        let view = [target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]];
        let length = view.iter().map(|v| v * v).sum::<f64>().sqrt();
        let tilt = if length > 0.0 {
            (-view[2] / length).clamp(-1.0, 1.0).acos().to_degrees()
        } else {
            f64::NAN
        };
        let station = Self::pick_station(conveyor);
        let distance = (0..3)
            .map(|k| (eye[k] - station[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        (tilt, distance)
    }
}

/// One directional light.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightSpec {
    /// Direction the light travels, world frame (need not be unit length).
    pub direction: [f64; 3],
    /// Intensity (1 lights a white surface facing it fully).
    pub intensity: f64,
}

/// The cell's lights: directional lights plus an ambient term.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LightingSection {
    /// Ambient light, as a share of full light.
    pub ambient: f64,
    /// Directional lights (at most 4).
    pub lights: Vec<LightSpec>,
}

impl Default for LightingSection {
    fn default() -> Self {
        Self {
            ambient: 0.22,
            lights: vec![
                // A ceiling key light a little off the vertical, and a weak fill from the side.
                LightSpec {
                    direction: [0.25, 0.35, -1.0],
                    intensity: 0.75,
                },
                LightSpec {
                    direction: [-0.6, -0.2, -0.5],
                    intensity: 0.25,
                },
            ],
        }
    }
}

/// Realism drawn per image from the seed: sensor noise, optics, dirt and small set-up changes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorSection {
    /// Gaussian noise, one sigma, grey levels (0-255).
    pub noise_sigma: f64,
    /// Share of pixels hit by salt-and-pepper noise.
    pub salt_pepper_fraction: f64,
    /// Largest illumination gradient: relative brightness change from image centre to edge.
    pub illumination_gradient: f64,
    /// Vignetting: relative darkening at the image corners.
    pub vignetting: f64,
    /// Most oil stains on a part's end face (uniform in [0, max]).
    pub max_stains: u32,
    /// Most dirt specks on a part's end face (uniform in [0, max]).
    pub max_dirt: u32,
    /// Largest change of each light's direction, degrees.
    pub light_jitter_deg: f64,
    /// Largest relative change of each light's intensity.
    pub intensity_jitter: f64,
    /// Camera position jitter, one sigma per axis, m (the calibration does not know it).
    pub pose_jitter_m: f64,
    /// Camera orientation jitter, one sigma per axis, degrees.
    pub pose_jitter_deg: f64,
}

impl Default for SensorSection {
    fn default() -> Self {
        Self {
            noise_sigma: 2.0,
            salt_pepper_fraction: 0.0005,
            illumination_gradient: 0.12,
            vignetting: 0.2,
            max_stains: 2,
            max_dirt: 5,
            light_jitter_deg: 10.0,
            intensity_jitter: 0.15,
            pose_jitter_m: 0.0002,
            pose_jitter_deg: 0.02,
        }
    }
}

impl SensorSection {
    /// No realism at all: a perfect sensor, clean parts, the nominal lights and pose.
    pub fn ideal() -> Self {
        Self {
            noise_sigma: 0.0,
            salt_pepper_fraction: 0.0,
            illumination_gradient: 0.0,
            vignetting: 0.0,
            max_stains: 0,
            max_dirt: 0,
            light_jitter_deg: 0.0,
            intensity_jitter: 0.0,
            pose_jitter_m: 0.0,
            pose_jitter_deg: 0.0,
        }
    }
}
