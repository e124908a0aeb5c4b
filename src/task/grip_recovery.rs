//! The controller's answer to a weakened or lost grip, from the gripper's own sensors (the
//! force the jaws report, their opening), never from the truth: a grip found weak at the grasp
//! is taken again where the part stands; one that weakens on the way up or over is carried
//! back slowly over the belt and set down where it was grasped; then the arm goes home, looks
//! again and picks the part again.

use nalgebra::{Isometry3, Point3, Translation3, Vector3};

use super::cell_data::CellData;
use super::let_through::is_refusal;
use super::lying_repick::{on_footprint, seen_around};
use super::perceive::perceive_oracle;
use super::pick_cycle::{Cycle, GRIP_BUILD_S, OPEN_FORCE_N};
use super::sorter::Sorter;
use crate::cell::CellModel;
use crate::control::{GripReading, GripWatch, HoldMonitor};
use crate::kinematics::{IkSolver, tcp_pose};
use crate::outcome::{
    Failure, FailureReason, FaultAction, FaultKind, LyingPartRecord, Phase, fail,
};
use crate::planning::{JointTrajectory, PART_OBSTACLE, straight_line};
use crate::scenario::PartTypeId;
use crate::sim::JAW_SPEED_M_S;
use crate::station::{LyingPart, LyingPartFinder, PerceivedObstacle, TargetRule, TubeSize};

/// Rest after a dropped part, before the controller looks for it, s.
const DROP_SETTLE_S: f64 = 0.5;
/// How far the jaws rise straight up after a drop before the arm heads home, m.
const DROP_RAISE_M: f64 = 0.1;
/// The share of the carry's speed at which a weakly held part is brought back and set down.
const SET_DOWN_SPEED_SHARE: f64 = 0.5;
/// A TCP this close to the column above its grasp goes straight down to it, m.
const COLUMN_M: f64 = 0.005;
/// How far from the pick station along the belt a part that fell is looked for, m.
const LYING_SEARCH_M: f64 = 0.3;
/// Step of the straight lines the jaws follow, m.
const LINE_STEP_M: f64 = 0.01;
/// A bottle seen now within this of where one was seen before the drop is that bottle, m.
const BOTTLE_STILL_M: f64 = 0.03;
/// Picks of a dropped part before it is given up (counted lost): the first pick again, and
/// one more after a second fall.
const MAX_PICKS_AFTER_DROP: u32 = 2;

impl CellData {
    /// The gripper's sensors now, read into `watch`: the pads' offsets, the force each jaw
    /// reports and the force commanded.
    fn read_grip(&self, watch: &mut GripWatch) -> GripReading {
        let pads = self.cell.arm.finger_positions_m(&self.cell.world);
        let force = self.view().jaw_grip_force_n();
        watch.read(pads, force, self.gripper.force_n())
    }

    /// After the jaws closed (the grasp's hook): when the scenario injects grip faults, the
    /// watch is armed, and a force already fallen is met by opening and closing the jaws
    /// again where the part stands, which gives the drive its force back.
    pub(crate) fn regrip_if_weak(
        &mut self,
        model: &CellModel,
        grip_force_n: f64,
    ) -> Result<(), Failure> {
        if model.scenario().faults.gripper.is_none() {
            return Ok(());
        }
        self.faults.grasp_q = Some(self.q);
        let mut watch = GripWatch::new(2.0 * self.faults.held_radius_m);
        let mut reading = self.read_grip(&mut watch);
        while watch.doubting() {
            self.step(model)?;
            reading = self.read_grip(&mut watch);
        }
        self.faults.grip_watch = Some(watch);
        let GripReading::Weak { force_n } = reading else {
            return Ok(());
        };
        let at_s = self.cell.world.time_s();
        self.release_jaws(model, self.faults.open_m)?;
        self.gripper.set(0.0, grip_force_n);
        let stroke_s = self.gripper.target_m() / JAW_SPEED_M_S;
        self.settle(model, stroke_s + GRIP_BUILD_S)?;
        self.faults.regripped = Some((at_s, force_n));
        self.faults.grip_watch = Some(GripWatch::new(2.0 * self.faults.held_radius_m));
        Ok(())
    }

