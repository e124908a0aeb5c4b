//! The physics world: the only stage that mutates simulation state.

mod arm;
mod error;
mod world;

pub use arm::{ARM_JOINTS, ArmGains, JAW_SPEED_M_S, SimArm};
pub use error::SimError;
pub use world::{World, WorldParams};
