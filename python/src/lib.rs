//! The Python module `twincell._native`: the twin's stages as functions over numpy arrays and
//! plain Python values. The package `twincell` (python/twincell/) re-exports them.
//!
//! Every argument is checked before it reaches the library, and each failure becomes a Python
//! exception (`ValueError` for a wrong value, `TypeError` for a wrong type) whose message starts
//! with the argument's name; nothing here panics on a caller's input.

mod arrays;
mod detect;
mod env;
mod kinematics;
mod measure;
mod plan;
mod scenario_arg;

use pyo3::prelude::*;

/// The compiled part of the twincell package.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(detect::detect, m)?)?;
    m.add_function(wrap_pyfunction!(measure::measure, m)?)?;
    m.add_function(wrap_pyfunction!(kinematics::ik, m)?)?;
    m.add_function(wrap_pyfunction!(kinematics::fk, m)?)?;
    m.add_function(wrap_pyfunction!(plan::plan_pick, m)?)?;
    m.add_class::<env::PyCellEnv>()?;
    Ok(())
}
