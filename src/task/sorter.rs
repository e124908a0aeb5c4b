//! The built-in controller's own state through a trial: its camera, its planner, the part it is
//! handling and what it has decided. The stages it runs are functions of this, the
//! [`CellModel`] and the trial's [`CellData`].

use super::cell_data::CellData;
use super::tracking::BeltTracking;
use crate::cell::CellModel;
use crate::outcome::Misidentification;
use crate::planning::PickPlanner;
use crate::station::{CameraPerception, TrackId};

/// The controller of one trial.
pub(crate) struct Sorter<'a> {
    /// The camera pipeline; `None` reads the truth from the world (the oracle).
    pub(crate) camera: Option<&'a CameraPerception>,
    pub(crate) planner: PickPlanner,
    /// The part being handled, by its index in the cell's registry.
    pub(crate) current: usize,
    /// Grip force per jaw for the detected part type, N.
    pub(crate) grip_recipe_n: f64,
    /// When the belt last stopped for a pick, s.
    pub(crate) pick_time_s: Option<f64>,
    /// The item at the photo-eye the camera took for something else, when it did.
    pub(crate) misidentified: Option<Misidentification>,
    /// A stream's items tracked along the belt (`None` in a single-part trial).
    pub(crate) tracking: Option<BeltTracking>,
    /// The track of the item at the photo-eye, once identified.
    pub(crate) station_track: Option<TrackId>,
    /// Whether the last look saw no part and only bottles clear of the photo-eye's beam: what
    /// breaks the beam is hidden from the camera, not still upstream.
    pub(crate) hidden_at_beam: bool,
}

/// The planner's view of the cell as reset: the robot's collision shapes at home and the fixed
/// scenery as obstacles. Nothing in it depends on the trial's draw, so a runner captures it
/// once and every trial shares it.
pub(crate) fn planner_for(model: &CellModel, data: &CellData) -> PickPlanner {
    PickPlanner::for_cell(model, &data.cell)
}

impl<'a> Sorter<'a> {
    /// The controller of a trial of `model`, planning with `planner`.
    pub(crate) fn new(
        model: &CellModel,
        planner: PickPlanner,
        camera: Option<&'a CameraPerception>,
    ) -> Self {
        Self {
            camera,
            planner,
            current: 0,
            grip_recipe_n: model.scenario().gripper.grip_force_n,
            pick_time_s: None,
            misidentified: None,
            tracking: None,
            station_track: None,
            hidden_at_beam: false,
        }
    }
}
