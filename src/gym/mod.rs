//! The cell as a step-by-step environment for controllers outside the twin (the Python
//! package's Gymnasium environment wraps it): one episode is one single-part trial, reset from
//! the scenario seed and the trial's index as `twincell run` resets it; a step applies an
//! [`Action`] for one control period of [`PHYSICS_STEPS_PER_CONTROL`] physics steps and returns
//! an [`Observation`]; at the episode's end the twin's judge gives the trial's record.
//!
//! The controller sees what the cell's sensors give (joints, jaws, photo-eye, belt encoder, the
//! camera's frame when it asks for one, with the calibration); the truth only in oracle mode,
//! and in the record once the trial is over.

mod action;
mod batch_files;
mod cell_env;
mod episode_end;
mod observation;

pub use action::{Action, ActionError, ArmTarget, MAX_JAW_FORCE_N, MAX_JAW_WIDTH_M};
pub use batch_files::{BatchFilesError, write_batch};
pub use cell_env::{CellEnv, EnvError, PHYSICS_STEPS_PER_CONTROL, StepResult};
pub use observation::{Observation, Truth};
