//! `twincell.ik(pose)` and `twincell.fk(q)`: the arm's closed-form inverse and forward
//! kinematics.

use std::path::PathBuf;

use nalgebra::Isometry3;
use numpy::PyArray2;
use numpy::ndarray::Array2;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use twincell::kinematics::{
    AnalyticIk, ArmModel, BUILTIN_URDF, IkSolver, UrdfArm, flange_pose, tcp_pose,
};

use crate::arrays::{bad_value, joints};
use crate::scenario_arg::{cell_model, overrides};

/// Which link a pose is of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Link {
    Flange,
    Tcp,
}

fn link_of(link: &str) -> PyResult<Link> {
    match link {
        "flange" => Ok(Link::Flange),
        "tcp" => Ok(Link::Tcp),
        other => Err(bad_value(
            "link",
            format!("{other:?} is not \"flange\" or \"tcp\""),
        )),
    }
}

/// The arm model of the scenario (the built-in AUBO i5 without one), with its tool at the
/// TCP (the gripper's `tcp_Link`) or at the flange.
fn arm_model(
    scenario: Option<PathBuf>,
    kwargs: Option<&Bound<'_, PyDict>>,
    link: Link,
) -> PyResult<ArmModel> {
    let model = match scenario {
        Some(path) => cell_model("scenario", &path, &overrides("overrides", kwargs)?)?
            .arm_model()
            .clone(),
        None => {
            if kwargs.is_some_and(|k| !k.is_empty()) {
                return Err(bad_value("overrides", "overrides need a scenario"));
            }
            UrdfArm::from_urdf_str(BUILTIN_URDF)
                .map_err(|e| bad_value("scenario", format!("the built-in URDF: {e}")))?
                .model
        }
    };
    Ok(match link {
        Link::Tcp => model,
        Link::Flange => model.with_tool(Isometry3::identity()),
    })
}

/// Every distinct closed-form solution within the joint limits for `pose` of `link` (`"flange"`,
/// the URDF's last arm link, or `"tcp"`, the gripper's tool centre point) in the arm's base
/// frame (the URDF's root link), as `twincell ik` gives them.
///
/// `pose` is `[x, y, z, roll, pitch, yaw]` (m, rad, R = Rz(yaw) Ry(pitch) Rx(roll)) or a 4 x 4
/// matrix. The arm is the scenario's (`scenario`: a TOML file, keyword arguments override its
/// keys as `--set` does), or the built-in AUBO i5. Returns an `n x 6` float array of joint
/// angles in the controller's convention, `n = 0` when the pose is out of reach.
#[pyfunction]
#[pyo3(signature = (pose, scenario = None, link = "flange", **overrides))]
pub fn ik<'py>(
    py: Python<'py>,
    pose: &Bound<'py, PyAny>,
    scenario: Option<PathBuf>,
    link: &str,
    overrides: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let link = link_of(link)?;
    let target = crate::arrays::pose("pose", pose)?;
    let model = arm_model(scenario, overrides, link)?;
    let solver = AnalyticIk::new(model).map_err(|e| bad_value("scenario", e))?;
    let solutions = solver.solve(&target);
    let flat: Vec<f64> = solutions.as_slice().iter().flatten().copied().collect();
    let array =
        Array2::from_shape_vec((solutions.len(), 6), flat).map_err(|e| bad_value("pose", e))?;
    Ok(PyArray2::from_owned_array(py, array))
}

/// The pose of `link` (`"flange"` or `"tcp"`) in the arm's base frame at joint angles `q`
/// (6 numbers, rad, controller convention), as a 4 x 4 matrix; the arm as for `ik`.
#[pyfunction]
#[pyo3(signature = (q, scenario = None, link = "flange", **overrides))]
pub fn fk<'py>(
    py: Python<'py>,
    q: &Bound<'py, PyAny>,
    scenario: Option<PathBuf>,
    link: &str,
    overrides: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let link = link_of(link)?;
    let q = joints("q", q)?;
    let model = arm_model(scenario, overrides, link)?;
    let pose = match link {
        Link::Flange => flange_pose(&model, &q),
        Link::Tcp => tcp_pose(&model, &q),
    };
    let m = pose.to_homogeneous();
    let array = Array2::from_shape_fn((4, 4), |(r, c)| m[(r, c)]);
    Ok(PyArray2::from_owned_array(py, array))
}
