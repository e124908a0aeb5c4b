//! The sorting cell: arm on a pedestal, conveyor with a photo-eye, bins, the part and the bottle,
//! built into one physics world from a scenario, and the task controller that runs a trial.

pub mod bottle_fit;
pub mod camera_perception;
mod conveyor;
mod layout;
mod observer;
mod part;
mod trial;

use nalgebra::Isometry3;

pub use camera_perception::CameraPerception;
pub use conveyor::ConveyorHooks;
pub use layout::{BinBody, Cell, CellError, Tag};
pub use observer::{
    BoreView, CellView, DetectionView, PerceptionFrame, SAMPLE_RATE_HZ, TrialObserver,
    TrialObserverFactory,
};
pub use part::{BoreForm, PartInstance};
pub use trial::CellTrialRunner;

/// The tool centre point of the project's gripper in the flange frame: midway between the pads.
pub fn gripper_tcp() -> Isometry3<f64> {
    Isometry3::translation(0.0, 0.0, 0.125)
}
