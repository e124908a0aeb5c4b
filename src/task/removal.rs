//! Clearing a foreign object off the belt: when the part has no grasp clear of the obstacles
//! and a bottle is what blocks it, the cell picks that bottle by its body with a light grip,
//! drops it into the scenario's waste bin and goes back to look again. A bottle a removal puts
//! into the waste bin counts as removed, not touched; the robot's touch on any other still
//! fails the cycle.

use nalgebra::{Point3, Vector3};
use rapier3d::parry::query;

use super::cell_data::CellData;
use super::let_through::is_refusal;
use super::pick_cycle::{Cycle, OPEN_FORCE_N, RELEASE_MARGIN_S, STOP_SETTLE_S, play_part};
use super::sorter::Sorter;
use crate::cell::CellModel;
use crate::kinematics::JointVector;
use crate::math::pose_to_physics;
use crate::outcome::{Failure, FailureReason, Phase, fail};
use crate::planning::{CylinderPick, GripCylinder, JointTrajectory};
use crate::scenario::BinId;
use crate::sim::JAW_SPEED_M_S;
use crate::station::{PerceivedObstacle, Percept, TargetRule, part_obstacle};

/// Removals one pick cycle may make before the part is let through.
pub(crate) const MAX_REMOVALS_PER_CYCLE: u32 = 3;
/// Squeeze force of each jaw on a bottle, N: a thin plastic body that the tubes' grip (60 N)
/// would crush. Its 30 g weigh 0.3 N, but a lying bottle is held off its middle and swung over
/// the waste bin: the pads must hold its turn about the jaws' axis too. At 8 N the kinematic
/// pads (`sim::jaws`) let 2 bottles of clutter_dense's 100 default and 2602 trials turn out of
/// the jaws in the lift (3 N: 9), at 16 N none.
const BOTTLE_GRIP_FORCE_N: f64 = 16.0;
/// Where along a bottle, as shares of its height from the base, the pads may close: its straight
/// body, between the rounded heel and the shoulder.
const BOTTLE_BODY_SHARE: [f64; 2] = [0.1, 0.7];
/// Time for the grip force to build once the jaws have closed, s.
const GRIP_BUILD_S: f64 = 0.1;
/// Time a dropped bottle gets to come to rest in the waste bin, s.
const DROP_REST_S: f64 = 0.6;
/// Two bottle obstacles overlapping deeper than this are poses of one bottle, m: more than the
/// growth a fitted pose gets on each side.
const SAME_BOTTLE_OVERLAP_M: f64 = 0.012;
/// Largest angle between the axis lines a bottle's pose hypotheses may have for it to be
/// picked, deg: the jaws close square to the best one's, and tolerate this much off square.
const MAX_AXIS_SPREAD_DEG: f64 = 15.0;

/// How far the belt is indexed on between looks for a part that no look found, m: less than
/// the camera's view along the belt, so a part comes into view before it could pass it.
const INDEX_STEP_M: f64 = 0.08;
/// Looks the cell takes, indexing the belt on between them, for a part no look found: enough
/// for a part the width of the bottles' placement (`bottle.distance_range_m` ends at 0.5 m)
/// behind the photo-eye.
const MAX_INDEX_STEPS: usize = 6;
/// A found part further behind the photo-eye than this is brought under it, m.
const CENTRED_M: f64 = 0.01;

/// Whether the jaws closed on the bottle.
enum Grip {
    Held,
    Missed,
}

/// One bottle as perception placed it: its obstacles (the pose hypotheses of one fit), best
/// first, and its gap to the part's side, m.
struct SeenBottle {
    obstacles: Vec<usize>,
    gap_m: f64,
}

impl SeenBottle {
    /// Whether its pose hypotheses agree on how it lies: all standing, or all lying with their
    /// axes within [`MAX_AXIS_SPREAD_DEG`] of the best one's line. A bottle seen from above can
    /// explain its box lying at mirrored yaws, and jaws square to the wrong one land on it.
    fn settled(&self, percept: &Percept) -> bool {
        let axes: Vec<Vector3<f64>> = self
            .obstacles
            .iter()
            .map(|&i| &percept.obstacles[i])
            .filter(|o| o.name == "bottle")
            .map(|o| o.world_from_shape.rotation * Vector3::y())
            .collect();
        let Some(first) = axes.first() else {
            return false;
        };
        let lying = |a: &Vector3<f64>| a.z.abs() < std::f64::consts::FRAC_1_SQRT_2;
        let spread_cos = MAX_AXIS_SPREAD_DEG.to_radians().cos();
        axes.iter()
            .all(|a| lying(a) == lying(first) && (!lying(a) || a.dot(first).abs() >= spread_cos))
    }
}