    /// Watches the held part through the controller's own sensors: jaws closed past the part
    /// show it gone; a force fallen below the command on the way up or over ends the motion so
    /// that the part is set down (over its bin, the place goes on). The judge's monitor of the
    /// part's drift ends the trial on a slip unless an injected fault weakened the grip, when
    /// where the part comes to rest decides.
    pub(crate) fn watch_grip(
        &mut self,
        model: &CellModel,
        phase: Phase,
        hold: &HoldMonitor,
        tcp_from_part: &Isometry3<f64>,
    ) -> Result<(), Failure> {
        if model.scenario().faults.gripper.is_some() {
            let width_m = 2.0 * self.faults.held_radius_m;
            let mut watch = self
                .faults
                .grip_watch
                .take()
                .unwrap_or_else(|| GripWatch::new(width_m));
            let reading = self.read_grip(&mut watch);
            self.faults.grip_watch = Some(watch);
            let now = self.cell.world.time_s();
            match reading {
                GripReading::Empty => {
                    self.faults.drop_seen = Some((now, phase));
                    return fail(
                        FailureReason::Dropped,
                        format!("the jaws closed on nothing during {phase}: the part fell"),
                    );
                }
                GripReading::Weak { force_n } if phase != Phase::Place => {
                    self.faults.drop_seen = Some((now, phase));
                    self.faults.weak_grip_n = Some(force_n);
                    return fail(
                        FailureReason::Dropped,
                        format!(
                            "the jaws' force fell to {force_n:.1} N of the {:.0} N commanded \
                             during {phase}",
                            self.gripper.force_n()
                        ),
                    );
                }
                GripReading::Weak { force_n } => {
                    self.faults.weak_in_place.get_or_insert((now, force_n));
                }
                GripReading::Holding => {}
            }
            if self.gripper.fault_struck() {
                return Ok(());
            }
        }
        hold.check(phase, tcp_from_part)
    }
}

