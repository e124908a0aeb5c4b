//! A scenario argument: a TOML file, with `--set`-style overrides from keyword arguments.

use std::path::Path;

use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict};
use twincell::cell::CellModel;
use twincell::scenario::{Override, Scenario};

use crate::arrays::{bad_type, bad_value};

/// `key=value` overrides from a dict, values written as TOML (strings as they are).
pub fn overrides(arg: &str, dict: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<Override>> {
    let Some(dict) = dict else {
        return Ok(Vec::new());
    };
    let mut out = Vec::with_capacity(dict.len());
    for (key, value) in dict.iter() {
        let key: String = key.extract().map_err(|_| {
            bad_type(
                arg,
                format!("override keys are strings, got {}", key.get_type()),
            )
        })?;
        // TOML text of the value; a Python str goes in as a TOML string.
        let text = if value.is_instance_of::<PyBool>() {
            if value.is_truthy()? { "true" } else { "false" }.to_owned()
        } else if let Ok(s) = value.extract::<String>() {
            format!("{s:?}")
        } else {
            value.repr()?.to_string()
        };
        let parsed: Override = format!("{key}={text}")
            .parse()
            .map_err(|e| bad_value(arg, e))?;
        out.push(parsed);
    }
    Ok(out)
}

/// The scenario file at `path` with `overrides` applied, validated.
pub fn load_scenario(arg: &str, path: &Path, overrides: &[Override]) -> PyResult<Scenario> {
    Scenario::load_with(path, overrides).map_err(|e| bad_value(arg, e))
}

/// The cell model of the scenario file at `path` with `overrides`.
pub fn cell_model(arg: &str, path: &Path, overrides: &[Override]) -> PyResult<CellModel> {
    let scenario = load_scenario(arg, path, overrides)?;
    CellModel::new(scenario, path).map_err(|e| bad_value(arg, format!("{e}: {}", path.display())))
}
