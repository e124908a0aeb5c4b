//! The pick of a part that fell over: a tube seen lying on the belt after a drop is gripped by
//! its body across the diameter, square to its axis (`planning::cylinder_grasp`, with the part
//! type's radius, length, mass and grip force), carried to the bin the cell had decided while
//! the part stood, and laid down there. It is held by the pads' squeeze and friction only, watched
//! as any carried part is; the cycle is judged as a pick cycle is, against the truth.

use std::time::Instant;

use nalgebra::{Point3, Vector3};

use super::cell_data::CellData;
use super::judge;
use super::motion_stages::Held;
use super::pick_cycle::{Cycle, OPEN_FORCE_N, STOP_SETTLE_S, grasp, play_part};
use super::sorter::Sorter;
use crate::cell::CellModel;
use crate::control::HoldMonitor;
use crate::outcome::{Failure, FailureReason, Phase, fail};
use crate::planning::{CylinderPick, GripCylinder, PlacePlan, cylinder_obstacle};
use crate::scenario::{BinId, PartTypeId};
use crate::station::{
    LyingPart, NEIGHBOURHOOD_M, PerceivedObstacle, Sighting, bottle_obstacle, part_obstacle,
};

/// How much a fitted pose's shape is grown on each side for its uncertainty, m (as a bottle
/// seen by the camera is).
const FIT_GROWTH_M: f64 = 0.004;

impl Sorter<'_> {
    /// Picks the lying part `lying` (seen with `obstacles` around it) and lays it in the bin
    /// the cell decided for it before it fell, as `before` (the cycle the drop ended) records;
    /// then judges the cycle against the truth.
    pub(crate) fn repick_lying(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        lying: &LyingPart,
        obstacles: &[PerceivedObstacle],
        before: Cycle,
    ) -> Cycle {
        let (scenario, catalogue) = (model.scenario(), model.catalogue());
        data.touch_phase = None;
        data.faults.cycles += 1;
        let decision = before.decision.as_ref();
        // The type measured while the part stood; else the size the lying fit matched.
        let part_type = decision
            .and_then(|d| {
                catalogue
                    .parts()
                    .find(|(_, kind)| kind.name == d.detected_type)
            })
            .map_or(PartTypeId(lying.size_index), |(id, _)| id);
        let bin = decision.and_then(|d| {
            (0..data.cell.bins.len())
                .map(BinId)
                .find(|&b| catalogue.bin_name(b) == d.bin)
        });
        let result = match bin {
            Some(bin) => self.lay_in_bin(model, data, lying, part_type, obstacles, bin),
            None => fail(
                FailureReason::WrongBin,
                "no bin was decided for the part before it fell",
            ),
        };
        let evidence = data.cycle_evidence(self.current);
        let placed_bin_id = evidence.placed_bin;
        let failure = judge::judge_cycle(scenario, catalogue, &before.part, result, &evidence);
        Cycle {
            touched: before.touched || evidence.bottle_disturbed(scenario),
            picked: before.picked || evidence.bottle_lifted,
            displacement_m: before.displacement_m.max(evidence.bottle_displacement_m),
            part: before.part,
            decision: before.decision,
            placed_bin: placed_bin_id.map(|b| catalogue.bin_name(b).to_owned()),
            placed_bin_id,
            failure,
            cycle_time_s: self
                .pick_time_s
                .map_or(0.0, |t| data.cell.world.time_s() - t),
            grasp: before.grasp,
            passed: None,
        }
    }

    /// Plans the lying part's pick and its place into `bin`, then plays them: down around its
    /// body, the grip (a fault planned for this grasp strikes it as any), up and over, down into
    /// the bin, let go and home.
    fn lay_in_bin(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        lying: &LyingPart,
        part_type: PartTypeId,
        obstacles: &[PerceivedObstacle],
        bin: BinId,
    ) -> Result<(), Failure> {
        let scenario = model.scenario();
        let kind = model.catalogue().part(part_type);
        let radius_m = kind.outer_radius_m();
        data.phase = Phase::Plan;
        let started = Instant::now();
        let planned = self.plan_lying(model, data, lying, part_type, obstacles, bin);
        data.timing.planning_ms += started.elapsed().as_secs_f64() * 1e3;
        let (picked, place) = planned?;
        // Kept for checking the motions again after a further fault, and for a set-down.
        data.faults.checker = Some(picked.checker.clone());
        data.faults.carried = Some(picked.carried.clone());
        data.faults.pregrasp_q = Some(picked.pick.pregrasp);
        data.faults.open_m = picked.open_m;
        data.gripper.set(picked.open_m, OPEN_FORCE_N);
        let approach = &picked.pick.approach;
        for phase in [Phase::Approach, Phase::Descend] {
            data.phase = phase;
            play_part(model, data, phase, approach, Phase::Approach, None)?;
        }
        data.phase = Phase::Grasp;
        // The pads close across the diameter, each at the body's radius from its axis.
        grasp(model, data, kind.grip_force_n, radius_m)?;
        let monitor = HoldMonitor {
            tcp_from_part: data.tcp_from_part(model.arm_model(), self.current)?,
            slip_tolerance_m: scenario.task.slip_tolerance_m,
        };
        let held = Some(Held {
            part: self.current,
            monitor: &monitor,
        });
        for phase in [Phase::Lift, Phase::Transport] {
            data.phase = phase;
            play_part(model, data, phase, &place.carry, Phase::Lift, held)?;
        }
        data.phase = Phase::Place;
        let span = (0.0, place.lower.duration_s());
        data.execute(model, Phase::Place, &place.lower, span, STOP_SETTLE_S, held)?;
        data.phase = Phase::Release;
        data.release_jaws(model, picked.open_m)?;
        data.phase = Phase::Retreat;
        let span = (0.0, place.retreat.duration_s());
        data.execute(model, Phase::Retreat, &place.retreat, span, 0.0, None)?;
        Ok(())
    }

    /// The lying part's pick, and its place into `bin`, at its edge.
    fn plan_lying(
        &self,
        model: &CellModel,
        data: &CellData,
        lying: &LyingPart,
        part_type: PartTypeId,
        obstacles: &[PerceivedObstacle],
        bin: BinId,
    ) -> Result<(CylinderPick, PlacePlan), Failure> {
        let kind = model.catalogue().part(part_type);
        let (radius_m, length_m) = (kind.outer_radius_m(), kind.height_m);
        let axis = Vector3::new(lying.yaw_rad.cos(), lying.yaw_rad.sin(), 0.0);
        let c = lying.centre_in_world;
        // Lying on the belt: its axis one radius above the belt's top.
        let centre = Point3::new(c.x, c.y, data.cell.belt_top_z + radius_m);
        let obstacle = cylinder_obstacle(
            "lying part",
            &centre,
            &axis,
            radius_m + FIT_GROWTH_M,
            length_m + 2.0 * FIT_GROWTH_M,
        );
        let half_m = length_m / 2.0;
        let cylinder = GripCylinder {
            centre,
            axis,
            radius_m,
            length_m,
            // A plain tube: the pads may close anywhere along it.
            grip_span_m: [-half_m, half_m],
            mass_kg: kind.mass_kg(),
            grip_force_n: kind.grip_force_n,
            obstacle,
        };
        let friction = model.scenario().gripper.pad_friction;
        let picked = self
            .planner
            .plan_cylinder_pick(&cylinder, obstacles, &data.q, friction)?;
        let bin_body = &data.cell.bins[bin.0];
        let place = self
            .planner
            .plan_cylinder_place(&picked, bin_body, data.bin_fill[bin.0])?;
        Ok((picked, place))
    }
}