impl Sorter<'_> {
    /// The recovery of the part being handled from a grip the jaws showed weak or empty
    /// (`cycle` ended there): a weakly held part is set down where it was grasped; then the arm
    /// goes home, looks again, and picks the part again when it is seen at the station,
    /// standing or lying. A part that falls again is answered again, up to
    /// [`MAX_PICKS_AFTER_DROP`] picks; one not seen, or not to be picked, is counted lost.
    pub(crate) fn recover_grip(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        mut cycle: Cycle,
    ) -> Cycle {
        let Some((seen_at_s, mut phase)) = data.faults.drop_seen.take() else {
            return cycle;
        };
        let mut actions = Vec::new();
        let mut detail = String::new();
        let mut lying = None;
        let mut picks = 0;
        loop {
            let looked = self.answer_drop(model, data, phase, &mut actions, &mut detail);
            let again = picks < MAX_PICKS_AFTER_DROP;
            match looked {
                Ok(AtStation::Standing) if again => {
                    actions.extend([FaultAction::FoundOnBelt, FaultAction::Repicked]);
                    cycle = self.pick_cycle(model, data, None);
                    if refused_again(model, data, self.current, &mut cycle, &mut actions) {
                        break;
                    }
                }
                Ok(AtStation::Lying(part, around)) if again => {
                    actions.extend([FaultAction::SawLyingPart, FaultAction::RepickedLying]);
                    lying = Some(lying_record(model, &part));
                    cycle = self.repick_lying(model, data, &part, &around, cycle);
                    if refused_again(model, data, self.current, &mut cycle, &mut actions) {
                        break;
                    }
                }
                Ok(seen) => {
                    if let AtStation::Lying(part, _) = seen {
                        actions.push(FaultAction::SawLyingPart);
                        lying = Some(lying_record(model, &part));
                    }
                    actions.push(FaultAction::CountedLost);
                    let rest = data.part_resting_place(model, self.current);
                    let why = if again {
                        "not seen at the pick station again"
                    } else {
                        "fell again after its picks"
                    };
                    if let Some(failure) = cycle.failure.as_mut() {
                        failure
                            .detail
                            .push_str(&format!("; {why}: counted lost (truth: {rest})"));
                    }
                    break;
                }
                Err(failure) => {
                    actions.push(FaultAction::CountedLost);
                    cycle.failure = Some(failure);
                    break;
                }
            }
            picks += 1;
            match data.faults.drop_seen.take() {
                Some((_, fell_in)) => phase = fell_in,
                None => break,
            }
        }
        let sorted = cycle.failure.is_none();
        data.faults
            .record(FaultKind::Gripper, seen_at_s, detail, actions, sorted);
        if let Some(record) = data.faults.records.last_mut() {
            record.saw_lying_part = lying;
        }
        cycle
    }

    /// The answer to one drop or weak grip the jaws showed during `phase`: a weakly held part
    /// is set down where it was grasped; then the arm goes home and looks at the station.
    /// `actions` and `detail` are the fault record's, added to.
    fn answer_drop(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        phase: Phase,
        actions: &mut Vec<FaultAction>,
        detail: &mut String,
    ) -> Result<AtStation, Failure> {
        let again = !detail.is_empty();
        let mut said = format!("the grip weakened and the part fell during {phase}");
        let mut set_down = Ok(true);
        if let Some(force_n) = data.faults.weak_grip_n.take() {
            actions.push(FaultAction::SawWeakGrip);
            said = format!(
                "the grip weakened to {force_n:.1} N during {phase}; the part was set down"
            );
            set_down = self.set_down(model, data);
            match &set_down {
                Ok(true) => actions.push(FaultAction::SetDown),
                Ok(false) => {
                    actions.push(FaultAction::SawDrop);
                    said = format!(
                        "the grip weakened to {force_n:.1} N during {phase}; the part fell \
                         while it was brought back"
                    );
                }
                Err(_) => {}
            }
        } else {
            actions.push(FaultAction::SawDrop);
            if again {
                said = format!("the part fell again during {phase}");
            }
        }
        if again {
            detail.push_str("; then ");
        }
        detail.push_str(&said);
        set_down.and_then(|_| self.look_again_after_drop(model, data))
    }

    /// Brings a weakly held part back over where it was grasped, slowly, and lowers it there
    /// onto the belt; then opens the jaws. `Ok(false)` when the jaws show the part lost on the
    /// way.
    fn set_down(&mut self, model: &CellModel, data: &mut CellData) -> Result<bool, Failure> {
        let Some(q_grasp) = data.faults.grasp_q else {
            return fail(FailureReason::Panic, "a grip watched without a grasp");
        };
        let arm = &self.planner.model;
        let speed = self.planner.carry_speed_fraction * SET_DOWN_SPEED_SHARE;
        let q_now = data.cell.arm.joint_positions(&data.cell.world);
        let base_from_now = tcp_pose(arm, &q_now);
        let base_from_grasp = tcp_pose(arm, &q_grasp);
        let offset = base_from_now.translation.vector - base_from_grasp.translation.vector;
        let mut parts = Vec::new();
        let (mut q_from, mut base_from_start) = (q_now, base_from_now);
        if offset.xy().norm() > COLUMN_M {
            // Back over the grasp at the height the part is carried now.
            let lift = Vector3::new(0.0, 0.0, offset.z.max(0.0));
            let above = Translation3::from(lift) * base_from_grasp;
            let Some(q_above) = self
                .planner
                .ik
                .solve(&above)
                .by_distance_from(&q_grasp)
                .first()
                .copied()
            else {
                return fail(
                    FailureReason::Unreachable,
                    "no IK solution above the grasp to set the part down",
                );
            };
            parts.push(JointTrajectory::through(arm, &[q_now, q_above], speed));
            (q_from, base_from_start) = (q_above, above);
        }
        let Some(down) = straight_line(
            &self.planner.ik,
            &base_from_start,
            &base_from_grasp,
            &q_from,
            LINE_STEP_M,
        ) else {
            return fail(
                FailureReason::Unreachable,
                "no straight line down to where the part was grasped",
            );
        };
        let back_s = parts.iter().map(JointTrajectory::duration_s).sum::<f64>();
        parts.push(JointTrajectory::along(arm, down, speed));
        let path = JointTrajectory::join(parts, false);
        let grip = data.faults.held_radius_m;
        if let Some(checker) = &data.faults.checker {
            // The part goes back the way it came: over the belt it is carried, and in the last
            // straight line down it meets the belt it stood on.
            let ignore = [PART_OBSTACLE];
            let carried = data.faults.carried.as_ref();
            let back = (back_s > 0.0)
                .then(|| checker.check_span(&path, (0.0, back_s), grip, carried, &ignore))
                .flatten();
            let hit = back.or_else(|| {
                checker.check_span(&path, (back_s, path.duration_s()), grip, None, &ignore)
            });
            if let Some(hit) = hit {
                return fail(
                    FailureReason::Collision,
                    format!(
                        "setting the weakly held part down would bring {} onto {}",
                        hit.link, hit.obstacle
                    ),
                );
            }
        }
        let span = (0.0, path.duration_s());
        data.execute(model, Phase::Transport, &path, span, 0.0, None)?;
        let mut watch = GripWatch::new(2.0 * grip);
        let held = data.read_grip(&mut watch) != GripReading::Empty;
        data.phase = Phase::Release;
        data.release_jaws(model, data.faults.open_m)?;
        Ok(held)
    }

    /// After a drop the jaws showed: the arm goes home with its jaws open, out of the
    /// camera's view, and the part is looked for again.
    fn look_again_after_drop(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
    ) -> Result<AtStation, Failure> {
        let scenario = model.scenario();
        let home = scenario.robot.home_q_rad;
        // From the pose commanded last: where the jaws stand at the grasp, the part's push
        // on them may hold the arm a hair off it.
        let q_now = data.q;
        data.gripper.set(data.faults.open_m, OPEN_FORCE_N);
        let speed = scenario.robot.speed_fraction;
        // Straight up first, clear of what stands on the belt, then over home.
        let arm = &self.planner.model;
        let base_from_tcp = tcp_pose(arm, &q_now);
        // Where the part was set down, the jaws leave the way they came: up to above the
        // grasp, then home, as the approach (checked when it was planned) came in.
        let at_grasp = data.faults.grasp_q.is_some_and(|q_grasp| {
            let grasp = tcp_pose(arm, &q_grasp).translation.vector;
            (base_from_tcp.translation.vector - grasp).norm() < COLUMN_M
        });
        let raised = match data.faults.pregrasp_q.filter(|_| at_grasp) {
            Some(q_pregrasp) => tcp_pose(arm, &q_pregrasp),
            None => Translation3::new(0.0, 0.0, DROP_RAISE_M) * base_from_tcp,
        };
        let mut parts = Vec::new();
        let mut q_raised = q_now;
        if let Some(up) = straight_line(
            &self.planner.ik,
            &base_from_tcp,
            &raised,
            &q_now,
            LINE_STEP_M,
        ) {
            q_raised = up[up.len() - 1];
            parts.push(JointTrajectory::along(arm, up, speed));
        }
        parts.push(JointTrajectory::through(arm, &[q_raised, home], speed));
        let back = JointTrajectory::join(parts, true);
        // The straight rise is the way the jaws came down (checked when the pick was planned);
        // the move home from its top is new.
        let home_s = back.part_starts_s().get(1).copied().unwrap_or(0.0);
        let span = (home_s, back.duration_s());
        if let Some(checker) = &data.faults.checker
            && let Some(hit) =
                checker.check_span(&back, span, data.faults.open_m, None, &[PART_OBSTACLE])
        {
            return fail(
                FailureReason::Collision,
                format!(
                    "after the drop the way home would bring {} onto {}",
                    hit.link, hit.obstacle
                ),
            );
        }
        let span = (0.0, back.duration_s());
        data.execute(model, Phase::Retreat, &back, span, DROP_SETTLE_S, None)?;
        data.q = home;
        Ok(self.look_at_station(model, data))
    }

    /// What perception shows at the pick station now: the camera's look (a standing part it
    /// measures, else a lying tube in its frame), or in oracle mode the truth about the
    /// handled part.
    fn look_at_station(&mut self, model: &CellModel, data: &mut CellData) -> AtStation {
        let scenario = model.scenario();
        let belt = &scenario.conveyor;
        let station = Point3::new(
            belt.photo_eye_x_m,
            belt.belt_center_m[1],
            data.cell.belt_top_z,
        );
        // In a stream the next item waits a spacing upstream: only what lies nearer the
        // station than half of that can be the part that fell.
        let search_m = if scenario.is_stream() {
            LYING_SEARCH_M.min(scenario.stream.spacing_m / 2.0)
        } else {
            LYING_SEARCH_M
        };
        if let Some(camera) = self.camera {
            let Ok(sighting) = self.look(model, data, camera, TargetRule::NearestStation) else {
                return AtStation::Nothing;
            };
            let sizes = model
                .catalogue()
                .parts()
                .map(|(_, kind)| TubeSize {
                    diameter_m: kind.outer_diameter_m,
                    length_m: kind.height_m,
                })
                .collect();
            let (x, y) = (belt.belt_center_m[0], belt.belt_center_m[1]);
            let belt_xy_m = [
                [x - belt.length_m / 2.0, x + belt.length_m / 2.0],
                [y - belt.width_m / 2.0, y + belt.width_m / 2.0],
            ];
            let calibration = camera.rig().calibration;
            let finder = LyingPartFinder::new(calibration, data.cell.belt_top_z, belt_xy_m, sizes);
            // The bottles seen before the drop, where they stood: a body found lying where one
            // of them still is (the bottle fit places one there now too) is that bottle.
            let bottles_before: Vec<Point3<f64>> = data
                .faults
                .checker
                .iter()
                .flat_map(|c| c.obstacles())
                .filter(|o| o.name == "bottle")
                .map(|o| {
                    Point3::from(
                        (self.planner.world_from_base * o.base_from_shape)
                            .translation
                            .vector,
                    )
                })
                .collect();
            let was_bottle = |x: f64, y: f64| {
                bottles_before
                    .iter()
                    .any(|b| (b.x - x).hypot(b.y - y) < BOTTLE_STILL_M)
            };
            let lying = finder
                .find_all(&sighting.image, &station, search_m)
                .into_iter()
                .find(|part| {
                    !sighting.bottles.iter().flat_map(|b| &b.poses).any(|pose| {
                        let t = pose.world_from_bottle.translation.vector;
                        on_footprint(part, t.x, t.y) && was_bottle(t.x, t.y)
                    })
                });
            let target = sighting
                .target
                .as_ref()
                .map(|t| t.centre_in_world)
                .filter(|c| (c - station).xy().norm() < search_m);
            // A tube lying with its end to the camera can show a bore and the detector take it
            // for a standing one: where both name one body, the finder (which weighs the
            // standing outline against the lying one) decides; where they are two, the one
            // nearer the station is the part that fell.
            let standing = match (&lying, target) {
                (_, None) => false,
                (None, Some(_)) => true,
                (Some(part), Some(c)) => {
                    !on_footprint(part, c.x, c.y)
                        && (c - station).xy().norm() < (part.centre_in_world - station).xy().norm()
                }
            };
            if standing {
                if self.perceive(model, data, Some(sighting)).is_ok() {
                    return AtStation::Standing;
                }
                return AtStation::Nothing;
            }
            return lying.map_or(AtStation::Nothing, |part| {
                let around = seen_around(model, data, &sighting, &part);
                AtStation::Lying(part, around)
            });
        }
        let part = &data.cell.items.parts()[self.current];
        let Some(pose) = data.cell.body_pose(part.body) else {
            return AtStation::Nothing;
        };
        let axis = pose.rotation * Vector3::z();
        let on_belt = (pose.translation.x - belt.photo_eye_x_m).abs() < search_m
            && (pose.translation.y - belt.belt_center_m[1]).abs() < belt.width_m / 2.0;
        let instance = &part.instance;
        let standing_z = data.cell.belt_top_z + instance.height_m / 2.0;
        let lying_z = data.cell.belt_top_z + instance.outer_radius_m;
        if on_belt && axis.z > 0.9 && (pose.translation.z - standing_z).abs() < 0.01 {
            AtStation::Standing
        } else if on_belt && axis.z.abs() < 0.3 && (pose.translation.z - lying_z).abs() < 0.01 {
            let around = perceive_oracle(model, data, self.current)
                .map(|p| p.obstacles)
                .unwrap_or_default();
            let part = LyingPart {
                centre_in_world: Point3::from(pose.translation.vector),
                yaw_rad: axis.y.atan2(axis.x).rem_euclid(std::f64::consts::PI),
                length_m: instance.height_m,
                diameter_m: 2.0 * instance.outer_radius_m,
                size_index: instance.type_index,
                residual_px: 0.0,
            };
            AtStation::Lying(part, around)
        } else {
            AtStation::Nothing
        }
    }
}

