//! `twincell._native.CellEnv`: the library's step-by-step environment (`twincell::gym`) for the
//! Gymnasium environment in `twincell/env.py`, which adds the spaces and the dict action.

use std::path::PathBuf;
use std::time::Instant;

use nalgebra::Isometry3;
use numpy::ndarray::{Array2, Array3};
use numpy::{PyArray1, PyArray2, PyArray3};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use twincell::gym::write_batch;
use twincell::gym::{Action, ArmTarget, CellEnv, EnvError, Observation, PHYSICS_STEPS_PER_CONTROL};
use twincell::outcome::{Perception, TrialRecord};

use crate::arrays::{bad_value, joints, pose};
use crate::scenario_arg::cell_model;

/// An `EnvError` as the Python exception for it: a refused action is the caller's `ValueError`
/// naming the action's key; the rest are the environment's state.
fn env_error(e: EnvError) -> PyErr {
    match e {
        EnvError::Action(a) => {
            let text = a.to_string();
            match text.split_once(": ") {
                Some((key, why)) => PyValueError::new_err(format!("action['{key}']: {why}")),
                None => PyValueError::new_err(format!("action: {text}")),
            }
        }
        EnvError::Cell(c) => {
            PyRuntimeError::new_err(format!("reset: the cell could not be built: {c}"))
        }
        other => PyRuntimeError::new_err(other.to_string()),
    }
}

/// A 4 x 4 homogeneous matrix of `pose`.
fn matrix<'py>(py: Python<'py>, pose: &Isometry3<f64>) -> Bound<'py, PyArray2<f64>> {
    let m = pose.to_homogeneous();
    PyArray2::from_owned_array(py, Array2::from_shape_fn((4, 4), |(r, c)| m[(r, c)]))
}

/// One action as the Python layer hands it over, already split into its keys.
struct ActionArgs<'a, 'py> {
    joints: Option<&'a Bound<'py, PyAny>>,
    tool_pose: Option<&'a Bound<'py, PyAny>>,
    jaw_width: f64,
    jaw_force: f64,
    belt: bool,
    frame: bool,
}

impl ActionArgs<'_, '_> {
    fn action(&self) -> PyResult<Action> {
        let arm = match (self.joints, self.tool_pose) {
            (Some(q), None) => ArmTarget::Joints(joints("action['joints']", q)?),
            (None, Some(p)) => ArmTarget::ToolPose(pose("action['tool_pose']", p)?),
            _ => {
                return Err(bad_value(
                    "action",
                    "give exactly one of 'joints' and 'tool_pose'",
                ));
            }
        };
        Ok(Action {
            arm,
            jaw_width_m: self.jaw_width,
            jaw_force_n: self.jaw_force,
            belt_run: self.belt,
            take_frame: self.frame,
        })
    }
}

/// An action as `replay` takes it: `(joints, tool_pose, jaw_width, jaw_force, belt, frame)`.
type ActionTuple<'py> = (
    Option<Bound<'py, PyAny>>,
    Option<Bound<'py, PyAny>>,
    f64,
    f64,
    bool,
    bool,
);

/// The cell of one scenario, stepped one control period at a time.
#[pyclass(unsendable, module = "twincell._native", name = "CellEnv")]
pub struct PyCellEnv {
    env: Option<CellEnv>,
}

impl PyCellEnv {
    fn env(&mut self) -> PyResult<&mut CellEnv> {
        self.env.as_mut().ok_or_else(|| {
            PyRuntimeError::new_err(
                "env: the environment is closed; make a new one with twincell.make_env",
            )
        })
    }

    fn env_ref(&self) -> PyResult<&CellEnv> {
        self.env.as_ref().ok_or_else(|| {
            PyRuntimeError::new_err(
                "env: the environment is closed; make a new one with twincell.make_env",
            )
        })
    }
}

