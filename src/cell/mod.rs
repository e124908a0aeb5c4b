//! The sorting cell built from a scenario through `sim`: arm on a pedestal, conveyor with a
//! photo-eye, bins, the trial's part and bottle.

mod cell_model;
mod layout;
mod placement;
mod sight;

pub use crate::kinematics::gripper_tcp;
pub use crate::sim::{BoreForm, ConveyorHooks, PartInstance, Tag};
pub use cell_model::{CellModel, UrdfSource};
pub use layout::{BinBody, Cell, CellError, SceneryBox};
pub use placement::{CLEARANCE_M, Footprint, PartSpot, PlacementError, place_bottles};
pub use sight::{MIN_EYE_CLEARANCE_M, StationSight};