/// What a look at the station after a drop shows of the part.
enum AtStation {
    /// A part standing there, to be picked again.
    Standing,
    /// A tube lying on the belt, and what its pick must clear around it.
    Lying(LyingPart, Vec<PerceivedObstacle>),
    /// Nothing the controller can act on.
    Nothing,
}

/// Whether the pick of a fallen part was refused by the planner (the arm never left home):
/// the part stays where it fell, and is counted lost.
fn refused_again(
    model: &CellModel,
    data: &CellData,
    current: usize,
    cycle: &mut Cycle,
    actions: &mut Vec<FaultAction>,
) -> bool {
    let Some(failure) = cycle.failure.as_mut() else {
        return false;
    };
    if !is_refusal(failure.reason) || data.faults.drop_seen.is_some() || cycle.placed_bin.is_some()
    {
        return false;
    }
    actions.push(FaultAction::CountedLost);
    let rest = data.part_resting_place(model, current);
    failure.detail = format!(
        "the fallen part's pick was refused ({}): counted lost (truth: {rest})",
        failure.detail
    );
    true
}

/// What the record keeps of a lying part.
fn lying_record(model: &CellModel, part: &LyingPart) -> LyingPartRecord {
    let c = part.centre_in_world;
    LyingPartRecord {
        centre_m: [c.x, c.y, c.z],
        axis_yaw_deg: part.yaw_rad.to_degrees(),
        length_mm: part.length_m * 1e3,
        diameter_mm: part.diameter_m * 1e3,
        part_type: model
            .catalogue()
            .part(PartTypeId(part.size_index))
            .name
            .clone(),
    }
}
