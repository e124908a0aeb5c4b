//! The environment: a cell model, the trial running in it, and the step that advances it.

use image::RgbImage;
use nalgebra::Isometry3;

use super::action::{Action, ActionError, ArmTarget};
use super::episode_end::{self, Ending};
use super::observation::{Observation, Truth};
use crate::batch::trial_seed;
use crate::camera::CameraJson;
use crate::cell::{CellError, CellModel};
use crate::kinematics::{IkSolver, JointVector};
use crate::outcome::{Failure, FailureReason, Perception, TrialRecord};
use crate::render::{CameraRig, Renderer, RendererOptions, Scene, Shot};
use crate::rng::SimRng;
use crate::task::CellData;

/// Physics steps in one control period: at the default 1/240 s step, a period is 1/30 s, the
/// rate at which observers sample a trial.
pub const PHYSICS_STEPS_PER_CONTROL: usize = 8;

/// Salt that keeps the frames' realism stream apart from the trial's physics stream.
const FRAME_SALT: u64 = 0x4752_4142;

/// Why the environment could not be made or stepped.
#[derive(Debug, thiserror::Error)]
pub enum EnvError {
    /// The cell could not be built for a trial.
    #[error(transparent)]
    Cell(#[from] CellError),
    /// The scenario feeds a stream of parts; an episode is one part.
    #[error(
        "scenario {0}: an episode is one single-part trial, and this scenario is a stream \
         (parts_per_trial > 1)"
    )]
    Stream(String),
    /// The camera or its renderer could not be set up, or a frame not rendered.
    #[error("camera: {0}")]
    Camera(String),
    /// `step` before the first `reset`.
    #[error("no episode is running: call reset first")]
    NoEpisode,
    /// `step` after the episode ended.
    #[error("the episode is over (trial {0}): call reset")]
    EpisodeOver(u32),
    /// The action was refused.
    #[error(transparent)]
    Action(#[from] ActionError),
}

/// What one step gives back.
#[derive(Debug, Clone)]
pub struct StepResult {
    /// The sensors after the period.
    pub observation: Observation,
    /// Whether the action's tool pose had no IK solution (the arm kept its last target).
    pub ik_unreachable: bool,
    /// The trial's record, judged, once it has ended; `None` while it runs.
    pub record: Option<TrialRecord>,
    /// Whether it ended by the scenario's trial time-out.
    pub timed_out: bool,
}

/// One running trial.
struct Episode {
    data: CellData,
    trial: u32,
    target_q: JointVector,
    jaw_command: (f64, f64),
    /// The joint servos' set-point velocities, rad/s.
    setpoint_qd: JointVector,
    velocities: JointVector,
    ending: episode_end::Watch,
    record: Option<TrialRecord>,
}

/// A scenario's cell, stepped by an outside controller.
pub struct CellEnv {
    model: CellModel,
    perception: Perception,
    rig: CameraRig,
    renderer: Option<Renderer>,
    scenario_seed: u64,
    episode: Option<Episode>,
    /// The record of a trial whose cell could not be built (its last reset failed).
    unbuilt: Option<TrialRecord>,
}

impl CellEnv {
    /// The environment of `model`'s scenario; camera mode sets up the renderer now, so that a
    /// machine without one fails here.
    pub fn new(model: CellModel, perception: Perception) -> Result<Self, EnvError> {
        let scenario = model.scenario();
        if scenario.is_stream() {
            return Err(EnvError::Stream(scenario.name.clone()));
        }
        let rig =
            CameraRig::from_scenario(scenario).map_err(|e| EnvError::Camera(e.to_string()))?;
        let scenario_seed = scenario.seed;
        let mut env = Self {
            model,
            perception,
            rig,
            renderer: None,
            scenario_seed,
            episode: None,
            unbuilt: None,
        };
        if perception == Perception::Camera {
            env.renderer()?;
        }
        Ok(env)
    }

    /// The cell's model.
    pub fn model(&self) -> &CellModel {
        &self.model
    }

    /// The perception mode.
    pub fn perception(&self) -> Perception {
        self.perception
    }

    /// The scenario seed trials are drawn from.
    pub fn scenario_seed(&self) -> u64 {
        self.scenario_seed
    }

    /// One control period, s.
    pub fn control_period_s(&self) -> f64 {
        self.model.scenario().physics.dt_s * PHYSICS_STEPS_PER_CONTROL as f64
    }

    /// The camera's calibration and image size, as `twincell render` writes it.
    pub fn calibration(&self) -> CameraJson {
        CameraJson::new(&self.rig.calibration, self.rig.width_px, self.rig.height_px)
    }

    /// Top of the belt, world z, m (parts stand on it).
    pub fn belt_top_z_m(&self) -> Option<f64> {
        self.episode.as_ref().map(|e| e.data.view().cell.belt_top_z)
    }

    /// The pose of the arm's base in the world (where tool poses are solved from), once reset.
    pub fn world_from_base(&self) -> Option<Isometry3<f64>> {
        self.episode
            .as_ref()
            .map(|e| *e.data.view().cell.arm.world_from_base())
    }

