//! `twincell.plan_pick(percept, scenario)`: the twin's grasp search on a percept the caller
//! gives, in the scenario's cell.

use std::path::PathBuf;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};
use numpy::PyArray2;
use numpy::ndarray::Array2;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use twincell::cell::{Cell, CellModel};
use twincell::kinematics::JointVector;
use twincell::planning::{JointTrajectory, PickPlanner};
use twincell::rng::SimRng;
use twincell::scenario::{Catalogue, PartTypeId};
use twincell::station::{PerceivedObstacle, Percept, bottle_obstacle, part_obstacle};

use crate::arrays::{bad_type, bad_value, floats, joints};
use crate::scenario_arg::cell_model;

/// Sample spacing of the trajectories handed back, s.
const SAMPLE_PERIOD_S: f64 = 0.01;

/// A required item of a dict argument.
fn item<'py>(arg: &str, dict: &Bound<'py, PyDict>, key: &str) -> PyResult<Bound<'py, PyAny>> {
    dict.get_item(key)?
        .ok_or_else(|| bad_value(arg, format!("missing key {key:?}")))
}

/// Two finite numbers.
fn xy(arg: &str, value: &Bound<'_, PyAny>) -> PyResult<[f64; 2]> {
    let v = floats(arg, value)?;
    <[f64; 2]>::try_from(v.as_slice())
        .map_err(|_| bad_value(arg, format!("expected [x, y], got {} numbers", v.len())))
}

/// The part type named `value` in the catalogue.
fn part_type(arg: &str, catalogue: &Catalogue, value: &Bound<'_, PyAny>) -> PyResult<PartTypeId> {
    let name: String = value.extract().map_err(|_| {
        bad_type(
            arg,
            format!("expected a part type name, got {}", value.get_type()),
        )
    })?;
    catalogue
        .parts()
        .find(|(_, kind)| kind.name == name)
        .map(|(id, _)| id)
        .ok_or_else(|| {
            let known: Vec<&str> = catalogue.parts().map(|(_, k)| k.name.as_str()).collect();
            bad_value(
                arg,
                format!(
                    "{name:?} is not a part type of the scenario ({})",
                    known.join(", ")
                ),
            )
        })
}

/// One obstacle of the percept dict: a bottle (`xy` standing on the belt, turned by `yaw`, or
/// `world_from_bottle` as a 4 x 4 matrix; `lying`) or another part (`part_type`, `xy`).
fn obstacle(
    arg: &str,
    value: &Bound<'_, PyAny>,
    model: &CellModel,
    belt_top_z: f64,
) -> PyResult<PerceivedObstacle> {
    let Ok(dict) = value.cast::<PyDict>() else {
        return Err(bad_type(
            arg,
            format!("expected a dict, got {}", value.get_type()),
        ));
    };
    let kind: String = item(arg, dict, "kind")?.extract().map_err(|_| {
        bad_type(
            &format!("{arg}[\"kind\"]"),
            "expected \"bottle\" or \"part\"",
        )
    })?;
    match kind.as_str() {
        "bottle" => {
            let lying = match dict.get_item("lying")? {
                Some(v) => v.is_truthy()?,
                None => false,
            };
            let pose = match dict.get_item("world_from_bottle")? {
                Some(m) => crate::arrays::pose(&format!("{arg}[\"world_from_bottle\"]"), &m)?,
                None => {
                    let [x, y] = xy(&format!("{arg}[\"xy\"]"), &item(arg, dict, "xy")?)?;
                    let yaw = match dict.get_item("yaw")? {
                        Some(v) => floats(&format!("{arg}[\"yaw\"]"), &v)?
                            .first()
                            .copied()
                            .unwrap_or(0.0),
                        None => 0.0,
                    };
                    Isometry3::from_parts(
                        Translation3::new(x, y, belt_top_z),
                        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
                    )
                }
            };
            Ok(bottle_obstacle(&model.scenario().bottle, &pose, lying, 0.0))
        }
        "part" => {
            let id = part_type(
                &format!("{arg}[\"part_type\"]"),
                model.catalogue(),
                &item(arg, dict, "part_type")?,
            )?;
            let kind = model.catalogue().part(id);
            let [x, y] = xy(&format!("{arg}[\"xy\"]"), &item(arg, dict, "xy")?)?;
            Ok(part_obstacle(
                &Point3::new(x, y, belt_top_z + kind.height_m / 2.0),
                kind.outer_radius_m(),
                kind.height_m,
            ))
        }
        other => Err(bad_value(
            &format!("{arg}[\"kind\"]"),
            format!("{other:?} is not \"bottle\" or \"part\""),
        )),
    }
}

