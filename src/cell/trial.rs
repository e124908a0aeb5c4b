//! The task controller: one sorting trial as an explicit state machine over the physics world.
//!
//! wait -> perceive -> plan -> approach -> grasp -> lift -> transport -> place -> retreat, each
//! with a time-out and a named failure for every way it can go wrong.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rapier3d::prelude::*;

use super::camera_perception::{CameraPerception, Sighting};
use super::observer::{
    BoreView, CellView, DetectionView, ObserverSlot, PerceptionFrame, TrialObserver,
    TrialObserverFactory,
};
use super::{Cell, CellError, PartInstance, Tag};
use crate::batch::{
    DecisionRecord, FailureReason, Outcome, PartRecord, Perception, StreamPartRecord, StreamRecord,
    TrialRecord, TrialRunner, TrialTiming,
};
use crate::control::TrajectoryFollower;
use crate::kinematics::{AnalyticIk, ArmModel, IkSolver, JointVector};
use crate::planning::{Carried, CollisionChecker, JointTrajectory, Obstacle, straight_line};
use crate::render::Scene;
use crate::rng::SimRng;
use crate::scenario::{BottleSection, Scenario};
use crate::sim::JAW_SPEED_M_S;

/// Belt drive ramp, m/s^2: gentle enough that a standing bottle does not tip.
const BELT_ACCEL_M_S2: f64 = 1.0;
/// Height of the TCP above the part's bottom while grasping: the fingertips stop 8 mm above the
/// belt.
const GRASP_TCP_ABOVE_BOTTOM_M: f64 = 0.023;
/// Time for the grip force to build once the drive reaches its end, s.
const GRIP_BUILD_S: f64 = 0.1;
/// Approach and retreat distance above grasp and place poses, m.
const APPROACH_M: f64 = 0.12;
/// A robot collider this close to the bottle counts as touching it, m.
const TOUCH_DISTANCE_M: f64 = 0.0005;
/// How far the fingertips reach below the TCP along the tool axis, m.
const FINGERTIP_BELOW_TCP_M: f64 = 0.015;
/// Half the width of a finger pad across the jaw axis, m.
const PAD_HALF_WIDTH_M: f64 = 0.015;
/// Sample spacing of straight tool lines, m.
const LINE_STEP_M: f64 = 0.005;
/// The planner's name for the part while it stands on the belt.
const PART_OBSTACLE: &str = "part";
/// Things on the belt within this distance of the part are obstacles to its pick, m.
const NEIGHBOURHOOD_M: f64 = 0.45;
/// Distance between neighbouring places for parts in a bin, m.
const BIN_SLOT_PITCH_M: f64 = 0.09;
/// Clearance the planner keeps from obstacles, m.
const PLANNING_MARGIN_M: f64 = 0.008;
/// How much a bottle seen by the camera is grown as an obstacle, for the uncertainty of a pose
/// fitted to its box, m.
const SEEN_BOTTLE_GROWTH_M: f64 = 0.004;
/// Salt that keeps the camera's realism stream apart from the trial's physics stream.
const CAMERA_SALT: u64 = 0x4C4F_4F4B;

/// Runs sorting trials of a scenario in the cell.
#[derive(Debug, Clone)]
pub struct CellTrialRunner {
    scenario: Scenario,
    urdf: Option<(PathBuf, String)>,
    ik: AnalyticIk,
    camera: Option<Arc<CameraPerception>>,
    observers: Option<Arc<dyn TrialObserverFactory>>,
}

impl CellTrialRunner {
    /// A runner for `scenario` (read from `scenario_path`, which anchors a relative URDF path);
    /// camera perception uses the shipped detector model (`assets/models/detector.onnx`).
    pub fn new(
        scenario: Scenario,
        scenario_path: &Path,
        perception: Perception,
    ) -> Result<Self, CellError> {
        let model = crate::detect::Detector::default_path();
        Self::with_model(scenario, scenario_path, perception, &model)
    }

    /// As [`Self::new`], camera perception with the detector model at `model_path` (its model
    /// card beside it).
    pub fn with_model(
        scenario: Scenario,
        scenario_path: &Path,
        perception: Perception,
        model_path: &Path,
    ) -> Result<Self, CellError> {
        let urdf = match &scenario.robot.urdf {
            Some(relative) => {
                let path = scenario_path
                    .parent()
                    .unwrap_or(Path::new("."))
                    .join(relative);
                let text = std::fs::read_to_string(&path).map_err(|e| {
                    CellError::Sim(crate::sim::SimError::Urdf {
                        reason: e.to_string(),
                        path: path.clone(),
                    })
                })?;
                Some((path, text))
            }
            None => None,
        };
        let camera = match perception {
            Perception::Camera => {
                let camera = CameraPerception::new(&scenario, model_path.to_path_buf())
                    .map_err(|e| CellError::Camera(Box::new(e)))?;
                Some(Arc::new(camera))
            }
            Perception::Oracle => None,
        };
        let ik = AnalyticIk::new(Cell::arm_model())
            .map_err(|e| CellError::Sim(crate::sim::SimError::Kinematics(e)))?;
        Ok(Self {
            scenario,
            urdf,
            ik,
            camera,
            observers: None,
        })
    }

    /// Has every trial watched by an observer from `factory` (records stay the same).
    pub fn observe_with(&mut self, factory: Arc<dyn TrialObserverFactory>) {
        self.observers = Some(factory);
    }

    /// The scenario run.
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// Overrides every part type's grip force (for experiments such as a too-weak gripper).
    pub fn set_grip_force_n(&mut self, force_n: f64) {
        self.scenario.gripper.grip_force_n = force_n;
        for part in &mut self.scenario.part_types {
            part.grip_force_n = None;
        }
    }
}

impl TrialRunner for CellTrialRunner {
    fn run_trial(&self, index: u32, seed: u64) -> TrialRecord {
        let started = Instant::now();
        let mut rng = SimRng::new(seed);
        let mut observer = self.observers.as_ref().map(|f| f.observer(index));
        let mut record = match Cell::build(&self.scenario, self.urdf.as_ref(), &mut rng) {
            Ok(cell) => {
                let mut trial = Trial::new(
                    &self.scenario,
                    self.camera.as_deref(),
                    &self.ik,
                    cell,
                    rng,
                    seed,
                );
                trial.attach(observer.as_deref_mut(), index);
                if self.scenario.is_stream() {
                    trial.run_stream(index, seed)
                } else {
                    trial.run(index, seed)
                }
            }
            Err(e) => TrialRecord::failed(
                index,
                seed,
                FailureReason::PhysicsBlowUp,
                format!("cell could not be built: {e}"),
            ),
        };
        record.timing.wall_ms = started.elapsed().as_secs_f64() * 1e3;
        if let Some(observer) = observer.as_mut() {
            observer.finish_trial(&record);
        }
        record
    }
}