impl Sorter<'_> {
    /// Whether a refused pick may be answered by clearing a bottle: the scenario has a waste
    /// bin, the refusal came from planning, and the cycle has removals left.
    pub(crate) fn may_remove(model: &CellModel, refusal: &Failure, removals: u32) -> bool {
        model.catalogue().waste_bin().is_some()
            && !model.scenario().is_stream()
            && is_refusal(refusal.reason)
            && removals < MAX_REMOVALS_PER_CYCLE
    }

    /// A single-part trial whose belt a bottle stopped: the photo-eye trips on whatever comes
    /// first, and a bottle ahead of the part can stop the belt with the part still upstream, at
    /// the camera's edge or out of its view. When the look at the station found no part
    /// (`cycle` failed as `not_detected`), the cell indexes the belt on by
    /// [`INDEX_STEP_M`] and looks again, up to [`MAX_INDEX_STEPS`] times; once a look finds a
    /// part, the belt brings it under the station (by the look's place for it) and the cycle
    /// runs again from a fresh look. The oracle (which reads the part wherever it stands) and a
    /// found part keep `cycle`.
    pub(crate) fn index_to_part(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        cycle: Cycle,
    ) -> Cycle {
        let not_seen = cycle
            .failure
            .as_ref()
            .is_some_and(|f| f.reason == FailureReason::NotDetected);
        let Some(camera) = self.camera else {
            return cycle;
        };
        // Not when what breaks the beam is only hidden: indexing would carry it away.
        if !not_seen || self.hidden_at_beam {
            return cycle;
        }
        let eye_x = model.scenario().conveyor.photo_eye_x_m;
        for _ in 0..MAX_INDEX_STEPS {
            data.phase = Phase::Pass;
            if let Err(failure) = data.jog_belt(model, INDEX_STEP_M) {
                return self.unreached(model, data, failure);
            }
            let Ok(sighting) = self.look(model, data, camera, TargetRule::NearestStation) else {
                break;
            };
            let Some(target) = &sighting.target else {
                continue;
            };
            let behind_m = eye_x - target.centre_in_world.x;
            data.phase = Phase::Pass;
            if behind_m > CENTRED_M
                && let Err(failure) = data.jog_belt(model, behind_m)
            {
                return self.unreached(model, data, failure);
            }
            return self.pick_cycle(model, data, None);
        }
        cycle
    }

    /// Finds the bottle that blocks the pick of `percept`'s part and removes it into the waste
    /// bin. `Ok(false)` when no bottle blocks it, or none that blocks can be picked.
    pub(crate) fn remove_blocker(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        percept: &Percept,
    ) -> Result<bool, Failure> {
        let Some(waste) = model.catalogue().waste_bin() else {
            return Ok(false);
        };
        let started = std::time::Instant::now();
        let planned = self.plan_removal(model, data, percept);
        data.timing.planning_ms += started.elapsed().as_secs_f64() * 1e3;
        let Some(picked) = planned else {
            return Ok(false);
        };
        let bin = &data.cell.bins[waste.0];
        let (drop, rests) = self.planner.plan_drop(&picked, bin, &data.waste_contents)?;
        let before: Vec<bool> = (0..data.cell.items.bottles().len())
            .map(|i| in_bin(model, data, i, waste))
            .collect();
        data.removal_touches = Some(vec![None; before.len()]);
        let moved = self.carry_out(model, data, &picked, &drop);
        let touches = data.removal_touches.take().unwrap_or_default();
        let Grip::Held = moved? else {
            // Missed: whatever it touched on the way counts as touched.
            if let Some(phase) = touches.iter().flatten().next() {
                data.touch_phase.get_or_insert(*phase);
            }
            return Ok(false);
        };
        let mut removed_now = 0;
        for (i, was_in) in before.iter().enumerate() {
            if !was_in && in_bin(model, data, i, waste) {
                if data.removed.len() <= i {
                    data.removed.resize(i + 1, false);
                }
                data.removed[i] = true;
                removed_now += 1;
            } else if let Some(phase) = touches.get(i).copied().flatten() {
                data.touch_phase.get_or_insert(phase);
            }
        }
        if removed_now == 0 {
            return fail(
                FailureReason::Dropped,
                "the bottle picked to clear the part did not reach the waste bin",
            );
        }
        data.removals += removed_now;
        data.waste_contents.push(rests);
        Ok(true)
    }

    /// The pick of the bottle whose removal frees the part: the one nearest the part whose
    /// absence alone lets the part be picked, else the nearest that can be picked at all, when
    /// taking every bottle away would free it. `None` when bottles do not block the part.
    fn plan_removal(
        &self,
        model: &CellModel,
        data: &CellData,
        percept: &Percept,
    ) -> Option<CylinderPick> {
        let bottles = seen_bottles(percept);
        let pickable_without = |gone: &dyn Fn(usize) -> bool| {
            let mut rest = percept.clone();
            rest.obstacles = percept
                .obstacles
                .iter()
                .enumerate()
                .filter(|(i, _)| !gone(*i))
                .map(|(_, o)| o.clone())
                .collect();
            let checker = self.planner.checker_for(&rest);
            self.planner.plan_pick(&rest, &checker, &data.q).is_ok()
        };
        if bottles.is_empty()
            || !pickable_without(&|i| bottles.iter().any(|b| b.obstacles.contains(&i)))
        {
            return None;
        }
        let blocker = bottles
            .iter()
            .position(|b| pickable_without(&|i| b.obstacles.contains(&i)));
        // The blocker first, then the others nearest first: one in the arm's way to the
        // blocker comes off before it.
        let mut order: Vec<usize> = blocker.into_iter().collect();
        order.extend((0..bottles.len()).filter(|&k| Some(k) != blocker));
        order
            .into_iter()
            .find_map(|k| self.plan_bottle_pick(model, data, percept, &bottles[k]))
    }

    /// The pick of `bottle` by its best-fitting pose, clear of the part and every other thing
    /// perceived.
    fn plan_bottle_pick(
        &self,
        model: &CellModel,
        data: &CellData,
        percept: &Percept,
        bottle: &SeenBottle,
    ) -> Option<CylinderPick> {
        let scenario = model.scenario();
        let &best = bottle.obstacles.first()?;
        if !bottle.settled(percept) {
            return None;
        }
        let obstacle = percept.obstacles[best].clone();
        let section = &scenario.bottle;
        let axis = obstacle.world_from_shape.rotation * Vector3::y();
        let centre = Point3::from(obstacle.world_from_shape.translation.vector);
        let h = section.height_m;
        let cylinder = GripCylinder {
            centre,
            axis,
            radius_m: section.radius_m,
            length_m: h,
            grip_span_m: BOTTLE_BODY_SHARE.map(|share| share * h - h / 2.0),
            mass_kg: section.mass_kg,
            grip_force_n: BOTTLE_GRIP_FORCE_N,
            obstacle,
        };
        let [x, y] = percept.part_xy;
        let part = part_obstacle(
            &Point3::new(x, y, data.cell.belt_top_z + percept.part_height_m / 2.0),
            percept.part_outer_radius_m,
            percept.part_height_m,
        );
        let others: Vec<PerceivedObstacle> = percept
            .obstacles
            .iter()
            .enumerate()
            .filter(|(i, _)| !bottle.obstacles.contains(i))
            .map(|(_, o)| o.clone())
            .chain([part])
            .collect();
        let q: JointVector = data.q;
        let friction = scenario.gripper.pad_friction;
        self.planner
            .plan_cylinder_pick(&cylinder, &others, &q, friction)
            .ok()
    }

    /// Plays a planned removal: down around the bottle, a light grip, up and over the waste
    /// bin, let go, and home.
    fn carry_out(
        &self,
        model: &CellModel,
        data: &mut CellData,
        picked: &CylinderPick,
        drop: &crate::planning::PlacePlan,
    ) -> Result<Grip, Failure> {
        data.gripper.set(picked.open_m, OPEN_FORCE_N);
        for phase in [Phase::Approach, Phase::Descend] {
            play_part(
                model,
                data,
                phase,
                &picked.pick.approach,
                Phase::Approach,
                None,
            )?;
        }
        data.phase = Phase::Grasp;
        data.gripper.set(0.0, picked.payload.grip_force_n);
        let stroke_s = data.gripper.target_m() / JAW_SPEED_M_S;
        data.settle(model, stroke_s + GRIP_BUILD_S)?;
        let gap = data.cell.arm.finger_positions_m(&data.cell.world);
        if !super::pick_cycle::jaws_hold(
            gap[0] + gap[1],
            picked.grip_m,
            data.cell.arm.closed_gap_m(),
        ) {
            // Nothing between the jaws: the bottle is not where it was fitted. Open, straight
            // up along the lift and home, and leave it.
            data.gripper.set(picked.open_m, OPEN_FORCE_N);
            data.settle(model, picked.open_m / JAW_SPEED_M_S + RELEASE_MARGIN_S)?;
            let speed = self.planner.speed_fraction;
            let arm = &self.planner.model;
            let back = JointTrajectory::join(
                vec![
                    JointTrajectory::along(arm, picked.pick.lift_path.clone(), speed),
                    JointTrajectory::through(
                        arm,
                        &[picked.pick.lift_end, self.planner.home_q_rad],
                        speed,
                    ),
                ],
                true,
            );
            let span = (0.0, back.duration_s());
            data.execute(model, Phase::Retreat, &back, span, 0.0, None)?;
            return Ok(Grip::Missed);
        }
        for phase in [Phase::Lift, Phase::Transport] {
            play_part(model, data, phase, &drop.carry, Phase::Lift, None)?;
        }
        let span = (0.0, drop.lower.duration_s());
        data.execute(model, Phase::Place, &drop.lower, span, STOP_SETTLE_S, None)?;
        data.phase = Phase::Release;
        data.release_jaws(model, picked.open_m)?;
        let span = (0.0, drop.retreat.duration_s());
        data.execute(model, Phase::Retreat, &drop.retreat, span, 0.0, None)?;
        data.settle(model, DROP_REST_S)?;
        Ok(Grip::Held)
    }
}