/// The observation as a dict of numpy arrays (the frame, when there is one, H x W x 3 uint8).
fn observation<'py>(py: Python<'py>, obs: Observation) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item(
        "joint_positions",
        PyArray1::from_slice(py, &obs.joint_positions_rad),
    )?;
    out.set_item(
        "joint_velocities",
        PyArray1::from_slice(py, &obs.joint_velocities_rad_s),
    )?;
    out.set_item("jaw_width", PyArray1::from_slice(py, &[obs.jaw_width_m]))?;
    out.set_item("jaw_force", PyArray1::from_slice(py, &obs.jaw_force_n))?;
    out.set_item("photo_eye", i64::from(obs.photo_eye))?;
    out.set_item(
        "belt_position",
        PyArray1::from_slice(py, &[obs.belt_position_m]),
    )?;
    out.set_item(
        "belt_speed",
        PyArray1::from_slice(py, &[obs.belt_speed_m_s]),
    )?;
    out.set_item("sim_time", PyArray1::from_slice(py, &[obs.sim_time_s]))?;
    if let Some(image) = obs.frame {
        let (w, h) = image.dimensions();
        let array = Array3::from_shape_vec((h as usize, w as usize, 3), image.into_raw())
            .map_err(|e| PyRuntimeError::new_err(format!("frame: {e}")))?;
        out.set_item("frame", PyArray3::from_owned_array(py, array))?;
    }
    if let Some(truth) = obs.truth {
        let t = PyDict::new(py);
        t.set_item("part_type", truth.part_type as i64)?;
        t.set_item("part_pose", matrix(py, &truth.world_from_part))?;
        t.set_item(
            "roundness_mm",
            PyArray1::from_slice(py, &[truth.roundness_mm]),
        )?;
        t.set_item(
            "bore_diameter_mm",
            PyArray1::from_slice(py, &[truth.bore_diameter_mm]),
        )?;
        t.set_item("correct_bin", truth.correct_bin.map(|b| b as i64))?;
        let poses: Vec<Bound<'py, PyArray2<f64>>> = truth
            .world_from_bottles
            .iter()
            .map(|p| matrix(py, p))
            .collect();
        t.set_item("bottle_poses", poses)?;
        out.set_item("truth", t)?;
    }
    Ok(out)
}

#[pymethods]
impl PyCellEnv {
    /// The environment of the scenario file `scenario` with `--set`-style `overrides`, in
    /// `perception` mode (`"camera"` or `"oracle"`).
    #[new]
    #[pyo3(signature = (scenario, perception = "camera", overrides = None))]
    fn new(
        scenario: PathBuf,
        perception: &str,
        overrides: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let perception = match perception {
            "camera" => Perception::Camera,
            "oracle" => Perception::Oracle,
            other => {
                return Err(bad_value(
                    "perception",
                    format!("{other:?} is not \"camera\" or \"oracle\""),
                ));
            }
        };
        let overrides = crate::scenario_arg::overrides("overrides", overrides)?;
        // The file's own errors name the scenario; those its overrides cause, the overrides.
        let model = if overrides.is_empty() {
            cell_model("scenario", &scenario, &[])?
        } else {
            crate::scenario_arg::load_scenario("scenario", &scenario, &[])?;
            cell_model("overrides", &scenario, &overrides)?
        };
        let env = CellEnv::new(model, perception).map_err(|e| match e {
            EnvError::Stream(_) => bad_value("scenario", format!("{e}: {}", scenario.display())),
            other => PyRuntimeError::new_err(other.to_string()),
        })?;
        Ok(Self { env: Some(env) })
    }

