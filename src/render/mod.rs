//! The cell's camera: a headless wgpu renderer of the simulated cell, calibrated by construction.
//!
//! - [`scene`]: the cell's bodies as meshes ([`mesh`]) with materials ([`material`]) and poses,
//!   read from a built [`crate::cell::Cell`] without changing it; the part's bore is its true,
//!   non-round form.
//! - [`renderer`]: a wgpu device (a GPU when there is one, else the software adapter: Mesa
//!   llvmpipe through GL/EGL, or lavapipe through Vulkan), 4x MSAA (optionally supersampled),
//!   an offscreen target read back into an [`image::RgbImage`]; no window, no surface. Its
//!   projection is built from a [`crate::camera::CameraCalibration`], so the
//!   renderer and perception share one camera model.
//! - [`sensor`]: seeded sensor effects after the render (gradient, vignetting, noise,
//!   salt-and-pepper), with the model's plain definition beside it as the reference its tests
//!   compare against; [`shot`]: a staged pick-station shot with drawn realism and ground truth;
//!   [`window`]: an area of interest of a shot read out at the sensor's full pitch;
//!   [`binned`]: the detector's frame drawn binned on the sensor, at the detector's own
//!   resolution;
//!   [`dataset`]: an Ultralytics/YOLO dataset of such shots, or of [`family`] shots drawn over
//!   the whole tube family and camera envelope.

pub mod binned;
mod cull;
pub mod dataset;
pub mod error;
mod exposure;
pub mod family;
pub mod family_occlusion;
mod gpu_scene;
pub mod material;
pub mod mesh;
pub mod motion_blur;
mod pipeline;
pub mod renderer;
pub mod scene;
pub mod sensor;
mod sensor_binned;
mod sensor_noise;
mod sensor_reference;
pub mod shot;
mod targets;
pub mod window;

pub use binned::reader_bin;
pub use error::RenderError;
pub use motion_blur::MotionBlur;
pub use renderer::{Exposure, GpuScene, Light, Renderer, RendererOptions, StainBlob};
pub use scene::{ObjectKind, Scene, SceneObject};
pub use shot::{BoreTruth, CameraRig, ObjectTruth, Shot, ShotError};
pub use window::SensorWindow;
