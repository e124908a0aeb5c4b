//! The built-in controller's own state through a trial: its camera, its planner, the part it is
//! handling and what it has decided. The stages it runs are functions of this, the
//! [`CellModel`] and the trial's [`CellData`].

use super::cell_data::CellData;
use crate::cell::CellModel;
use crate::outcome::Misidentification;
use crate::planning::{PickPlanner, capture_robot_shapes, scenery_obstacles};
use crate::station::CameraPerception;

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
}

impl<'a> Sorter<'a> {
    /// The controller for the trial in `data`, as reset.
    pub(crate) fn new(
        model: &CellModel,
        data: &CellData,
        camera: Option<&'a CameraPerception>,
    ) -> Self {
        let scenario = model.scenario();
        let cell = &data.cell;
        let arm = model.arm_model().clone();
        let home = scenario.robot.home_q_rad;
        let world_from_base = *cell.arm.world_from_base();
        let planner = PickPlanner {
            robot_shapes: capture_robot_shapes(&cell.world, &cell.arm, &arm, &home),
            model: arm,
            ik: model.ik().clone(),
            world_from_base,
            finger_reference_m: cell.finger_reference_m,
            obstacles: scenery_obstacles(&cell.scenery, &world_from_base.inverse()),
            belt_top_z: cell.belt_top_z,
            open_clearance_m: scenario.gripper.open_clearance_m,
            speed_fraction: scenario.robot.speed_fraction,
            carry_speed_fraction: scenario.robot.carry_speed_fraction,
            home_q_rad: home,
        };
        Self {
            camera,
            planner,
            current: 0,
            grip_recipe_n: scenario.gripper.grip_force_n,
            pick_time_s: None,
            misidentified: None,
        }
    }
}