    /// The trial running (or last run), if any.
    pub fn trial(&self) -> Option<u32> {
        self.episode.as_ref().map(|e| e.trial)
    }

    /// Starts trial `trial` of the scenario seeded `scenario_seed` (the scenario's own seed, or
    /// the one last given, when `None`): the cell as `twincell run` builds it, the arm at home,
    /// the belt stopped. Returns the first observation (without a frame).
    pub fn reset(
        &mut self,
        trial: u32,
        scenario_seed: Option<u64>,
    ) -> Result<Observation, EnvError> {
        if let Some(seed) = scenario_seed {
            self.scenario_seed = seed;
        }
        self.episode = None;
        self.unbuilt = None;
        let seed = trial_seed(self.scenario_seed, trial);
        let data = match CellData::reset(&self.model, seed) {
            Ok(data) => data,
            Err(e) => {
                // Recorded as `twincell run` records it: a failed trial, not a failed batch.
                let reason = match &e {
                    CellError::Placement(_) => FailureReason::Placement,
                    _ => FailureReason::PhysicsBlowUp,
                };
                let detail = format!("cell could not be built: {e}");
                self.unbuilt = Some(TrialRecord::failed(trial, seed, reason, detail));
                return Err(e.into());
            }
        };
        let view = data.view();
        let target_q = view.joint_command_rad;
        let pads = view.jaw_positions_m();
        let jaw_command = (pads[0] + pads[1], view.grip_force_limit_n);
        let ending = episode_end::Watch::default();
        self.episode = Some(Episode {
            data,
            trial,
            target_q,
            jaw_command,
            setpoint_qd: [0.0; 6],
            velocities: [0.0; 6],
            ending,
            record: None,
        });
        self.observe(None)
    }

    /// Applies `action` for one control period and judges the trial if that ended it.
    pub fn step(&mut self, action: &Action) -> Result<StepResult, EnvError> {
        action.validate(self.model.arm_model())?;
        let model = &self.model;
        let Some(episode) = self.episode.as_mut() else {
            return Err(EnvError::NoEpisode);
        };
        if episode.record.is_some() {
            return Err(EnvError::EpisodeOver(episode.trial));
        }
        let data = &mut episode.data;
        let mut ik_unreachable = false;
        match &action.arm {
            ArmTarget::Joints(q) => episode.target_q = *q,
            ArmTarget::ToolPose(world_from_tcp) => {
                let base_from_tcp = data.cell.arm.world_from_base().inverse() * world_from_tcp;
                let solutions = model.ik().solve(&base_from_tcp);
                match nearest(solutions.as_slice(), &data.q) {
                    Some(q) => episode.target_q = q,
                    None => ik_unreachable = true,
                }
            }
        }
        let jaw_command = (action.jaw_width_m, action.jaw_force_n);
        if jaw_command != episode.jaw_command {
            let pads = data.cell.arm.finger_positions_m(&data.cell.world);
            let offset_m = action.jaw_width_m / 2.0;
            data.gripper
                .open_from(pads[0].min(pads[1]), offset_m, action.jaw_force_n);
            episode.jaw_command = jaw_command;
        }
        let speed = if action.belt_run {
            model.scenario().conveyor.speed_m_s
        } else {
            0.0
        };
        data.belt.run_at(speed);
        data.phase = episode.ending.phase(data, action.belt_run);
        let before = data.view().joint_positions_rad();
        let result = run_period(model, data, &episode.target_q, &mut episode.setpoint_qd);
        let after = data.view().joint_positions_rad();
        let period_s = self.model.scenario().physics.dt_s * PHYSICS_STEPS_PER_CONTROL as f64;
        episode.velocities = std::array::from_fn(|j| (after[j] - before[j]) / period_s);
        let ending = match result {
            Ok(()) => episode.ending.update(model, data, period_s),
            Err(failure) => Some(Ending::Failed(failure)),
        };
        let timed_out =
            matches!(&ending, Some(Ending::Failed(f)) if f.reason == FailureReason::Timeout);
        if let Some(ending) = ending {
            let record = episode.ending.record(model, data, episode.trial, ending);
            episode.record = Some(record);
        }
        let record = episode.record.clone();
        let observation = self.observe(action.take_frame.then_some(()))?;
        Ok(StepResult {
            observation,
            ik_unreachable,
            record,
            timed_out,
        })
    }

    /// Ends the episode now, as a controller that gives up: the trial is judged as it stands.
    /// The record it already had when it had ended; a trial whose cell could not be built
    /// (the last reset failed) is a failed record; `None` before any reset.
    pub fn finish(&mut self) -> Option<TrialRecord> {
        if let Some(record) = &self.unbuilt {
            return Some(record.clone());
        }
        let model = &self.model;
        let episode = self.episode.as_mut()?;
        if episode.record.is_none() {
            let record =
                episode
                    .ending
                    .record(model, &mut episode.data, episode.trial, Ending::GaveUp);
            episode.record = Some(record);
        }
        episode.record.clone()
    }

