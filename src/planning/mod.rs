//! Motion planning: from a percept and the cell's obstacles to collision-checked joint-space
//! trajectories within the arm's limits.

mod collision;
mod cylinder_drop;
mod cylinder_grasp;
mod cylinder_place;
#[cfg(test)]
mod cylinder_grasp_tests;
mod grasp_search;
mod intercept;
mod payload;
mod pick_planner;
#[cfg(test)]
mod pick_planner_tests;
#[cfg(test)]
mod lean_place_tests;
#[cfg(test)]
mod second_look_tests;
mod robot_shapes;
mod straight_line;
mod time_scaling;
mod trajectory;

pub use collision::{
    Carried, Clearance, CollisionChecker, CollisionHit, LinkMount, Obstacle, RobotShape,
};
pub use cylinder_grasp::{CylinderPick, GripCylinder, cylinder_obstacle};
pub use grasp_search::{
    Approach, CLEARANCE_CAP_M, GraspPose, GraspRanking, GraspSearch, ScoredGrasp,
};
pub use intercept::{Intercept, InterceptProblem};
pub use payload::{GRIP_SAFETY_FACTOR, Payload};
pub use pick_planner::{
    GRASP_TCP_ABOVE_BOTTOM_M, PALM_CLEARANCE_M, PART_OBSTACLE, PickPlan, PickPlanner, PlacePlan,
    PlaceSpot, bin_slot, drop_second_looks, scenery_obstacles,
};
pub use robot_shapes::capture_robot_shapes;
pub use straight_line::straight_line;
pub use time_scaling::{ScalingSample, TimeScaling};
pub use trajectory::{JointTrajectory, ToolLimits, TrajectorySample};
