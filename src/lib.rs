//! twincell: a physics-simulated digital twin of a robot sorting cell.
//!
//! The modules follow one tick of the cell, and each imports only the ones listed before it
//! (see ARCHITECTURE.md; `tests/architecture.rs` checks it).

pub mod math;
pub mod rng;
pub mod kinematics;
pub mod scenario;
pub mod outcome;
pub mod sim;
pub mod cell;
pub mod camera;
pub mod render;
pub mod detect;
pub mod perception;
pub mod station;
pub mod planning;
pub mod control;
pub mod task;
pub mod batch;
#[cfg(feature = "record")]
pub mod record;
pub mod demo;
pub mod gym;