/// A failure with its reason and detail.
#[derive(Debug)]
struct Failure {
    reason: FailureReason,
    detail: String,
}

fn count_u32(n: usize) -> u32 {
    u32::try_from(n).unwrap_or(u32::MAX)
}

fn fail<T>(reason: FailureReason, detail: impl Into<String>) -> Result<T, Failure> {
    Err(Failure {
        reason,
        detail: detail.into(),
    })
}

/// What perception reports about the pick station.
#[derive(Debug, Clone)]
struct Percept {
    part_type: String,
    /// Part's centre on the belt (x, y) and bottom z, world.
    part_xy: [f64; 2],
    part_outer_radius_m: f64,
    part_height_m: f64,
    roundness_mm: Option<f64>,
    bore_diameter_mm: Option<f64>,
    /// Why the measurement contradicts the detection, if it does (the part is then rejected).
    inconsistency: Option<String>,
    /// Other things on the belt near the part, as obstacles in the world: name, pose of the
    /// shape, shape, top z. The paper's cell has one, the bottle.
    obstacles: Vec<PerceivedObstacle>,
}

/// What the stream's feeder puts on the belt next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FeedItem {
    Part,
    Bottle,
}

/// What one pick cycle did to its part.
struct Cycle {
    part: PartRecord,
    decision: Option<DecisionRecord>,
    placed_bin: Option<String>,
    failure: Option<Failure>,
    touched: bool,
    picked: bool,
    displacement_m: f64,
    cycle_time_s: f64,
}

/// How a motion is watched while it runs.
#[derive(Debug, Clone, Copy)]
enum Watch {
    Free,
    /// The part is held: it must stay where it was in the TCP frame.
    Holding {
        tcp_from_part: Isometry3<f64>,
    },
}

struct Trial<'a> {
    scenario: &'a Scenario,
    /// The camera pipeline; `None` reads the truth from the world (the oracle).
    camera: Option<&'a CameraPerception>,
    /// The trial's seed, and the camera shots taken so far (each draws its own realism).
    seed: u64,
    shots: u64,
    cell: Cell,
    model: ArmModel,
    ik: AnalyticIk,
    timing: TrialTiming,
    belt_target_m_s: f64,
    /// Parts on the belt or past it, and the one being handled.
    parts: Vec<(RigidBodyHandle, PartInstance)>,
    current: usize,
    /// Bottles and their poses when the belt last stopped.
    bottles: Vec<(RigidBodyHandle, Option<Isometry3<f64>>)>,
    /// The feeder's items still to come (taken from the end) and the belt travel since the
    /// last one went on.
    feed: Vec<FeedItem>,
    travel_since_feed_m: f64,
    rng: SimRng,
    /// Parts placed so far per bin (a stream fills its bins slot by slot).
    bin_fill: std::collections::BTreeMap<String, usize>,
    bottle_touched: bool,
    /// The phase in which the robot first touched the bottle.
    touch_phase: Option<&'static str>,
    /// The phase running now.
    phase: &'static str,
    /// Grip force per jaw for the detected part type, N.
    grip_recipe_n: f64,
    finger_command_m: f64,
    finger_target_m: f64,
    grip_force_n: f64,
    q: JointVector,
    pick_time_s: Option<f64>,
    observer: ObserverSlot<'a>,
}

impl<'a> Trial<'a> {
    fn new(
        scenario: &'a Scenario,
        camera: Option<&'a CameraPerception>,
        ik: &AnalyticIk,
        cell: Cell,
        mut rng: SimRng,
        seed: u64,
    ) -> Self {
        let model = Cell::arm_model();
        let ik = ik.clone();
        let parts = vec![(cell.part_body, cell.part.clone())];
        let bottles = cell.bottle_body.map(|b| (b, None)).into_iter().collect();
        // A stream opens with the part already on the belt; the rest follow in a seeded order.
        let mut feed = Vec::new();
        if scenario.is_stream() {
            feed.extend(std::iter::repeat_n(
                FeedItem::Part,
                scenario.parts_per_trial as usize - 1,
            ));
            feed.extend(std::iter::repeat_n(
                FeedItem::Bottle,
                scenario.stream.bottles as usize,
            ));
            for i in (1..feed.len()).rev() {
                let j = rng.below(i as u64 + 1) as usize;
                feed.swap(i, j);
            }
            feed.reverse();
        }
        Self {
            scenario,
            camera,
            seed,
            shots: 0,
            cell,
            model,
            ik,
            timing: TrialTiming::default(),
            belt_target_m_s: 0.0,
            parts,
            current: 0,
            bottles,
            feed,
            travel_since_feed_m: 0.0,
            rng,
            bin_fill: std::collections::BTreeMap::new(),
            bottle_touched: false,
            touch_phase: None,
            phase: "wait",
            grip_recipe_n: scenario.gripper.grip_force_n,
            finger_command_m: 0.045,
            finger_target_m: 0.045,
            grip_force_n: scenario.gripper.grip_force_n,
            q: scenario.robot.home_q_rad,
            pick_time_s: None,
            observer: ObserverSlot::default(),
        }
    }