    /// The sensors now, with a new frame when `frame` is `Some`.
    fn observe(&mut self, frame: Option<()>) -> Result<Observation, EnvError> {
        let image = match frame {
            Some(()) => Some(self.render_frame()?),
            None => None,
        };
        let Some(episode) = self.episode.as_ref() else {
            return Err(EnvError::NoEpisode);
        };
        let data = &episode.data;
        let view = data.view();
        let pads = view.jaw_positions_m();
        let truth = (self.perception == Perception::Oracle).then(|| self.truth(data));
        Ok(Observation {
            joint_positions_rad: view.joint_positions_rad(),
            joint_velocities_rad_s: episode.velocities,
            jaw_width_m: pads[0] + pads[1],
            jaw_force_n: view.jaw_grip_force_n(),
            photo_eye: data.photo_eye_reports(),
            belt_position_m: data.belt.encoder_travel_m(),
            belt_speed_m_s: f64::from(view.cell.conveyor.speed_m_s()),
            sim_time_s: view.sim_time_s(),
            frame: image,
            truth,
        })
    }

    /// The world's truth about the trial's part and bottles.
    fn truth(&self, data: &CellData) -> Truth {
        let view = data.view();
        let (scenario, catalogue) = (self.model.scenario(), self.model.catalogue());
        let part = &view.parts()[0];
        let record = crate::task::judge::part_record(scenario, catalogue, &part.instance);
        let correct_bin = scenario
            .bins
            .iter()
            .position(|b| b.name == record.correct_bin);
        Truth {
            part_type: part.instance.type_index,
            world_from_part: view
                .body_pose(part.body)
                .unwrap_or_else(Isometry3::identity),
            roundness_mm: record.true_roundness_mm,
            bore_diameter_mm: record.true_bore_diameter_mm,
            correct_bin,
            world_from_bottles: view
                .cell
                .items
                .bottles()
                .iter()
                .filter_map(|b| view.body_pose(b.body))
                .collect(),
        }
    }

    /// The renderer, made on first use.
    fn renderer(&mut self) -> Result<&mut Renderer, EnvError> {
        if self.renderer.is_none() {
            let camera = &self.model.scenario().camera;
            let options = RendererOptions {
                msaa_samples: camera.msaa_samples,
                supersample: camera.supersample,
            };
            let renderer = Renderer::new(options).map_err(|e| EnvError::Camera(e.to_string()))?;
            self.renderer = Some(renderer);
        }
        self.renderer
            .as_mut()
            .ok_or_else(|| EnvError::Camera("no renderer".into()))
    }

    /// The camera's frame of the cell as it stands, its realism drawn from the trial's seed and
    /// the number of frames taken so far.
    fn render_frame(&mut self) -> Result<RgbImage, EnvError> {
        let rig = self.rig;
        let shot = {
            let Some(episode) = self.episode.as_mut() else {
                return Err(EnvError::NoEpisode);
            };
            let scenario = self.model.scenario();
            let data = &mut episode.data;
            let scene = Scene::from_cell(data.view().cell, scenario);
            let mut rng = SimRng::derive(data.seed ^ FRAME_SALT, data.shots);
            data.shots += 1;
            Shot::of_scene(scenario, &rig, &scenario.sensor, scene, &mut rng)
        };
        let renderer = self.renderer()?;
        shot.render(renderer)
            .map_err(|e| EnvError::Camera(e.to_string()))
    }
}

/// One control period: the servos' set-points move towards `target_q` at the joints' velocity
/// limits, one physics step at a time.
fn run_period(
    model: &CellModel,
    data: &mut CellData,
    target_q: &JointVector,
    setpoint_qd: &mut JointVector,
) -> Result<(), Failure> {
    let dt_s = model.scenario().physics.dt_s;
    let limits = &model.arm_model().limits;
    for _ in 0..PHYSICS_STEPS_PER_CONTROL {
        for j in 0..6 {
            let (v_max, a_max) = (limits[j].max_velocity_rad_s, limits[j].max_accel_rad_s2);
            let error = target_q[j] - data.q[j];
            // The fastest speed from which the joint still stops at the target, then at most
            // its velocity limit, reached at most at its acceleration limit.
            let stop = (2.0 * a_max * error.abs()).sqrt().min(error.abs() / dt_s);
            let wanted = stop.min(v_max).copysign(error);
            let v = wanted.clamp(setpoint_qd[j] - a_max * dt_s, setpoint_qd[j] + a_max * dt_s);
            data.q[j] += v * dt_s;
            setpoint_qd[j] = v;
        }
        data.cell
            .arm
            .command(&mut data.cell.world, &data.q, setpoint_qd);
        data.tick(model)?;
    }
    Ok(())
}

/// The solution nearest `q` (largest joint move smallest), if any.
fn nearest(solutions: &[JointVector], q: &JointVector) -> Option<JointVector> {
    let distance = |s: &JointVector| {
        s.iter()
            .zip(q)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    };
    solutions
        .iter()
        .min_by(|a, b| distance(a).total_cmp(&distance(b)))
        .copied()
}
