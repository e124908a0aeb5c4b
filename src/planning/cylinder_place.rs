//! The place of a picked cylinder into a bin, laid down rather than dropped: a steel tube
//! picked lying (fallen over) is lowered lying into its bin's free slot nearest the edge until
//! its lowest point is just above the floor, and let go there.

use nalgebra::Vector3;

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

/// Placed counts probed for a bin's slots (more than any bin here holds).
const SLOTS_PROBED: usize = 64;

impl PickPlanner {
    /// The place of `picked` into `bin` after `placed_before` parts: carried over the free
    /// slot farthest from the bin's centre that it fits (standing parts fill the slots nearest
    /// the centre first, and a lying tube reaches into the slots beside its own), lowered until
    /// its lowest point is just above the floor, and let go.
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
        let place_at = |offset: Vector3<f64>| {
            let floor = bin.floor_center + offset;
            let spot = PlaceSpot {
                xy: [floor.x, floor.y],
                above_z: floor.z + bin.wall_height + LAY_APPROACH_ABOVE_RIM_M + below_tcp_m,
                place_z: floor.z + LAY_ABOVE_FLOOR_M + below_tcp_m,
                bin_name: &bin.name,
                clear_of: &[],
                yaws_deg: None,
                tilt_rad: 0.0,
            };
            self.place_carried(
                carried,
                (picked.grip_m, picked.open_m),
                &spot,
                &picked.pick,
                &picked.payload.tool_limits(),
                &picked.checker,
            )
        };
        // The bin's slots in the order it fills them; the first `placed_before` are taken.
        let mut slots: Vec<Vector3<f64>> = Vec::new();
        for placed in 0..SLOTS_PROBED {
            let slot = bin_slot(bin, placed);
            if !slots.iter().any(|s| (s - slot).norm() < 1e-9) {
                slots.push(slot);
            }
        }
        let taken = placed_before.min(slots.len().saturating_sub(1));
        let mut free = slots.split_off(taken);
        // Farthest first; among equals, the order the bin fills them in.
        free.sort_by(|a, b| b.norm().total_cmp(&a.norm()));
        let mut last = None;
        for slot in free {
            match place_at(slot) {
                Ok(plan) => return Ok(plan),
                Err(failure) => last = Some(failure),
            }
        }
        match last {
            Some(failure) => Err(failure),
            None => place_at(Vector3::zeros()),
        }
    }
}
