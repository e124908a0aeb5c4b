//! Hooks through which an outside observer (a recorder, a viewer) watches a trial run.
//!
//! The cell calls a [`TrialObserver`] at the start of a trial, at [`SAMPLE_RATE_HZ`] of simulated
//! time from the physics loop, when perception has looked at the pick station, and with the
//! trial's record at the end. Observers get read-only views: they cannot change what a trial
//! does, so a batch's records are the same with and without one. The cell knows nothing of any
//! particular observer (the `record` module holds the Rerun recorder).

use nalgebra::Isometry3;
use rapier3d::prelude::RigidBodyHandle;

use crate::cell::Cell;
use crate::kinematics::JointVector;
use crate::outcome::{Phase, TrialRecord};
use crate::scenario::Scenario;
use crate::sim::{FINGER_LINKS, PartItem, Tag};

/// How often a running trial is sampled, per second of simulated time.
pub const SAMPLE_RATE_HZ: f64 = 30.0;

/// Watches trials. Every hook is called on the thread that runs the trial.
pub trait TrialObserver {
    /// Trial `trial_index` of `scenario` starts; `view` shows the cell as built.
    fn begin_trial(&mut self, trial_index: u32, scenario: &Scenario, view: &CellView<'_>);
    /// The cell at `sim_time_s`, about [`SAMPLE_RATE_HZ`] times per simulated second.
    fn sample(&mut self, sim_time_s: f64, view: &CellView<'_>);
    /// What perception made of the pick-station image at `sim_time_s`.
    fn perception(&mut self, sim_time_s: f64, frame: &PerceptionFrame);
    /// The trial is over; `outcome` is its record as the batch writes it.
    fn finish_trial(&mut self, outcome: &TrialRecord);
}

/// Makes one observer per trial; shared by the batch's worker threads.
pub trait TrialObserverFactory: Send + Sync + std::fmt::Debug {
    /// The observer of trial `trial_index`.
    fn observer(&self, trial_index: u32) -> Box<dyn TrialObserver>;
}

/// A read-only view of a running trial's cell.
#[derive(Clone, Copy)]
pub struct CellView<'a> {
    /// The cell: world, arm, bins, and the registry of parts and bottles.
    pub cell: &'a Cell,
    /// The task phase running now (`wait`, `approach`, `grasp`, ...).
    pub phase: Phase,
    /// The joint angles the controller commands, rad.
    pub joint_command_rad: JointVector,
    /// The grip force the jaws may push with, per jaw, N.
    pub grip_force_limit_n: f64,
}

impl<'a> CellView<'a> {
    /// Every part the trial has put on the belt so far, with its body.
    pub fn parts(&self) -> &'a [PartItem] {
        self.cell.items.parts()
    }

    /// Simulated time, s.
    pub fn sim_time_s(&self) -> f64 {
        self.cell.world.time_s()
    }

    /// Measured joint angles, rad.
    pub fn joint_positions_rad(&self) -> JointVector {
        self.cell.arm.joint_positions(&self.cell.world)
    }

    /// Measured jaw positions, each pad's distance from the gripper's centre line, m.
    pub fn jaw_positions_m(&self) -> [f64; 2] {
        self.cell.arm.finger_positions_m(&self.cell.world)
    }

    /// Pose of a body in the world.
    pub fn body_pose(&self, body: RigidBodyHandle) -> Option<Isometry3<f64>> {
        self.cell.body_pose(body)
    }

    /// Whether `body` can move (the arm's links, parts, bottles), as opposed to fixed scenery.
    pub fn is_moving(&self, body: RigidBodyHandle) -> bool {
        self.cell
            .world
            .physics
            .bodies
            .get(body)
            .is_some_and(|b| !b.is_fixed())
    }

    /// Every bottle body in the world, in handle order.
    pub fn bottles(&self) -> Vec<RigidBodyHandle> {
        let mut bottles: Vec<RigidBodyHandle> =
            self.cell.items.bottles().iter().map(|b| b.body).collect();
        bottles.sort_by_key(|h| h.into_raw_parts());
        bottles
    }