    /// Attaches an observer to trial `index` and shows it the cell as built.
    fn attach(&mut self, observer: Option<&'a mut (dyn TrialObserver + 'static)>, index: u32) {
        self.observer = ObserverSlot::new(observer);
        let scenario = self.scenario;
        self.observe(|slot, view| slot.begin(index, scenario, view));
    }

    /// Hands `f` the observer's slot and a view of the cell as it is now.
    fn observe(&mut self, f: impl FnOnce(&mut ObserverSlot<'a>, &CellView<'_>)) {
        let view = CellView {
            cell: &self.cell,
            parts: &self.parts,
            phase: self.phase,
            joint_command_rad: self.q,
            grip_force_limit_n: self.grip_force_n,
        };
        f(&mut self.observer, &view);
    }

    /// The paper's trial: one part (and its bottle) from the belt into its bin.
    fn run(mut self, index: u32, seed: u64) -> TrialRecord {
        let cycle = match self.wait_for_part() {
            Ok(()) => self.pick_cycle(),
            Err(failure) => self.unreached(failure),
        };
        let (failure, detail) = match cycle.failure {
            Some(f) => (Some(f.reason), Some(f.detail)),
            None => (None, None),
        };
        let sim_time_s = self.cell.world.time_s();
        TrialRecord {
            trial: index,
            seed,
            outcome: Outcome::from_failed(failure.is_some()),
            failure,
            detail,
            part: Some(cycle.part),
            decision: cycle.decision,
            placed_bin: cycle.placed_bin,
            distractor_touched: cycle.touched,
            distractor_picked: cycle.picked,
            distractor_displacement_mm: cycle.displacement_m * 1e3,
            cycle_time_s: cycle.cycle_time_s,
            sim_time_s,
            timing: self.timing,
            stream: None,
        }
    }

    /// A stream trial: the feeder puts parts and bottles on the belt; the belt stops at the
    /// photo-eye for each; parts are sorted, bottles let through. The stream halts at its
    /// first fault, as a cell does.
    fn run_stream(mut self, index: u32, seed: u64) -> TrialRecord {
        let planned = self.scenario.parts_per_trial;
        let mut parts: Vec<StreamPartRecord> = Vec::new();
        let (mut bottles_passed, mut belt_stops) = (0u32, 0u32);
        let (mut touched, mut picked, mut displacement_m) = (false, false, 0.0f64);
        let mut first_stop_s = None;
        let mut halt: Option<Failure> = None;
        while parts.len() < planned as usize {
            if let Err(failure) = self.wait_for_part() {
                halt = Some(failure);
                break;
            }
            belt_stops += 1;
            first_stop_s.get_or_insert(self.pick_time_s.unwrap_or(0.0));
            let at_eye = self.cell.bodies_at_photo_eye();
            if let Some(i) = self.parts.iter().position(|(b, _)| at_eye.contains(b)) {
                self.current = i;
                let cycle = self.pick_cycle();
                touched |= cycle.touched;
                picked |= cycle.picked;
                displacement_m = displacement_m.max(cycle.displacement_m);
                if let Some(bin) = &cycle.placed_bin {
                    *self.bin_fill.entry(bin.clone()).or_insert(0) += 1;
                }
                let failed = cycle.failure.is_some();
                let (failure, detail) = match cycle.failure {
                    Some(f) => (Some(f.reason), Some(f.detail)),
                    None => (None, None),
                };
                parts.push(StreamPartRecord {
                    index: count_u32(parts.len()),
                    outcome: Outcome::from_failed(failed),
                    failure,
                    detail,
                    part: cycle.part,
                    decision: cycle.decision,
                    placed_bin: cycle.placed_bin,
                    cycle_time_s: cycle.cycle_time_s,
                });
                if failed {
                    break;
                }
            } else if self.bottles.iter().any(|(b, _)| at_eye.contains(b)) {
                bottles_passed += 1;
                if let Err(failure) = self.let_pass() {
                    halt = Some(failure);
                    break;
                }
            } else {
                halt = Some(Failure {
                    reason: FailureReason::NotDetected,
                    detail: "the photo-eye is blocked by neither a part nor a bottle".into(),
                });
                break;
            }
        }
        let parts_sorted = count_u32(
            parts
                .iter()
                .filter(|p| p.outcome == Outcome::Success)
                .count(),
        );
        let part_fault = parts
            .iter()
            .find(|p| p.outcome == Outcome::Failure)
            .map(|p| {
                (
                    p.failure,
                    format!(
                        "part {} ({}): {}",
                        p.index,
                        p.part.part_type,
                        p.detail.as_deref().unwrap_or("failed")
                    ),
                )
            });
        let (failure, detail) = match (part_fault, halt) {
            (Some((reason, detail)), _) => (reason, Some(detail)),
            (None, Some(f)) => (
                Some(f.reason),
                Some(format!("after {} parts: {}", parts.len(), f.detail)),
            ),
            (None, None) => (None, None),
        };
        let sim_time_s = self.cell.world.time_s();
        TrialRecord {
            trial: index,
            seed,
            outcome: Outcome::from_failed(failure.is_some()),
            failure,
            detail: detail.map(|d| format!("{parts_sorted}/{planned} parts sorted; {d}")),
            part: None,
            decision: None,
            placed_bin: None,
            distractor_touched: touched,
            distractor_picked: picked,
            distractor_displacement_mm: displacement_m * 1e3,
            cycle_time_s: first_stop_s.map_or(0.0, |t| sim_time_s - t),
            sim_time_s,
            timing: self.timing,
            stream: Some(StreamRecord {
                parts_planned: planned,
                parts_sorted,
                bottles_passed,
                belt_stops,
                parts,
            }),
        }
    }

    /// The truth about the part being handled.
    fn part_record(&self) -> PartRecord {
        let part = &self.parts[self.current].1;
        let true_roundness_mm = part.bore.roundness_m() * 1000.0;
        let truly_acceptable = true_roundness_mm <= self.scenario.roundness_tolerance_mm;
        let clear_cut = (true_roundness_mm - self.scenario.roundness_tolerance_mm).abs()
            > crate::batch::CLEAR_CUT_BAND_MM;
        PartRecord {
            part_type: part.type_name.clone(),
            true_roundness_mm,
            true_bore_diameter_mm: part.bore.mean_diameter_m() * 1000.0,
            truly_acceptable,
            clear_cut,
            correct_bin: self.bin_for(&part.type_name, truly_acceptable),
        }
    }

    /// A part that never reached the pick station.
    fn unreached(&self, failure: Failure) -> Cycle {
        Cycle {
            part: self.part_record(),
            decision: None,
            placed_bin: None,
            failure: Some(failure),
            touched: false,
            picked: false,
            displacement_m: 0.0,
            cycle_time_s: 0.0,
        }
    }

    /// One pick cycle on the part at the photo-eye (the belt stopped): perceive, sort, check
    /// the bin and the bottles.
    fn pick_cycle(&mut self) -> Cycle {
        self.bottle_touched = false;
        self.touch_phase = None;
        let part = self.part_record();
        let correct_bin = part.correct_bin.clone();
        let mut decision = None;
        let result = self.sort(&mut decision);
        let placed_bin = self.bin_holding_part();
        let displacement_m = self.bottle_displacement_m();
        let picked = self.bottle_lifted();
        let touched = self.bottle_touched || displacement_m > self.scenario.task.bottle_tolerance_m;
        let failure = if let Err(f) = result {
            Some(f)
        } else if picked {
            Some(Failure {
                reason: FailureReason::DistractorPicked,
                detail: "the bottle was lifted".into(),
            })
        } else if touched {
            Some(Failure {
                reason: FailureReason::DistractorTouched,
                detail: match self.touch_phase {
                    Some(phase) => format!(
                        "robot touched the bottle during {phase}; it moved {:.1} mm",
                        displacement_m * 1e3
                    ),
                    None => format!("bottle moved {:.1} mm", displacement_m * 1e3),
                },
            })
        } else if !self.bin_is_right(&part, placed_bin.as_deref()) {
            Some(Failure {
                reason: FailureReason::WrongBin,
                detail: format!(
                    "part in {}, belongs in {correct_bin}",
                    placed_bin.as_deref().unwrap_or("no bin")
                ),
            })
        } else {
            None
        };
        Cycle {
            part,
            decision,
            placed_bin,
            failure,
            touched,
            picked,
            displacement_m,
            cycle_time_s: self
                .pick_time_s
                .map_or(0.0, |t| self.cell.world.time_s() - t),
        }
    }

    /// Whether `placed_bin` is right for `part`: the bin its true roundness calls for or, for a
    /// part within [`crate::batch::CLEAR_CUT_BAND_MM`] of the tolerance (where no measurement can
    /// prove conformance either way, as in ISO 14253-1's uncertainty zone), either its type's
    /// accept bin or the reject bin.
    fn bin_is_right(&self, part: &PartRecord, placed_bin: Option<&str>) -> bool {
        let Some(placed) = placed_bin else {
            return false;
        };
        placed == part.correct_bin
            || (!part.clear_cut
                && (placed == self.bin_for(&part.part_type, true)
                    || placed == self.bin_for(&part.part_type, false)))
    }

    /// Runs the belt until the bottle at the photo-eye has passed it.
    fn let_pass(&mut self) -> Result<(), Failure> {
        self.belt_target_m_s = self.scenario.conveyor.speed_m_s;
        let deadline = self.cell.world.time_s() + self.scenario.task.wait_timeout_s;
        while self.cell.photo_eye_blocked() {
            if self.cell.world.time_s() > deadline {
                return fail(FailureReason::Timeout, "a bottle stuck at the photo-eye");
            }
            self.step()?;
        }
        Ok(())
    }

    fn bin_for(&self, part_type: &str, accept: bool) -> String {
        let bin = if accept {
            self.scenario.accept_bin(part_type)
        } else {
            self.scenario.reject_bin()
        };
        bin.map(|b| b.name.clone()).unwrap_or_default()
    }

    /// The whole task; `decision` is filled once perception has decided.
    fn sort(&mut self, decision: &mut Option<DecisionRecord>) -> Result<(), Failure> {
        let percept = self.perceive()?;
        // A part is accepted only when its bore was measured within tolerance and the measurement
        // agrees with the detected type.
        let accept = percept.inconsistency.is_none()
            && percept
                .roundness_mm
                .is_some_and(|r| r <= self.scenario.roundness_tolerance_mm);
        let bin = self.bin_for(&percept.part_type, accept);
        *decision = Some(DecisionRecord {
            detected_type: percept.part_type.clone(),
            measured_roundness_mm: percept.roundness_mm,
            measured_bore_diameter_mm: percept.bore_diameter_mm,
            accept,
            bin: bin.clone(),
            note: percept.inconsistency.clone(),
        });
        self.grip_recipe_n = self.scenario.grip_force_for(&percept.part_type);
        let plan_started = Instant::now();
        let checker = self.checker_with(&percept);
        let plan = self.plan_pick(&percept, &checker);
        self.timing.planning_ms += plan_started.elapsed().as_secs_f64() * 1e3;
        let plan = plan?;

        // Approach: open, move above the part, descend.
        let open = percept.part_outer_radius_m + self.scenario.gripper.open_clearance_m;
        self.set_gripper(open, 40.0);
        self.execute("approach", &plan.to_pregrasp, Watch::Free)?;
        self.execute("descend", &plan.descend, Watch::Free)?;
        // Grasp: close with the set force until the fingers stop.
        self.grasp(percept.part_outer_radius_m)?;
        let tcp_from_part = self.tcp_from_part()?;
        let watch = Watch::Holding { tcp_from_part };
        // Lift, transport, lower into the bin.
        self.execute("lift", &plan.lift, watch)?;
        let plan_started = Instant::now();
        let place = self.plan_place(&percept, &bin, &plan.lift_end, &checker);
        self.timing.planning_ms += plan_started.elapsed().as_secs_f64() * 1e3;
        let place = place?;
        self.execute("transport", &place.transport, watch)?;
        self.execute("place", &place.lower, watch)?;
        // Release and retreat.
        self.set_gripper(open, 40.0);
        self.settle(0.3)?;
        self.execute("retreat", &place.retreat, Watch::Free)?;
        self.settle(0.4)?;
        Ok(())
    }

    /// Runs the belt until the photo-eye sees something, then stops it and lets things settle.
    fn wait_for_part(&mut self) -> Result<(), Failure> {
        self.belt_target_m_s = self.scenario.conveyor.speed_m_s;
        let deadline = self.cell.world.time_s() + self.scenario.task.wait_timeout_s;
        // Hold the arm at home while waiting.
        self.hold();
        while !self.cell.photo_eye_blocked() {
            if self.cell.world.time_s() > deadline {
                return fail(FailureReason::Timeout, "no part reached the photo-eye");
            }
            self.step()?;
        }
        self.belt_target_m_s = 0.0;
        while self.cell.conveyor.speed_m_s() > 0.0 {
            self.step()?;
        }
        self.settle(0.25)?;
        self.pick_time_s = Some(self.cell.world.time_s());
        // Bottles still on the belt are watched through the cycle; one that has run off the
        // belt's end is out of the robot's reach.
        let belt = &self.scenario.conveyor;
        let belt_end_x = belt.belt_center_m[0] + belt.length_m / 2.0;
        for i in 0..self.bottles.len() {
            self.bottles[i].1 = self.cell.body_pose(self.bottles[i].0).filter(|pose| {
                pose.translation.x < belt_end_x
                    && (pose.translation.z - self.cell.belt_top_z).abs() < 0.2
            });
        }
        Ok(())
    }

    fn perceive(&mut self) -> Result<Percept, Failure> {
        match self.camera {
            Some(camera) => self.perceive_camera(camera),
            None => self.perceive_oracle(),
        }
    }

    /// The product: render the pick station as the camera sees it, detect, measure, and turn
    /// the measurement into the part's place in the world through the calibration.
    fn perceive_camera(&mut self, camera: &CameraPerception) -> Result<Percept, Failure> {
        let mut scene = Scene::from_cell(&self.cell, self.scenario);
        for (body, part) in &self.parts {
            if *body != self.cell.part_body
                && let Some(pose) = self.cell.body_pose(*body)
            {
                scene.push_part(*body, pose, part);
            }
        }
        let mut rng = SimRng::derive(self.seed ^ CAMERA_SALT, self.shots);
        self.shots += 1;
        let belt = &self.scenario.conveyor;
        let station = nalgebra::Point3::new(
            belt.photo_eye_x_m,
            belt.belt_center_m[1],
            self.cell.belt_top_z,
        );
        let sighting = camera
            .look(
                self.scenario,
                scene,
                &mut rng,
                &station,
                self.cell.belt_top_z,
            )
            .map_err(|e| Failure {
                reason: FailureReason::PerceptionError,
                detail: e.to_string(),
            })?;
        self.timing.render_ms += sighting.render_ms;
        self.timing.detect_ms += sighting.detect_ms;
        self.timing.metrology_ms += sighting.metrology_ms;
        let truth = self.part_record();
        self.observer
            .perception(|| perception_frame(&sighting, &truth));
        self.percept_from(&sighting)
    }

    /// What a camera sighting means for the pick: the target part's type, place and bore, and the
    /// bottles and other parts near it as obstacles.
    fn percept_from(&self, sighting: &Sighting) -> Result<Percept, Failure> {
        let Some(target) = &sighting.target else {
            return fail(
                FailureReason::NotDetected,
                format!(
                    "no part detected at the pick station ({} detections)",
                    sighting.detections.len()
                ),
            );
        };
        let part_type = &self.scenario.part_types[target.type_index];
        let part_height_m = part_type.height_mm / 1000.0;
        let centre = target.centre_in_world;
        let near = |x: f64, y: f64| (x - centre.x).hypot(y - centre.y) < NEIGHBOURHOOD_M;
        let mut obstacles = Vec::new();
        for bottle in &sighting.bottles {
            for pose in &bottle.poses {
                let t = pose.world_from_bottle.translation.vector;
                if near(t.x, t.y) {
                    obstacles.push(bottle_obstacle(
                        &self.scenario.bottle,
                        &pose.world_from_bottle,
                        pose.lying,
                        SEEN_BOTTLE_GROWTH_M,
                    ));
                }
            }
        }
        for other in &sighting.other_parts {
            let p = other.centre_in_world;
            if near(p.x, p.y) {
                let other_type = &self.scenario.part_types[other.type_index];
                let height_m = other_type.height_mm / 1000.0;
                obstacles.push(part_obstacle(
                    &nalgebra::Point3::new(p.x, p.y, self.cell.belt_top_z + height_m / 2.0),
                    other_type.outer_diameter_mm / 2000.0,
                    height_m,
                ));
            }
        }
        let (roundness_mm, bore_diameter_mm) = match &target.bore {
            Some((_, plane)) => (Some(plane.roundness_m * 1e3), Some(plane.diameter_m * 1e3)),
            None => (None, None),
        };
        Ok(Percept {
            part_type: part_type.name.clone(),
            part_xy: [centre.x, centre.y],
            part_outer_radius_m: part_type.outer_diameter_mm / 2000.0,
            part_height_m,
            roundness_mm,
            bore_diameter_mm,
            inconsistency: target.inconsistency.clone(),
            obstacles,
        })
    }

    /// Ground truth read from the world (diagnosis mode): the part at the pick station, and
    /// the bottles and other parts near it as obstacles.
    fn perceive_oracle(&self) -> Result<Percept, Failure> {
        let (part_body, part) = &self.parts[self.current];
        let Some(part_pose) = self.cell.body_pose(*part_body) else {
            return fail(FailureReason::NotDetected, "part body missing");
        };
        let near = |pose: &Isometry3<f64>| {
            let d = pose.translation.vector - part_pose.translation.vector;
            d.x.hypot(d.y) < NEIGHBOURHOOD_M && (d.z).abs() < 0.1
        };
        let mut obstacles = Vec::new();
        for (body, _) in &self.bottles {
            let Some(pose) = self.cell.body_pose(*body).filter(near) else {
                continue;
            };
            let lying = self.cell.bottle_lying || (pose.rotation * Vector3::z()).z.abs() < 0.7;
            obstacles.push(bottle_obstacle(&self.scenario.bottle, &pose, lying, 0.0));
        }
        for (i, (body, other)) in self.parts.iter().enumerate() {
            if i == self.current {
                continue;
            }
            let Some(pose) = self.cell.body_pose(*body).filter(near) else {
                continue;
            };
            obstacles.push(part_obstacle(
                &nalgebra::Point3::from(pose.translation.vector),
                other.outer_radius_m,
                other.height_m,
            ));
        }
        Ok(Percept {
            part_type: part.type_name.clone(),
            part_xy: [part_pose.translation.x, part_pose.translation.y],
            part_outer_radius_m: part.outer_radius_m,
            part_height_m: part.height_m,
            roundness_mm: Some(part.bore.roundness_m() * 1000.0),
            bore_diameter_mm: Some(part.bore.mean_diameter_m() * 1000.0),
            inconsistency: None,
            obstacles,
        })
    }

    fn checker_with(&self, percept: &Percept) -> CollisionChecker {
        let mut checker = CollisionChecker::new(
            self.model.clone(),
            self.cell.robot_shapes.clone(),
            self.cell.finger_reference_m,
            self.cell.obstacles.clone(),
            PLANNING_MARGIN_M,
        );
        // The part is an obstacle until the fingers go down around it.
        let part_center = Isometry3::from_parts(
            Translation3::new(
                percept.part_xy[0],
                percept.part_xy[1],
                self.cell.belt_top_z + percept.part_height_m / 2.0,
            ),
            UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
        );
        checker.add_obstacle(Obstacle {
            name: PART_OBSTACLE.into(),
            base_from_shape: self.cell.arm.world_from_base().inverse() * part_center,
            shape: SharedShape::cylinder(
                (percept.part_height_m / 2.0) as f32,
                percept.part_outer_radius_m as f32,
            ),
        });
        for (name, pose, shape, _) in &percept.obstacles {
            checker.add_obstacle(Obstacle {
                name: (*name).into(),
                base_from_shape: self.cell.arm.world_from_base().inverse() * pose,
                shape: shape.clone(),
            });
        }
        checker
    }

    /// TCP pose in the arm's base frame: pointing down, fingers along world yaw, at world xyz.
    fn tcp_in_base(&self, xyz: Vector3<f64>, yaw_rad: f64) -> Isometry3<f64> {
        self.tilted_tcp_in_base(xyz, yaw_rad, 0.0)
    }

    /// As [`Self::tcp_in_base`], the gripper leaning by `tilt_rad` about its own finger axis
    /// (the jaws still close horizontally; the wrist swings to one side).
    fn tilted_tcp_in_base(&self, xyz: Vector3<f64>, yaw_rad: f64, tilt_rad: f64) -> Isometry3<f64> {
        let world = Isometry3::from_parts(
            Translation3::from(xyz),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad)
                * UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.0)
                * UnitQuaternion::from_euler_angles(tilt_rad, 0.0, 0.0),
        );
        self.cell.arm.world_from_base().inverse() * world
    }

    fn plan_pick(
        &self,
        percept: &Percept,
        checker: &CollisionChecker,
    ) -> Result<PickPlan, Failure> {
        let belt_top = self.cell.belt_top_z;
        let [x, y] = percept.part_xy;
        let grasp_z = belt_top + GRASP_TCP_ABOVE_BOTTOM_M;
        let bottle_top = percept
            .obstacles
            .iter()
            .map(|(_, _, _, top)| *top)
            .fold(belt_top, f64::max);
        // Lift so the part's bottom clears the bottle and the rails.
        let lift_z = grasp_z + (bottle_top - belt_top + 0.04).max(APPROACH_M);
        // Come down from above the bottle: the fingertips hang 15 mm below the TCP.
        let approach_z = (grasp_z + APPROACH_M).max(bottle_top + 0.015 + 0.03);
        // Fingers close across the line to the bottle, so neither finger passes near it.
        let nearest = percept.obstacles.iter().min_by(|a, b| {
            let d = |o: &Isometry3<f64>| (o.translation.x - x).hypot(o.translation.y - y);
            d(&a.1).total_cmp(&d(&b.1))
        });
        let preferred_yaw = nearest.map_or(0.0, |(_, pose, _, _)| {
            (pose.translation.y - y).atan2(pose.translation.x - x) + std::f64::consts::FRAC_PI_2
        });
        let open = percept.part_outer_radius_m + self.scenario.gripper.open_clearance_m;
        let speed = self.scenario.robot.speed_fraction;
        let carry = self.scenario.robot.carry_speed_fraction;
        let mut reachable = false;
        let mut last_hit = String::new();
        // Upright first, then leaning away from either side: a tall bottle next to the part can
        // stand where an upright wrist or forearm would pass.
        let candidates = [0.0, 25.0, -25.0, 40.0, -40.0]
            .into_iter()
            .flat_map(|tilt_deg| {
                [
                    0.0, 180.0, 30.0, -30.0, 210.0, 150.0, 60.0, -60.0, 90.0, 270.0,
                ]
                .into_iter()
                .map(move |offset_deg: f64| (tilt_deg, offset_deg))
            });
        for (tilt_deg, offset_deg) in candidates {
            let yaw = preferred_yaw + f64::to_radians(offset_deg);
            let tilt = f64::to_radians(tilt_deg);
            // A leaning jaw's lower corner hangs deeper: raise the TCP to keep the tips clear.
            let corner_drop =
                FINGERTIP_BELOW_TCP_M * (tilt.cos() - 1.0) + PAD_HALF_WIDTH_M * tilt.abs().sin();
            let grasp_z = grasp_z + corner_drop.max(0.0);
            let above = self.tilted_tcp_in_base(Vector3::new(x, y, approach_z), yaw, tilt);
            let at = self.tilted_tcp_in_base(Vector3::new(x, y, grasp_z), yaw, tilt);
            let lifted = self.tilted_tcp_in_base(Vector3::new(x, y, lift_z), yaw, tilt);
            // Every arm configuration over the part, nearest first: another wrist or elbow
            // branch can keep the links off a bottle that the nearest one would hit.
            for q_above in self.ik.solve(&above).by_distance_from(&self.q) {
                // Straight down onto the part and straight up again: a joint-space move would
                // swing the open fingers centimetres off the part's axis.
                let Some(down) = straight_line(&self.ik, &above, &at, &q_above, LINE_STEP_M) else {
                    continue;
                };
                let q_at = down[down.len() - 1];
                let Some(up) = straight_line(&self.ik, &at, &lifted, &q_at, LINE_STEP_M) else {
                    continue;
                };
                let q_lift = up[up.len() - 1];
                reachable = true;
                let to_pregrasp = JointTrajectory::through(&self.model, &[self.q, q_above], speed);
                let descend = JointTrajectory::along(&self.model, down, speed * 0.5);
                let lift = JointTrajectory::through(&self.model, &[q_at, q_lift], carry * 0.5);
                let _ = up;
                let hit = checker
                    .check_trajectory(&descend, open, None, &[PART_OBSTACLE])
                    .or_else(|| checker.check_trajectory(&to_pregrasp, open, None, &[]));
                match hit {
                    Some(hit) => {
                        last_hit = format!(
                            "{} would hit {} at yaw {offset_deg} deg",
                            hit.link, hit.obstacle
                        )
                    }
                    None => {
                        return Ok(PickPlan {
                            to_pregrasp,
                            descend,
                            lift,
                            lift_end: q_lift,
                        });
                    }
                }
            }
        }
        if reachable {
            fail(FailureReason::Collision, last_hit)
        } else {
            fail(
                FailureReason::Unreachable,
                format!("no IK solution to grasp the part at ({x:.3}, {y:.3})"),
            )
        }
    }

    fn plan_place(
        &self,
        percept: &Percept,
        bin_name: &str,
        q_start: &JointVector,
        checker: &CollisionChecker,
    ) -> Result<PlacePlan, Failure> {
        let Some(bin) = self.cell.bins.iter().find(|b| b.name == bin_name) else {
            return fail(FailureReason::WrongBin, format!("no bin named {bin_name}"));
        };
        let floor = bin.floor_center + self.bin_slot(bin);
        let place_z = floor.z + 0.012 + GRASP_TCP_ABOVE_BOTTOM_M;
        let above_z = floor.z + bin.wall_height + 0.04 + GRASP_TCP_ABOVE_BOTTOM_M;
        let carried = Carried {
            tcp_from_shape: Isometry3::from_parts(
                Translation3::new(
                    0.0,
                    0.0,
                    -(percept.part_height_m / 2.0 - GRASP_TCP_ABOVE_BOTTOM_M),
                ),
                UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
            ),
            shape: SharedShape::cylinder(
                (percept.part_height_m / 2.0) as f32,
                percept.part_outer_radius_m as f32,
            ),
        };
        let grip = percept.part_outer_radius_m;
        let open = grip + self.scenario.gripper.open_clearance_m;
        let speed = self.scenario.robot.speed_fraction;
        let carry = self.scenario.robot.carry_speed_fraction;
        let mut reachable = false;
        let mut last_hit = String::new();
        for yaw_deg in [0.0, 90.0, 180.0, 270.0, 45.0, 135.0, 225.0, 315.0] {
            let yaw = f64::to_radians(yaw_deg);
            let above = self.tcp_in_base(Vector3::new(floor.x, floor.y, above_z), yaw);
            let at = self.tcp_in_base(Vector3::new(floor.x, floor.y, place_z), yaw);
            for q_above in self.ik.solve(&above).by_distance_from(q_start) {
                let Some(down) = straight_line(&self.ik, &above, &at, &q_above, LINE_STEP_M) else {
                    continue;
                };
                let q_at = down[down.len() - 1];
                let mut up = down.clone();
                up.reverse();
                reachable = true;
                let transport = JointTrajectory::through(&self.model, &[*q_start, q_above], carry);
                let lower = JointTrajectory::along(&self.model, down, carry * 0.5);
                let retreat = JointTrajectory::along(&self.model, up, speed * 0.5).then(
                    JointTrajectory::through(
                        &self.model,
                        &[q_above, self.scenario.robot.home_q_rad],
                        speed,
                    ),
                );
                let _ = q_at;
                let ignore = [PART_OBSTACLE];
                let hit = checker
                    .check_trajectory(&lower, grip, Some(&carried), &ignore)
                    .or_else(|| checker.check_trajectory(&transport, grip, Some(&carried), &ignore))
                    .or_else(|| checker.check_trajectory(&retreat, open, None, &ignore));
                match hit {
                    Some(hit) => {
                        last_hit = format!(
                            "{} would hit {} placing at yaw {yaw_deg} deg",
                            hit.link, hit.obstacle
                        )
                    }
                    None => {
                        return Ok(PlacePlan {
                            transport,
                            lower,
                            retreat,
                        });
                    }
                }
            }
        }
        if reachable {
            fail(FailureReason::Collision, last_hit)
        } else {
            fail(
                FailureReason::Unreachable,
                format!("bin {bin_name} is out of reach"),
            )
        }
    }

    /// Where in a bin the next part goes, from the floor's centre: the centre for the paper's
    /// single part; in a stream, the next free cell of a grid at BIN_SLOT_PITCH_M (centre
    /// first), so parts stand side by side rather than on top of each other.
    fn bin_slot(&self, bin: &super::BinBody) -> Vector3<f64> {
        let placed = self.bin_fill.get(&bin.name).copied().unwrap_or(0);
        if placed == 0 {
            return Vector3::zeros();
        }
        let per_side = |size: f64| {
            ((size - BIN_SLOT_PITCH_M) / BIN_SLOT_PITCH_M)
                .floor()
                .max(0.0) as usize
                + 1
        };
        let (nx, ny) = (per_side(bin.size[0]), per_side(bin.size[1]));
        let mut slots: Vec<Vector3<f64>> = (0..nx * ny)
            .map(|k| {
                let offset =
                    |i: usize, n: usize| (i as f64 - (n as f64 - 1.0) / 2.0) * BIN_SLOT_PITCH_M;
                Vector3::new(offset(k % nx, nx), offset(k / nx, ny), 0.0)
            })
            .collect();
        slots.sort_by(|a, b| a.norm().total_cmp(&b.norm()));
        slots[placed % slots.len()]
    }

    fn set_gripper(&mut self, offset_m: f64, force_n: f64) {
        self.finger_command_m = offset_m;
        self.grip_force_n = force_n;
    }

    /// Closes the jaws with the scenario's force: the drive runs its stroke to fully closed, then
    /// holds; a part between the jaws stops them short, which is how the grasp is detected.
    fn grasp(&mut self, part_radius_m: f64) -> Result<(), Failure> {
        self.set_gripper(0.0, self.grip_recipe_n);
        let stroke_s = self.finger_target_m / JAW_SPEED_M_S;
        self.settle(stroke_s + GRIP_BUILD_S)?;
        let gap = self.cell.arm.finger_positions_m(&self.cell.world);
        let closed_on_part = gap[0] + gap[1] > 2.0 * part_radius_m - 0.006;
        if !closed_on_part {
            return fail(
                FailureReason::Slipped,
                format!(
                    "jaws closed to {:.1} mm: nothing between them",
                    (gap[0] + gap[1]) * 1e3
                ),
            );
        }
        Ok(())
    }

    fn tcp_in_world(&self) -> Isometry3<f64> {
        self.cell.arm.flange_in_world(&self.cell.world) * self.model.flange_from_tcp
    }

    fn tcp_from_part(&self) -> Result<Isometry3<f64>, Failure> {
        let Some(part) = self.cell.body_pose(self.parts[self.current].0) else {
            return fail(FailureReason::PhysicsBlowUp, "part body missing");
        };
        Ok(self.tcp_in_world().inverse() * part)
    }

    /// Plays a trajectory to the end plus a short settle, watching for slips, drops and the bottle.
    fn execute(
        &mut self,
        phase: &'static str,
        trajectory: &JointTrajectory,
        watch: Watch,
    ) -> Result<(), Failure> {
        self.phase = phase;
        let follower = TrajectoryFollower::new(trajectory.clone(), self.cell.world.time_s());
        let end = self.cell.world.time_s() + trajectory.duration_s() + 0.15;
        while self.cell.world.time_s() < end {
            if let Some(sample) = follower.update(&mut self.cell.world, &self.cell.arm) {
                self.q = sample.q;
            }
            self.step_physics()?;
            if let Watch::Holding { tcp_from_part } = watch {
                self.check_hold(phase, &tcp_from_part)?;
            }
        }
        if let Some(q) = trajectory.end() {
            self.q = q;
        }
        Ok(())
    }

    fn check_hold(&self, phase: &str, tcp_from_part: &Isometry3<f64>) -> Result<(), Failure> {
        // Lowered into the bin, a part that meets the floor is placed, not slipping.
        if phase == "place" && self.bin_holding_part().is_some() {
            return Ok(());
        }
        let now = self.tcp_from_part()?;
        let drift = (now.translation.vector - tcp_from_part.translation.vector).norm();
        if drift <= self.scenario.task.slip_tolerance_m {
            return Ok(());
        }
        let part_z = now.translation.vector.norm();
        if drift > 0.05 || part_z > 0.2 {
            fail(
                FailureReason::Dropped,
                format!("part fell from the fingers ({:.0} mm away)", drift * 1e3),
            )
        } else {
            fail(
                FailureReason::Slipped,
                format!(
                    "part slid {:.1} mm in the fingers during {phase}",
                    drift * 1e3
                ),
            )
        }
    }

    /// Holds the arm where it is for `duration_s`.
    fn settle(&mut self, duration_s: f64) -> Result<(), Failure> {
        let end = self.cell.world.time_s() + duration_s;
        while self.cell.world.time_s() < end {
            self.step()?;
        }
        Ok(())
    }

    fn hold(&mut self) {
        self.cell
            .arm
            .command(&mut self.cell.world, &self.q, &[0.0; 6]);
    }

    /// One step holding the current arm command.
    fn step(&mut self) -> Result<(), Failure> {
        self.hold();
        self.step_physics()
    }

    /// One physics step with the belt and gripper drives, then the blow-up and bottle checks.
    fn step_physics(&mut self) -> Result<(), Failure> {
        let dt = self.cell.world.params().dt_s;
        self.cell
            .conveyor
            .ramp_towards(self.belt_target_m_s as f32, (BELT_ACCEL_M_S2 * dt) as f32);
        self.feed(f64::from(self.cell.conveyor.speed_m_s()) * dt);
        // The jaws travel at most JAW_SPEED_M_S, like a real gripper's drive.
        let step = JAW_SPEED_M_S * dt;
        self.finger_target_m += (self.finger_command_m - self.finger_target_m).clamp(-step, step);
        self.cell.arm.command_gripper(
            &mut self.cell.world,
            self.finger_target_m,
            self.grip_force_n,
        );
        let started = Instant::now();
        self.cell.world.step_with_hooks(&self.cell.conveyor);
        self.timing.physics_ms += started.elapsed().as_secs_f64() * 1e3;
        self.observe(|slot, view| slot.step(view));
        let time_s = self.cell.world.time_s();
        if time_s > self.scenario.task.trial_timeout_s {
            return fail(
                FailureReason::Timeout,
                format!("trial ran past {:.0} s", self.scenario.task.trial_timeout_s),
            );
        }
        let bodies = self.parts.iter().map(|p| p.0);
        for body in bodies.chain(self.bottles.iter().map(|b| b.0)) {
            let finite = self
                .cell
                .world
                .physics
                .bodies
                .get(body)
                .is_some_and(|b| b.position().is_finite() && b.linvel().is_finite());
            if !finite {
                return fail(
                    FailureReason::PhysicsBlowUp,
                    format!("a body's state became non-finite at t = {time_s:.3} s"),
                );
            }
        }
        if !self.bottle_touched {
            self.bottle_touched = self.robot_touches_bottle();
            if self.bottle_touched {
                self.touch_phase = Some(self.phase);
            }
        }
        Ok(())
    }

    fn robot_touches_bottle(&self) -> bool {
        self.bottles
            .iter()
            .any(|(bottle, _)| self.robot_touches(*bottle))
    }

    fn robot_touches(&self, bottle: RigidBodyHandle) -> bool {
        let physics = &self.cell.world.physics;
        let Some(rb) = physics.bodies.get(bottle) else {
            return false;
        };
        rb.colliders().iter().any(|&collider| {
            physics
                .narrow_phase
                .contact_pairs_with(collider)
                .any(|pair| {
                    let other = if pair.collider1 == collider {
                        pair.collider2
                    } else {
                        pair.collider1
                    };
                    // Touching, not merely within the solver's prediction distance.
                    let touching = pair
                        .manifolds()
                        .iter()
                        .any(|m| m.points.iter().any(|p| p.dist <= TOUCH_DISTANCE_M as f32));
                    touching
                        && physics
                            .colliders
                            .get(other)
                            .is_some_and(|c| c.user_data == Tag::Robot as u128)
                })
        })
    }

    fn bin_holding_part(&self) -> Option<String> {
        let pose = self.cell.body_pose(self.parts[self.current].0)?;
        let center = pose.translation.vector;
        self.cell
            .bins
            .iter()
            .find(|bin| bin.contains(&center))
            .map(|bin| bin.name.clone())
    }

    /// The largest move of a bottle since the belt last stopped, m.
    fn bottle_displacement_m(&self) -> f64 {
        self.bottles
            .iter()
            .filter_map(|(body, rest)| {
                let (now, rest) = (self.cell.body_pose(*body)?, (*rest)?);
                Some((now.translation.vector - rest.translation.vector).norm())
            })
            .fold(0.0, f64::max)
    }

    /// Whether a bottle has been lifted since the belt last stopped.
    fn bottle_lifted(&self) -> bool {
        self.bottles.iter().any(|(body, rest)| {
            let (Some(now), Some(rest)) = (self.cell.body_pose(*body), rest) else {
                return false;
            };
            now.translation.z - rest.translation.z > 0.02
        })
    }

    /// The stream's feeder: a new item goes on at the spawn point each time the belt has
    /// carried the previous one `stream.spacing_m`.
    fn feed(&mut self, belt_travel_m: f64) {
        if self.feed.is_empty() {
            return;
        }
        self.travel_since_feed_m += belt_travel_m;
        if self.travel_since_feed_m < self.scenario.stream.spacing_m {
            return;
        }
        self.travel_since_feed_m -= self.scenario.stream.spacing_m;
        match self.feed.pop() {
            Some(FeedItem::Part) => {
                let part = self.cell.spawn_part(self.scenario, &mut self.rng);
                self.parts.push(part);
            }
            Some(FeedItem::Bottle) => {
                let body = self.cell.spawn_bottle(self.scenario, &mut self.rng);
                self.bottles.push((body, None));
            }
            None => {}
        }
    }
}

