//! Scenario overrides (`--set KEY=VALUE`): a value put into the scenario's TOML document by
//! its key path before the document is parsed and validated, so that an override is checked
//! exactly like the file.
//!
//! A key is a dotted path of TOML keys, e.g. `sensor.noise_sigma`. An element of an array of
//! tables is addressed by its index, `part_types[5].grip_force_n` or `bins[0].size_m`, or, when
//! its entries have a `name`, by that name: `part_types.axle_c44.grip_force_n`. Sections the
//! file leaves out are created (`sensor.noise_sigma` on a file without `[sensor]`). A value is
//! a TOML value (`0.02`, `[0.07, 0.08]`, `true`, `"text"`); text that is not one is taken as a
//! string.

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use super::extends::ScenarioDocument;
use super::{Scenario, ScenarioError};

/// One `KEY=VALUE` override.
#[derive(Debug, Clone, PartialEq)]
pub struct Override {
    /// The key path, as given.
    pub key: String,
    /// The value, as TOML.
    pub value: toml::Value,
}

/// Why an override's text could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{text:?}: {reason}")]
pub struct OverrideSyntaxError {
    /// The text given.
    pub text: String,
    /// What is wrong.
    pub reason: String,
}

fn syntax(text: &str, reason: impl Into<String>) -> OverrideSyntaxError {
    OverrideSyntaxError {
        text: text.to_owned(),
        reason: reason.into(),
    }
}

/// One segment of a key path: a key, optionally followed by an index (`bins[2]`).
#[derive(Debug, Clone, PartialEq, Eq)]
struct Segment<'a> {
    key: &'a str,
    index: Option<usize>,
}

fn segments(key: &str) -> Result<Vec<Segment<'_>>, String> {
    if key.trim().is_empty() {
        return Err("the key is empty".into());
    }
    key.split('.')
        .map(|part| {
            let (name, index) = match part.split_once('[') {
                Some((name, rest)) => {
                    let digits = rest
                        .strip_suffix(']')
                        .ok_or_else(|| format!("`{part}`: an index is written [N]"))?;
                    let index = digits
                        .parse::<usize>()
                        .map_err(|_| format!("`{part}`: index `{digits}` is not a number"))?;
                    (name, Some(index))
                }
                None => (part, None),
            };
            let valid = !name.is_empty()
                && name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
            if valid {
                Ok(Segment { key: name, index })
            } else {
                Err(format!(
                    "`{part}` is not a key (letters, digits, `_` and `-`)"
                ))
            }
        })
        .collect()
}

/// Reads the value part of an override: TOML when it parses as TOML, a string otherwise.
pub fn parse_value(text: &str) -> toml::Value {
    let text = text.trim();
    format!("v = {text}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut table| table.remove("v"))
        .unwrap_or_else(|| toml::Value::String(text.to_owned()))
}

/// Splits `V1,V2,...` at the commas outside brackets and quotes: `[0.07,0.08],[0.1,0.2]` is two
/// values.
pub fn split_values(text: &str) -> Vec<&str> {
    let mut values = Vec::new();
    let (mut depth, mut quote, mut start) = (0i32, None, 0);
    for (i, c) in text.char_indices() {
        match (quote, c) {
            (Some(q), c) if c == q => quote = None,
            (Some(_), _) => {}
            (None, '"' | '\'') => quote = Some(c),
            (None, '[' | '{') => depth += 1,
            (None, ']' | '}') => depth -= 1,
            (None, ',') if depth == 0 => {
                values.push(text[start..i].trim());
                start = i + 1;
            }
            _ => {}
        }
    }
    values.push(text[start..].trim());
    values
}

fn split_key(text: &str) -> Result<(&str, &str), OverrideSyntaxError> {
    let (key, value) = text
        .split_once('=')
        .ok_or_else(|| syntax(text, "expected KEY=VALUE"))?;
    let key = key.trim();
    segments(key).map_err(|reason| syntax(text, reason))?;
    if value.trim().is_empty() {
        return Err(syntax(text, "the value is empty"));
    }
    Ok((key, value))
}

impl FromStr for Override {
    type Err = OverrideSyntaxError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let (key, value) = split_key(text)?;
        Ok(Self {
            key: key.to_owned(),
            value: parse_value(value),
        })
    }
}

impl fmt::Display for Override {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}={}", self.key, self.value)
    }
}

/// One axis of a sweep: a key and the values it takes (`KEY=V1,V2,...`).
#[derive(Debug, Clone, PartialEq)]
pub struct SweepAxis {
    /// The key path.
    pub key: String,
    /// The values, in the order given.
    pub values: Vec<toml::Value>,
}

impl FromStr for SweepAxis {
    type Err = OverrideSyntaxError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let (key, values) = split_key(text)?;
        let values: Vec<&str> = split_values(values);
        if values.iter().any(|v| v.is_empty()) {
            return Err(syntax(text, "a value in the list is empty"));
        }
        Ok(Self {
            key: key.to_owned(),
            values: values.into_iter().map(parse_value).collect(),
        })
    }
}

/// Every combination of the axes' values, the last axis varying fastest.
pub fn sweep_grid(axes: &[SweepAxis]) -> Vec<Vec<Override>> {
    axes.iter().fold(vec![Vec::new()], |points, axis| {
        points
            .iter()
            .flat_map(|point| {
                axis.values.iter().map(move |value| {
                    let mut point = point.clone();
                    point.push(Override {
                        key: axis.key.clone(),
                        value: value.clone(),
                    });
                    point
                })
            })
            .collect()
    })
}