/// Whether bottle `index` lies in bin `bin` ([`crate::cell::BinBody::holds_axis`]: its lower
/// end inside the bin and its middle over the bin's floor; a bottle stands taller than a bin's
/// walls).
fn in_bin(model: &CellModel, data: &CellData, index: usize, bin: BinId) -> bool {
    let body = data.cell.items.bottles()[index].body;
    data.cell.body_pose(body).is_some_and(|pose| {
        data.cell.bins[bin.0].holds_axis(&pose, model.scenario().bottle.height_m)
    })
}

/// The bottles among `percept`'s obstacles, nearest the part first. A fit may place one bottle
/// in several poses that explain its outline about equally; two bottles cannot pass through
/// each other, so obstacles that overlap deeply are poses of one bottle.
fn seen_bottles(percept: &Percept) -> Vec<SeenBottle> {
    let [px, py] = percept.part_xy;
    let mut bottles: Vec<SeenBottle> = Vec::new();
    for (i, obstacle) in percept.obstacles.iter().enumerate() {
        if obstacle.name != "bottle" {
            continue;
        }
        let gap_m = footprint_gap_m(obstacle, [px, py]) - percept.part_outer_radius_m;
        let same = bottles.iter().position(|b| {
            b.obstacles
                .iter()
                .any(|&j| overlap_m(obstacle, &percept.obstacles[j]) > SAME_BOTTLE_OVERLAP_M)
        });
        match same {
            Some(k) => {
                bottles[k].obstacles.push(i);
                bottles[k].gap_m = bottles[k].gap_m.min(gap_m);
            }
            None => bottles.push(SeenBottle {
                obstacles: vec![i],
                gap_m,
            }),
        }
    }
    // What else was seen where a bottle is (its cap taken for a part's end face, say) is that
    // bottle too.
    for (i, obstacle) in percept.obstacles.iter().enumerate() {
        if obstacle.name == "bottle" {
            continue;
        }
        let inside = bottles.iter_mut().find(|b| {
            b.obstacles
                .iter()
                .any(|&j| overlap_m(obstacle, &percept.obstacles[j]) > SAME_BOTTLE_OVERLAP_M)
        });
        if let Some(bottle) = inside {
            bottle.obstacles.push(i);
        }
    }
    bottles.sort_by(|a, b| a.gap_m.total_cmp(&b.gap_m));
    bottles
}