    /// Starts trial `trial` of the scenario seeded `seed` (the last one when `None`); returns
    /// the first observation.
    #[pyo3(signature = (trial, seed = None))]
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        trial: u32,
        seed: Option<u64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let obs = self.env()?.reset(trial, seed).map_err(env_error)?;
        observation(py, obs)
    }

    /// One control period; returns `(observation, record_json or None, ik_unreachable,
    /// timed_out)`.
    #[pyo3(signature = (joints, tool_pose, jaw_width, jaw_force, belt, frame))]
    #[allow(clippy::too_many_arguments)]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        joints: Option<&Bound<'py, PyAny>>,
        tool_pose: Option<&Bound<'py, PyAny>>,
        jaw_width: f64,
        jaw_force: f64,
        belt: bool,
        frame: bool,
    ) -> PyResult<(Bound<'py, PyDict>, Option<String>, bool, bool)> {
        let env = self.env()?;
        let args = ActionArgs {
            joints,
            tool_pose,
            jaw_width,
            jaw_force,
            belt,
            frame,
        };
        let action = args.action()?;
        let result = env.step(&action).map_err(env_error)?;
        let record = result.record.as_ref().map(record_json).transpose()?;
        Ok((
            observation(py, result.observation)?,
            record,
            result.ik_unreachable,
            result.timed_out,
        ))
    }

    /// Ends the episode now and judges the trial as it stands; the record as JSON (`None`
    /// before any reset).
    fn finish(&mut self) -> PyResult<Option<String>> {
        self.env()?.finish().as_ref().map(record_json).transpose()
    }

    /// Steps the trial with `actions` (tuples as `step` takes them) natively, without building
    /// observations for Python; returns the seconds it took (for the steps-per-second bench).
    fn replay(&mut self, actions: Vec<Bound<'_, PyAny>>) -> PyResult<f64> {
        let mut parsed = Vec::with_capacity(actions.len());
        for a in &actions {
            let (joints, tool_pose, jaw_width, jaw_force, belt, frame): ActionTuple<'_> =
                a.extract()?;
            let args = ActionArgs {
                joints: joints.as_ref(),
                tool_pose: tool_pose.as_ref(),
                jaw_width,
                jaw_force,
                belt,
                frame,
            };
            parsed.push(args.action()?);
        }
        let env = self.env()?;
        let started = Instant::now();
        for action in &parsed {
            let result = env.step(action).map_err(env_error)?;
            if result.record.is_some() {
                break;
            }
        }
        Ok(started.elapsed().as_secs_f64())
    }

    /// Writes `records` (`trials.jsonl` lines of this scenario's trials) into `out` with the
    /// batch's `report.json`, `junit.xml` and `report.html`; returns the report as JSON.
    fn write_batch(&self, records: Vec<String>, out: PathBuf) -> PyResult<String> {
        let env = self.env_ref()?;
        let mut parsed = Vec::with_capacity(records.len());
        for (i, line) in records.iter().enumerate() {
            let record: TrialRecord = serde_json::from_str(line)
                .map_err(|e| bad_value("records", format!("record {i}: {e}")))?;
            parsed.push(record);
        }
        let scenario = env.model().scenario();
        let report = write_batch(
            scenario,
            env.scenario_seed(),
            env.perception(),
            &parsed,
            &out,
        )
        .map_err(|e| bad_value("out", e))?;
        serde_json::to_string(&report).map_err(|e| PyRuntimeError::new_err(format!("report: {e}")))
    }

    /// Closes the environment; every later call raises.
    fn close(&mut self) {
        self.env = None;
    }

    /// Whether `close` was called.
    #[getter]
    fn closed(&self) -> bool {
        self.env.is_none()
    }

    /// One control period, s.
    #[getter]
    fn control_period_s(&self) -> PyResult<f64> {
        Ok(self.env_ref()?.control_period_s())
    }

    /// Physics steps in one control period.
    #[getter]
    fn physics_steps_per_control(&self) -> usize {
        PHYSICS_STEPS_PER_CONTROL
    }

    /// The scenario seed trials are drawn from now.
    #[getter]
    fn scenario_seed(&self) -> PyResult<u64> {
        Ok(self.env_ref()?.scenario_seed())
    }

    /// The scenario as loaded (overrides applied), as JSON.
    #[getter]
    fn scenario_json(&self) -> PyResult<String> {
        serde_json::to_string(self.env_ref()?.model().scenario())
            .map_err(|e| PyRuntimeError::new_err(format!("scenario: {e}")))
    }

    /// The camera's calibration as `twincell render` writes it: `width_px`, `height_px`,
    /// `fx_px`, `fy_px`, `cx_px`, `cy_px`, `world_from_camera` (4 x 4).
    #[getter]
    fn calibration<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.env_ref()?.calibration();
        let out = PyDict::new(py);
        out.set_item("width_px", c.width_px)?;
        out.set_item("height_px", c.height_px)?;
        out.set_item("fx_px", c.fx_px)?;
        out.set_item("fy_px", c.fy_px)?;
        out.set_item("cx_px", c.cx_px)?;
        out.set_item("cy_px", c.cy_px)?;
        let m = c.world_from_camera;
        let array = Array2::from_shape_fn((4, 4), |(r, col)| m[r][col]);
        out.set_item("world_from_camera", PyArray2::from_owned_array(py, array))?;
        Ok(out)
    }

    /// Top of the belt, world z, m.
    #[getter]
    fn belt_top_z_m(&self) -> PyResult<Option<f64>> {
        Ok(self.env_ref()?.belt_top_z_m())
    }

    /// The pose of the arm's base (URDF `base_link`) in the world, 4 x 4, once reset: what
    /// `twincell.ik(..., link="tcp")` solves from.
    #[getter]
    fn world_from_base<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        Ok(self.env_ref()?.world_from_base().map(|p| matrix(py, &p)))
    }

    /// Each joint's `[min, max]` position limit, rad (6 x 2).
    #[getter]
    fn joint_limits<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let limits = &self.env_ref()?.model().arm_model().limits;
        let array = Array2::from_shape_fn((6, 2), |(j, k)| {
            if k == 0 {
                limits[j].min_rad
            } else {
                limits[j].max_rad
            }
        });
        Ok(PyArray2::from_owned_array(py, array))
    }
}

/// A trial record as one line of `trials.jsonl`.
fn record_json(record: &TrialRecord) -> PyResult<String> {
    serde_json::to_string(record).map_err(|e| PyRuntimeError::new_err(format!("record: {e}")))
}