/// Puts `value` at `key` in `document`; the reason when the path cannot be followed.
fn set_path(document: &mut toml::Table, key: &str, value: toml::Value) -> Result<(), String> {
    let path = segments(key)?;
    let mut table = document;
    let mut walked = String::new();
    for (depth, segment) in path.iter().enumerate() {
        let last = depth + 1 == path.len();
        if !walked.is_empty() {
            walked.push('.');
        }
        walked.push_str(segment.key);
        if let Some(index) = segment.index {
            let entry = table
                .get_mut(segment.key)
                .ok_or_else(|| format!("`{walked}` is not in the file, so it has no [{index}]"))?;
            let toml::Value::Array(items) = entry else {
                return Err(format!("`{walked}` is not an array"));
            };
            let len = items.len();
            let item = items
                .get_mut(index)
                .ok_or_else(|| format!("`{walked}` has {len} entries, no [{index}]"))?;
            walked.push_str(&format!("[{index}]"));
            if last {
                *item = value;
                return Ok(());
            }
            let toml::Value::Table(inner) = item else {
                return Err(format!("`{walked}` is not a table"));
            };
            table = inner;
            continue;
        }
        if last {
            table.insert(segment.key.to_owned(), value);
            return Ok(());
        }
        let entry = table
            .entry(segment.key.to_owned())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        table = match entry {
            toml::Value::Table(inner) => inner,
            toml::Value::Array(items) => {
                // The next segment names an entry of an array of tables by its `name`.
                let Some(next) = path.get(depth + 1) else {
                    return Err(format!("`{walked}` is an array"));
                };
                let found = items.iter_mut().find_map(|item| match item {
                    toml::Value::Table(t)
                        if t.get("name").and_then(toml::Value::as_str) == Some(next.key) =>
                    {
                        Some(t)
                    }
                    _ => None,
                });
                let Some(found) = found else {
                    return Err(format!(
                        "`{walked}` has no entry named `{}` (or address it by index, `{walked}[N]`)",
                        next.key
                    ));
                };
                if next.index.is_some() || depth + 2 == path.len() {
                    return Err(format!(
                        "`{walked}.{}` is an entry; name one of its keys after it",
                        next.key
                    ));
                }
                return set_path(found, &rest_of(&path, depth + 2), value);
            }
            _ => return Err(format!("`{walked}` is not a table")),
        };
    }
    Ok(())
}

fn rest_of(path: &[Segment], from: usize) -> String {
    path[from..]
        .iter()
        .map(|s| match s.index {
            Some(i) => format!("{}[{i}]", s.key),
            None => s.key.to_owned(),
        })
        .collect::<Vec<_>>()
        .join(".")
}

/// `document` with `overrides` applied in order.
fn apply(
    document: &ScenarioDocument,
    overrides: &[Override],
    path: &Path,
) -> Result<toml::Table, ScenarioError> {
    let mut table = document.table.clone();
    for o in overrides {
        set_path(&mut table, &o.key, o.value.clone()).map_err(|reason| ScenarioError {
            file: path.to_path_buf(),
            key: o.key.clone(),
            reason: format!("--set {o}: {reason}"),
        })?;
    }
    Ok(table)
}

impl ScenarioDocument {
    /// The scenario in `table` (this document, edited or not), parsed but not yet validated; a
    /// parse error names the file that holds the key it names.
    pub(super) fn deserialize(&self, table: toml::Table) -> Result<Scenario, ScenarioError> {
        serde_path_to_error::deserialize(toml::Value::Table(table)).map_err(|e| {
            // The key's own name (its path's last part, without an index) finds the file,
            // among the extending one and its bases, that holds it.
            let key = super::scenario_error::dotted_key(&e);
            let leaf = key.rsplit('.').next().unwrap_or_default();
            let leaf = leaf.split('[').next().unwrap_or_default();
            let file = self.file_holding(leaf).unwrap_or_else(|| self.top_file());
            ScenarioError::from_path_error(file, None, &e)
        })
    }
}

impl Scenario {
    /// Reads a scenario file, applies `overrides` to its TOML document, then parses and
    /// validates the result.
    pub fn load_with(path: &Path, overrides: &[Override]) -> Result<Self, ScenarioError> {
        Self::from_toml_with(&super::read(path)?, path, overrides)
    }

    /// As [`Scenario::from_toml`], with `overrides` applied to the document first. The file's
    /// own errors come first; an error the overrides cause names the override's key (or the
    /// key validation names) and says which `--set` led to it.
    pub fn from_toml_with(
        text: &str,
        path: &Path,
        overrides: &[Override],
    ) -> Result<Self, ScenarioError> {
        let scenario = Self::from_toml(text, path)?;
        if overrides.is_empty() {
            return Ok(scenario);
        }
        let document = ScenarioDocument::resolve(text, path)?;
        let parse = |applied: toml::Table| -> Result<Self, ScenarioError> {
            let scenario = document.deserialize(applied)?;
            scenario.validate(path).map_err(|e| document.blame(e))?;
            Ok(scenario)
        };
        let error = match parse(apply(&document, overrides, path)?) {
            Ok(scenario) => return Ok(scenario),
            Err(error) => error,
        };
        // Blame the first override after which the document no longer loads (every prefix
        // applies, since the whole list did).
        let culprit = (1..overrides.len())
            .find(|&n| apply(&document, &overrides[..n], path).is_ok_and(|t| parse(t).is_err()))
            .unwrap_or(overrides.len());
        let error = apply(&document, &overrides[..culprit], path)
            .ok()
            .and_then(|t| parse(t).err())
            .unwrap_or(error);
        let o = &overrides[culprit - 1];
        let key = if error.key.is_empty() {
            o.key.clone()
        } else {
            error.key
        };
        Err(ScenarioError {
            file: path.to_path_buf(),
            key,
            reason: format!("{} (after --set {o})", error.reason),
        })
    }
}

#[cfg(test)]
#[path = "overrides_tests.rs"]
mod tests;
