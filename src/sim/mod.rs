//! The physics world: the only stage that mutates simulation state. It owns every body
//! insertion (the arm, the belt's hooks, the parts and bottles and their registry) and the tags
//! that say what each collider is.

mod arm;
mod contacts;
mod conveyor;
mod error;
mod items;
mod jaws;
mod pad_stiction;
mod part;
mod servo;
mod tag;
mod tube_prism;
mod urdf_graph;
mod weld;
mod world;

pub use arm::{ArmGains, ArmLink, FINGER_JOINTS, FINGER_LINKS, JAW_SPEED_M_S, SimArm};
pub use conveyor::{BELT_ACCEL_M_S2, ConveyorHooks};
pub use error::SimError;
pub use items::{BottleItem, BottlePlacement, ItemSet, PartItem, body_pose, set_body_velocity};
pub use jaws::{FINGER_DAMPING_N_S_M, FINGER_STIFFNESS_N_M};
pub use pad_stiction::{CellHooks, PRESLIDE_RATE_HZ, PadStiction};
pub use part::{BoreForm, PartInstance};
pub use tag::{Tag, groups};
pub use world::{CONTACT_MARGIN_M, FREE_SOLVER_ITERATIONS, World, WorldParams};
