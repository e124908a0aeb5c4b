//! The physics world: the only stage that mutates simulation state.

mod arm;
mod error;
mod world;

pub use arm::{ArmGains, SimArm};
pub use error::SimError;
pub use world::{World, WorldParams};
