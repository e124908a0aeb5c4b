//! twincell: a physics-simulated digital twin of a robot sorting cell.

pub mod batch;
pub mod cell;
pub mod control;
pub mod demo;
pub mod detect;
pub mod kinematics;
pub mod math;
pub mod perception;
pub mod planning;
#[cfg(feature = "record")]
pub mod record;
pub mod render;
pub mod rng;
pub mod scenario;
pub mod sim;