/// How deep two obstacles' shapes overlap, m (0 when apart or unmeasurable).
fn overlap_m(a: &PerceivedObstacle, b: &PerceivedObstacle) -> f64 {
    let pose = |o: &PerceivedObstacle| pose_to_physics(&o.world_from_shape);
    query::contact(&pose(a), a.shape.as_ref(), &pose(b), b.shape.as_ref(), 0.0)
        .ok()
        .flatten()
        .map_or(0.0, |c| -f64::from(c.dist))
}

/// The distance in the belt's plane from `xy` to the footprint of `obstacle`'s cylinder, m.
fn footprint_gap_m(obstacle: &PerceivedObstacle, xy: [f64; 2]) -> f64 {
    let (half_m, radius_m) = obstacle.shape.as_cylinder().map_or((0.0, 0.0), |c| {
        (f64::from(c.half_height), f64::from(c.radius))
    });
    let centre = obstacle.world_from_shape.translation.vector;
    let axis = obstacle.world_from_shape.rotation * Vector3::y();
    let flat = Vector3::new(axis.x, axis.y, 0.0);
    // The footprint: the axis's shadow on the belt, grown by the radius.
    let reach_m = half_m * flat.norm();
    let dir = flat.try_normalize(1e-9).unwrap_or_else(Vector3::x);
    let to = Vector3::new(xy[0] - centre.x, xy[1] - centre.y, 0.0);
    let along = to.dot(&dir).clamp(-reach_m, reach_m);
    ((to - dir * along).norm() - radius_m).max(0.0)
}