    /// The force with which each jaw (left, right) presses on parts in the last step, N: the
    /// contact solver's normal impulses over the time step.
    pub fn jaw_grip_force_n(&self) -> [f64; 2] {
        let world = &self.cell.world;
        let dt_s = world.params().dt_s;
        FINGER_LINKS.map(|link| {
            let Some(body) = self.cell.arm.link_body(link) else {
                return 0.0;
            };
            let impulse = world.contact_impulse_with(body, Tag::Part);
            impulse / dt_s
        })
    }
}

/// What perception made of one pick-station image, as plain data for observers.
#[derive(Debug, Clone, PartialEq)]
pub struct PerceptionFrame {
    /// The image as the camera delivered it.
    pub image: image::RgbImage,
    /// The detector's objects.
    pub detections: Vec<DetectionView>,
    /// The bores measured.
    pub bores: Vec<BoreView>,
    /// What the look took to stand at the pick station: a part type's name, `bottle`, or
    /// `None` for nothing.
    pub station: Option<String>,
}

/// One detected object.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectionView {
    /// Class name: a part type or `bottle`.
    pub class_name: String,
    /// Confidence in [0, 1].
    pub score: f32,
    /// Box `[x_min, y_min, x_max, y_max]`, pixels (x right, y down).
    pub box_px: [f32; 4],
}

/// One measured bore, with the truth where it is known.
#[derive(Debug, Clone, PartialEq)]
pub struct BoreView {
    /// Fitted centre `[x, y]`, pixels.
    pub centre_px: [f64; 2],
    /// Fitted radius, pixels.
    pub radius_px: f64,
    /// The edge points the circle was fitted to, pixels, in order around the bore.
    pub contour_px: Vec<[f64; 2]>,
    /// Measured roundness `Rmax - Rmin`, mm.
    pub measured_roundness_mm: Option<f64>,
    /// True roundness, mm.
    pub true_roundness_mm: Option<f64>,
    /// Measured bore diameter, mm.
    pub measured_diameter_mm: Option<f64>,
    /// True bore diameter, mm.
    pub true_diameter_mm: Option<f64>,
}

/// The observer attached to a running trial, and when it is next due for a sample.
#[derive(Default)]
pub(crate) struct ObserverSlot {
    observer: Option<Box<dyn TrialObserver>>,
    next_sample_s: f64,
    now_s: f64,
}

impl ObserverSlot {
    /// A slot holding `observer`; empty slots cost one branch a step.
    pub(crate) fn new(observer: Option<Box<dyn TrialObserver>>) -> Self {
        Self {
            observer,
            next_sample_s: 0.0,
            now_s: 0.0,
        }
    }

    /// Starts trial `trial_index`: the observer sees the cell as built, then a first sample.
    pub(crate) fn begin(&mut self, trial_index: u32, scenario: &Scenario, view: &CellView<'_>) {
        let Some(observer) = self.observer.as_deref_mut() else {
            return;
        };
        self.now_s = view.sim_time_s();
        observer.begin_trial(trial_index, scenario, view);
        observer.sample(self.now_s, view);
        self.next_sample_s = self.now_s + 1.0 / SAMPLE_RATE_HZ;
    }

    /// After a physics step: a sample when one is due.
    pub(crate) fn step(&mut self, view: &CellView<'_>) {
        let Some(observer) = self.observer.as_deref_mut() else {
            return;
        };
        self.now_s = view.sim_time_s();
        // A small tolerance keeps the sample times on the 1/30 s grid despite float steps.
        if self.now_s + 1e-9 >= self.next_sample_s {
            observer.sample(self.now_s, view);
            while self.next_sample_s <= self.now_s + 1e-9 {
                self.next_sample_s += 1.0 / SAMPLE_RATE_HZ;
            }
        }
    }

    /// Empties the slot, handing back its observer.
    pub(crate) fn take(&mut self) -> Option<Box<dyn TrialObserver>> {
        self.observer.take()
    }

    /// Hands perception's result to the observer; `frame` is built only when one is attached.
    pub(crate) fn perception(&mut self, frame: impl FnOnce() -> PerceptionFrame) {
        if let Some(observer) = self.observer.as_deref_mut() {
            observer.perception(self.now_s, &frame());
        }
    }
}