struct PickPlan {
    to_pregrasp: JointTrajectory,
    descend: JointTrajectory,
    lift: JointTrajectory,
    lift_end: JointVector,
}

struct PlacePlan {
    transport: JointTrajectory,
    lower: JointTrajectory,
    retreat: JointTrajectory,
}

/// An obstacle as the planner takes it: name, pose of the shape, shape, top z.
type PerceivedObstacle = (&'static str, Isometry3<f64>, SharedShape, f64);

/// A bottle at `world_from_bottle` (origin at its base centre, axis along local z) as the
/// planner's obstacle: its bounding cylinder grown by `growth_m` all round.
fn bottle_obstacle(
    bottle: &BottleSection,
    world_from_bottle: &Isometry3<f64>,
    lying: bool,
    growth_m: f64,
) -> PerceivedObstacle {
    let half_height = bottle.height_m / 2.0 + growth_m;
    let radius = bottle.radius_m + growth_m;
    let shape = SharedShape::cylinder(half_height as f32, radius as f32);
    let center = world_from_bottle
        * Isometry3::from_parts(
            Translation3::new(0.0, 0.0, bottle.height_m / 2.0),
            UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
        );
    let top = center.translation.z + if lying { radius } else { half_height };
    ("bottle", center, shape, top)
}

/// Another upright part centred at `center_in_world` as the planner's obstacle.
fn part_obstacle(
    center_in_world: &nalgebra::Point3<f64>,
    outer_radius_m: f64,
    height_m: f64,
) -> PerceivedObstacle {
    let shape = SharedShape::cylinder((height_m / 2.0) as f32, outer_radius_m as f32);
    let center = Isometry3::from_parts(
        Translation3::from(center_in_world.coords),
        UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
    );
    (
        "other part",
        center,
        shape,
        center_in_world.z + height_m / 2.0,
    )
}

/// What the camera saw, as an observer is shown it: the image, the detector's boxes, and the
/// target's bore with the truth beside the measurement.
fn perception_frame(sighting: &Sighting, truth: &PartRecord) -> PerceptionFrame {
    let detections = sighting
        .detections
        .iter()
        .map(|d| DetectionView {
            class_name: d.class_name.clone(),
            score: d.score,
            box_px: d.box_px,
        })
        .collect();
    let bores = sighting
        .target
        .iter()
        .filter_map(|t| t.bore.as_ref())
        .map(|(bore, plane)| BoreView {
            centre_px: bore.centre_px,
            radius_px: bore.radius_px,
            contour_px: bore.edge_points_px.clone(),
            measured_roundness_mm: Some(plane.roundness_m * 1e3),
            true_roundness_mm: Some(truth.true_roundness_mm),
            measured_diameter_mm: Some(plane.diameter_m * 1e3),
            true_diameter_mm: Some(truth.true_bore_diameter_mm),
        })
        .collect();
    PerceptionFrame {
        image: sighting.image.clone(),
        detections,
        bores,
    }
}