/// The planner's percept from the caller's dict.
fn percept_of(value: &Bound<'_, PyAny>, model: &CellModel, belt_top_z: f64) -> PyResult<Percept> {
    let Ok(dict) = value.cast::<PyDict>() else {
        return Err(bad_type(
            "percept",
            format!("expected a dict, got {}", value.get_type()),
        ));
    };
    for key in dict.keys() {
        let name: String = key.extract().unwrap_or_else(|_| key.to_string());
        if !["part_type", "part_xy", "obstacles"].contains(&name.as_str()) {
            return Err(bad_value(
                "percept",
                format!("unknown key {name:?} (known: part_type, part_xy, obstacles)"),
            ));
        }
    }
    let id = part_type(
        "percept[\"part_type\"]",
        model.catalogue(),
        &item("percept", dict, "part_type")?,
    )?;
    let kind = model.catalogue().part(id);
    let part_xy = xy("percept[\"part_xy\"]", &item("percept", dict, "part_xy")?)?;
    let mut obstacles = Vec::new();
    if let Some(list) = dict.get_item("obstacles")? {
        let Ok(list) = list.cast::<PyList>() else {
            return Err(bad_type(
                "percept[\"obstacles\"]",
                "expected a list of dicts",
            ));
        };
        for (i, entry) in list.iter().enumerate() {
            obstacles.push(obstacle(
                &format!("percept[\"obstacles\"][{i}]"),
                &entry,
                model,
                belt_top_z,
            )?);
        }
    }
    Ok(Percept {
        part_type: id,
        part_xy,
        part_outer_radius_m: kind.outer_radius_m(),
        part_height_m: kind.height_m,
        roundness_mm: None,
        bore_diameter_mm: None,
        inconsistency: None,
        unidentified: None,
        obstacles,
    })
}

/// `(t, q)` samples of `trajectory` every [`SAMPLE_PERIOD_S`] and at its end.
fn samples<'py>(py: Python<'py>, trajectory: &JointTrajectory) -> PyResult<Bound<'py, PyDict>> {
    let duration = trajectory.duration_s();
    let count = (duration / SAMPLE_PERIOD_S).floor() as usize + 1;
    let mut times: Vec<f64> = (0..count).map(|i| i as f64 * SAMPLE_PERIOD_S).collect();
    if times.last().is_some_and(|&t| t < duration) {
        times.push(duration);
    }
    let rows: Vec<JointVector> = times
        .iter()
        .filter_map(|&t| trajectory.sample(t).map(|s| s.q))
        .collect();
    let q = Array2::from_shape_fn((rows.len(), 6), |(r, c)| rows[r][c]);
    let out = PyDict::new(py);
    out.set_item("t_s", times)?;
    out.set_item("q", PyArray2::from_owned_array(py, q))?;
    Ok(out)
}

/// Searches a collision-free pick of the part `percept` describes, in the scenario's cell,
/// with the twin's own planner (the one `twincell run` uses).
///
/// `percept` is a dict: `part_type` (a name from the scenario's `part_types`), `part_xy` (its
/// centre on the belt, world frame, m) and optionally `obstacles`, a list of dicts, each a
/// bottle (`{"kind": "bottle", "xy": [x, y], "yaw": rad, "lying": bool}` standing on the belt,
/// or with `world_from_bottle`, a 4 x 4 matrix, instead of `xy` and `yaw`) or another part
/// (`{"kind": "part", "part_type": name, "xy": [x, y]}`). `q_now` is where the arm starts
/// (default: the scenario's home); keyword arguments override scenario keys as `--set` does.
///
/// Returns `{"success": True, "approach": {"t_s": [...], "q": n x 6}, "pregrasp": q,
/// "lift_path": m x 6, "lift_end": q}`, or `{"success": False, "reason": R, "detail": D}` with
/// the reason as reports count it (`unreachable`, `collision`) when no pick is found.
#[pyfunction]
#[pyo3(signature = (percept, scenario, q_now = None, **overrides))]
pub fn plan_pick<'py>(
    py: Python<'py>,
    percept: &Bound<'py, PyAny>,
    scenario: PathBuf,
    q_now: Option<&Bound<'py, PyAny>>,
    overrides: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let model = cell_model(
        "scenario",
        &scenario,
        &crate::scenario_arg::overrides("overrides", overrides)?,
    )?;
    // The planner reads only the fixed cell (scenery, robot shapes), not the drawn items.
    let cell = Cell::build(&model, &mut SimRng::new(model.scenario().seed))
        .map_err(|e| bad_value("scenario", format!("{e}: {}", scenario.display())))?;
    let percept = percept_of(percept, &model, cell.belt_top_z)?;
    let q_now = match q_now {
        Some(q) if !q.is_none() => joints("q_now", q)?,
        _ => model.scenario().robot.home_q_rad,
    };
    if let Err(e) = model.arm_model().check_limits(&q_now) {
        return Err(bad_value("q_now", e));
    }
    let planner = PickPlanner::for_cell(&model, &cell);
    let planned = py.detach(|| {
        let checker = planner.checker_for(&percept);
        planner.plan_pick(&percept, &checker, &q_now)
    });
    let out = PyDict::new(py);
    match planned {
        Ok(plan) => {
            out.set_item("success", true)?;
            out.set_item("approach", samples(py, &plan.approach)?)?;
            out.set_item("pregrasp", plan.pregrasp.to_vec())?;
            let lift =
                Array2::from_shape_fn((plan.lift_path.len(), 6), |(r, c)| plan.lift_path[r][c]);
            out.set_item("lift_path", PyArray2::from_owned_array(py, lift))?;
            out.set_item("lift_end", plan.lift_end.to_vec())?;
        }
        Err(failure) => {
            out.set_item("success", false)?;
            out.set_item("reason", failure.reason.as_str())?;
            out.set_item("detail", failure.detail)?;
        }
    }
    Ok(out)
}
