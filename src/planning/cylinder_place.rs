//! The place of a picked cylinder into a bin, laid down rather than dropped: a steel tube
//! picked lying (fallen over) is lowered lying into its bin's next free slot until its lowest
//! point is just above the floor, and let go there.

use super::pick_planner::PlaceSpot;
use super::{CylinderPick, PickPlanner, PlacePlan, bin_slot};
use crate::cell::BinBody;
use crate::math::pose_to_physics;
use crate::outcome::Failure;

/// How far above the bin's floor the carried body's lowest point is let go, m (the standing
/// part's place lets go 12 mm above it).
const LAY_ABOVE_FLOOR_M: f64 = 0.012;
/// How far above the bin's rim the carried body's lowest point passes before the straight
/// descent, m.
const LAY_APPROACH_ABOVE_RIM_M: f64 = 0.04;

impl PickPlanner {
    /// The place of `picked` into `bin` after `placed_before` parts: carried over the next
    /// free slot (or, when no place there is clear, the floor's centre), lowered until its
    /// lowest point is just above the floor, and let go.
    pub fn plan_cylinder_place(
        &self,
        picked: &CylinderPick,
        bin: &BinBody,
        placed_before: usize,
    ) -> Result<PlacePlan, Failure> {
        // The tool points down at the place: the carried body's lowest point is its largest
        // TCP z.
        let carried = &picked.carried;
        let aabb = carried
            .shape
            .compute_aabb(&pose_to_physics(&carried.tcp_from_shape));
        let below_tcp_m = f64::from(aabb.maxs.z);
        let place_at = |slot: usize| {
            let floor = bin.floor_center + bin_slot(bin, slot);
            let spot = PlaceSpot {
                xy: [floor.x, floor.y],
                above_z: floor.z + bin.wall_height + LAY_APPROACH_ABOVE_RIM_M + below_tcp_m,
                place_z: floor.z + LAY_ABOVE_FLOOR_M + below_tcp_m,
                bin_name: &bin.name,
            };
            self.place_carried(
                carried,
                (picked.grip_m, picked.open_m),
                &spot,
                &picked.pick,
                &picked.payload,
                &picked.checker,
            )
        };
        match place_at(placed_before) {
            Err(_) if placed_before > 0 => place_at(0),
            placed => placed,
        }
    }
}