/// What the camera's `sighting` shows around the lying part `lying` that its pick must clear:
/// the bottles and the standing parts near it. A shape fitted where the lying tube itself lies
/// is a misreading of that tube (two bodies cannot overlap), and is left out.
pub(super) fn seen_around(
    model: &CellModel,
    data: &CellData,
    sighting: &Sighting,
    lying: &LyingPart,
) -> Vec<PerceivedObstacle> {
    let catalogue = model.catalogue();
    let centre = lying.centre_in_world;
    let near = |x: f64, y: f64| (x - centre.x).hypot(y - centre.y) < NEIGHBOURHOOD_M;
    let on_tube = |x: f64, y: f64| on_footprint(lying, x, y);
    let mut obstacles = Vec::new();
    for bottle in &sighting.bottles {
        for pose in &bottle.poses {
            let t = pose.world_from_bottle.translation.vector;
            if near(t.x, t.y) && !on_tube(t.x, t.y) {
                obstacles.push(bottle_obstacle(
                    &model.scenario().bottle,
                    &pose.world_from_bottle,
                    pose.lying,
                    FIT_GROWTH_M,
                ));
            }
        }
    }
    for other in sighting.other_parts.iter().chain(&sighting.target) {
        let p = other.centre_in_world;
        if near(p.x, p.y) && !on_tube(p.x, p.y) {
            let kind = catalogue.part(PartTypeId(other.type_index));
            obstacles.push(part_obstacle(
                &Point3::new(p.x, p.y, data.cell.belt_top_z + kind.height_m / 2.0),
                kind.outer_radius_m(),
                kind.height_m,
            ));
        }
    }
    obstacles
}

/// Whether the belt point (`x`, `y`) lies within `lying`'s footprint grown by its radius: a
/// shape fitted there overlaps the lying tube, and so is that tube (or the tube is it).
pub(super) fn on_footprint(lying: &LyingPart, x: f64, y: f64) -> bool {
    let c = lying.centre_in_world;
    let axis = Vector3::new(lying.yaw_rad.cos(), lying.yaw_rad.sin(), 0.0);
    let to = Vector3::new(x - c.x, y - c.y, 0.0);
    let along = to.dot(&axis);
    along.abs() <= lying.length_m / 2.0 + lying.diameter_m / 2.0
        && (to - axis * along).norm() <= lying.diameter_m
}
