//! The cell's trial runner: builds the cell for each trial and runs its task.

use std::path::Path;
use std::sync::{Arc, OnceLock};
use std::time::Instant;

use super::cell_data::CellData;
use super::observer::{CellView, PerceptionFrame, TrialObserver, TrialObserverFactory};
use super::sorter::{Sorter, planner_for};
use crate::cell::{CellError, CellModel, StationSight};
use crate::detect::DetectorModel;
use crate::outcome::{FailureReason, Perception, TrialRecord, TrialRunner};
use crate::planning::PickPlanner;
use crate::scenario::Scenario;
use crate::station::{CameraPerception, CameraPerceptionError};

/// Why a runner could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum RunnerError {
    /// The cell (its arm, its URDF) could not be loaded.
    #[error(transparent)]
    Cell(#[from] CellError),
    /// The camera pipeline (renderer, detector model) could not be set up.
    #[error(transparent)]
    Camera(Box<CameraPerceptionError>),
}

/// Runs sorting trials of a scenario in the cell.
#[derive(Debug, Clone)]
pub struct CellTrialRunner {
    model: CellModel,
    camera: Option<Arc<CameraPerception>>,
    observers: Vec<Arc<dyn TrialObserverFactory>>,
    /// The planner's view of the cell, captured from the first cell built (it is the same for
    /// every trial).
    planner: OnceLock<PickPlanner>,
}

impl CellTrialRunner {
    /// A runner for `scenario` (read from `scenario_path`, which anchors a relative URDF path);
    /// camera perception uses the shipped detector model (built into the binary).
    pub fn new(
        scenario: Scenario,
        scenario_path: &Path,
        perception: Perception,
    ) -> Result<Self, RunnerError> {
        Self::with_detector(scenario, scenario_path, perception, DetectorModel::Shipped)
    }

    /// As [`Self::new`], camera perception with the detector model at `model_path` (its model
    /// card beside it).
    pub fn with_model(
        scenario: Scenario,
        scenario_path: &Path,
        perception: Perception,
        model_path: &Path,
    ) -> Result<Self, RunnerError> {
        let detector = DetectorModel::File(model_path.to_path_buf());
        Self::with_detector(scenario, scenario_path, perception, detector)
    }

    /// As [`Self::new`], camera perception with the detector's network `detector`.
    pub fn with_detector(
        scenario: Scenario,
        scenario_path: &Path,
        perception: Perception,
        detector: DetectorModel,
    ) -> Result<Self, RunnerError> {
        let camera = match perception {
            Perception::Camera => {
                let camera = CameraPerception::new(&scenario, detector)
                    .map_err(|e| RunnerError::Camera(Box::new(e)))?;
                Some(Arc::new(camera))
            }
            Perception::Oracle => None,
        };
        let model = CellModel::new(scenario, scenario_path)?;
        if camera.is_some() {
            let sight = StationSight::of(&model)?;
            tracing::debug!("the camera's sight of the pick station: {sight:?}");
            sight.check()?;
            if let Some(warning) = sight.partial_warning() {
                tracing::warn!("{warning}");
            }
        }
        Ok(Self {
            model,
            camera,
            observers: Vec::new(),
            planner: OnceLock::new(),
        })
    }

    /// Has every trial watched by an observer from `factory` as well as by those added before
    /// (records stay the same).
    pub fn observe_with(&mut self, factory: Arc<dyn TrialObserverFactory>) {
        self.observers.push(factory);
    }

    /// The scenario run.
    pub fn scenario(&self) -> &Scenario {
        self.model.scenario()
    }

    /// The cell's model.
    pub fn model(&self) -> &CellModel {
        &self.model
    }

    /// Overrides every part type's grip force (for experiments such as a too-weak gripper).
    pub fn set_grip_force_n(&mut self, force_n: f64) {
        self.model.set_grip_force_n(force_n);
    }
}

impl TrialRunner for CellTrialRunner {
    fn run_trial(&self, index: u32, seed: u64) -> TrialRecord {
        let started = Instant::now();
        let model = &self.model;
        let mut observer: Option<Box<dyn TrialObserver>> = match self.observers.as_slice() {
            [] => None,
            [one] => Some(one.observer(index)),
            many => Some(Box::new(Observers(
                many.iter().map(|f| f.observer(index)).collect(),
            ))),
        };
        let mut record = match CellData::reset(model, seed) {
            Ok(mut data) => {
                data.attach(model, observer.take(), index);
                let planner = self.planner.get_or_init(|| planner_for(model, &data));
                let sorter = Sorter::new(model, planner.clone(), self.camera.as_deref());
                let record = if model.scenario().conveyor.tracking {
                    sorter.run_tracking_stream(model, &mut data, index)
                } else if model.scenario().is_stream() {
                    sorter.run_stream(model, &mut data, index)
                } else {
                    sorter.run_single(model, &mut data, index)
                };
                observer = data.detach();
                record
            }
            Err(e) => TrialRecord::failed(
                index,
                seed,
                match &e {
                    CellError::Placement(_) => FailureReason::Placement,
                    _ => FailureReason::PhysicsBlowUp,
                },
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

/// Several observers of one trial, each called in turn.
struct Observers(Vec<Box<dyn TrialObserver>>);

impl TrialObserver for Observers {
    fn begin_trial(&mut self, trial_index: u32, scenario: &Scenario, view: &CellView<'_>) {
        for o in &mut self.0 {
            o.begin_trial(trial_index, scenario, view);
        }
    }

    fn sample(&mut self, sim_time_s: f64, view: &CellView<'_>) {
        for o in &mut self.0 {
            o.sample(sim_time_s, view);
        }
    }

    fn perception(&mut self, sim_time_s: f64, frame: &PerceptionFrame) {
        for o in &mut self.0 {
            o.perception(sim_time_s, frame);
        }
    }

    fn finish_trial(&mut self, outcome: &TrialRecord) {
        for o in &mut self.0 {
            o.finish_trial(outcome);
        }
    }
}
