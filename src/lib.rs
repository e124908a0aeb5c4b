//! twincell: a physics-simulated digital twin of a robot sorting cell.
//!
//! The modules follow one tick of the cell, and each imports only the ones listed before it
//! (see ARCHITECTURE.md; `tests/architecture.rs` checks it).

pub mod batch;
pub mod camera;
pub mod cell;
pub mod control;
pub mod demo;
pub mod detect;
pub mod kinematics;
pub mod math;
pub mod outcome;
pub mod perception;
pub mod planning;
#[cfg(feature = "record")]
pub mod record;
pub mod render;
pub mod rng;
pub mod scenario;
pub mod sim;
pub mod task;
