//! `extends = "BASE.toml"`: a scenario file that says only what differs from its base.
//!
//! The base is read first (relative to the extending file's folder, and may itself extend
//! another), then the extending file is merged into it key by key: tables merge, and any other
//! value, an array of tables such as `part_types` or `bins` included, replaces the base's whole.
//! This is the same document that `--set` edits. Each key remembers the file that set it, so a
//! validation error names that file.

use std::path::{Path, PathBuf};

use super::ScenarioError;

/// The key that names a file's base.
pub const EXTENDS_KEY: &str = "extends";
/// Longest chain of bases followed before the chain counts as runaway.
const MAX_DEPTH: usize = 16;

/// A scenario's TOML document with its bases merged in, and which file set each key.
#[derive(Debug, Clone)]
pub(super) struct ScenarioDocument {
    /// The merged document, without `extends`.
    pub(super) table: toml::Table,
    /// Dotted key paths (arrays whole) and the file that last set each.
    provenance: Vec<(String, PathBuf)>,
    /// Every file read, the extending file first, with its text.
    pub(super) sources: Vec<(PathBuf, String)>,
}

impl ScenarioDocument {
    /// The document of the file at `path` whose text is `text`, its bases read from disk.
    pub(super) fn resolve(text: &str, path: &Path) -> Result<Self, ScenarioError> {
        let mut chain = vec![(path.to_path_buf(), text.to_owned(), parse(text, path)?)];
        loop {
            let (current, _, current_table) = &chain[chain.len() - 1];
            let Some(base) = base_of(current, current_table)? else {
                break;
            };
            if chain.iter().any(|(p, _, _)| same_file(p, &base)) {
                let names: Vec<String> = chain
                    .iter()
                    .map(|(p, _, _)| p.display().to_string())
                    .chain([base.display().to_string()])
                    .collect();
                return Err(error(
                    current,
                    EXTENDS_KEY,
                    format!("the bases form a cycle: {}", names.join(" -> ")),
                ));
            }
            if chain.len() > MAX_DEPTH {
                return Err(error(
                    current,
                    EXTENDS_KEY,
                    format!("more than {MAX_DEPTH} bases in a chain"),
                ));
            }
            let base_text = std::fs::read_to_string(&base).map_err(|e| {
                error(
                    current,
                    EXTENDS_KEY,
                    format!("cannot read {}: {e}", base.display()),
                )
            })?;
            let table = parse(&base_text, &base)?;
            chain.push((base, base_text, table));
        }
        let mut table = toml::Table::new();
        let mut provenance = Vec::new();
        for (file, _, mut layer) in chain.iter().cloned().rev() {
            layer.remove(EXTENDS_KEY);
            merge(&mut table, layer, "", &file, &mut provenance);
        }
        let sources = chain.into_iter().map(|(p, t, _)| (p, t)).collect();
        let mut document = Self {
            table,
            provenance,
            sources,
        };
        document.anchor_paths();
        Ok(document)
    }

    /// Paths in the document are relative to the file that wrote them: one that a base in
    /// another folder set is made absolute, so that it means the same from the extending file.
    fn anchor_paths(&mut self) {
        const PATH_KEYS: [(&str, &str); 1] = [("robot", "urdf")];
        for (section, key) in PATH_KEYS {
            let file = self.file_of(&format!("{section}.{key}")).to_path_buf();
            if file == self.sources[0].0 {
                continue;
            }
            let folder = file.parent().unwrap_or(Path::new("."));
            let Some(toml::Value::Table(table)) = self.table.get_mut(section) else {
                continue;
            };
            let Some(toml::Value::String(relative)) = table.get(key) else {
                continue;
            };
            let joined = folder.join(relative.as_str());
            let anchored = std::path::absolute(&joined).unwrap_or(joined);
            table.insert(
                key.to_owned(),
                toml::Value::String(anchored.display().to_string()),
            );
        }
    }

    /// Whether the file extends a base.
    pub(super) fn has_bases(&self) -> bool {
        self.sources.len() > 1
    }

    /// The file that set `key` (a dotted path as validation names it, e.g. `bins[2].size_m`;
    /// for a table, the file that set a key inside it last), or the extending file when none
    /// of the files did (a default).
    pub(super) fn file_of(&self, key: &str) -> &Path {
        let top = self.sources[0].0.as_path();
        let plain: Vec<&str> = key
            .split('.')
            .map(|segment| segment.split('[').next().unwrap_or(segment))
            .collect();
        (1..=plain.len())
            .rev()
            .find_map(|n| {
                let prefix = plain[..n].join(".");
                // A key that names a table was set by the file that set keys inside it.
                let inside = format!("{prefix}.");
                self.provenance
                    .iter()
                    .rev()
                    .find(|(k, _)| *k == prefix || k.starts_with(&inside))
                    .map(|(_, file)| file.as_path())
            })
            .unwrap_or(top)
    }

    /// `error` (which names the extending file) moved to the file that set its key.
    pub(super) fn blame(&self, mut error: ScenarioError) -> ScenarioError {
        if self.has_bases() {
            error.file = self.file_of(&error.key).to_path_buf();
        }
        error
    }

    /// The file that holds a key named `name` at any depth, the extending file first; for a
    /// parse error, which names only the last key of its path. `None` when no file does (an
    /// override set it).
    pub(super) fn file_holding(&self, name: &str) -> Option<&Path> {
        self.sources
            .iter()
            .find(|(_, text)| {
                text.parse::<toml::Table>()
                    .is_ok_and(|table| holds_key(&toml::Value::Table(table), name))
            })
            .map(|(p, _)| p.as_path())
    }

    /// The extending file.
    pub(super) fn top_file(&self) -> &Path {
        &self.sources[0].0
    }
}

fn holds_key(value: &toml::Value, name: &str) -> bool {
    match value {
        toml::Value::Table(table) => table.iter().any(|(k, v)| k == name || holds_key(v, name)),
        toml::Value::Array(items) => items.iter().any(|v| holds_key(v, name)),
        _ => false,
    }
}

fn error(file: &Path, key: &str, reason: String) -> ScenarioError {
    ScenarioError {
        file: file.to_path_buf(),
        key: key.to_owned(),
        reason,
    }
}

fn parse(text: &str, path: &Path) -> Result<toml::Table, ScenarioError> {
    text.parse::<toml::Table>()
        .map_err(|e| ScenarioError::from_toml(path, text, &e))
}

/// The base that the file at `path` names, resolved against its folder.
fn base_of(path: &Path, table: &toml::Table) -> Result<Option<PathBuf>, ScenarioError> {
    let Some(value) = table.get(EXTENDS_KEY) else {
        return Ok(None);
    };
    let Some(name) = value.as_str().filter(|s| !s.trim().is_empty()) else {
        return Err(error(
            path,
            EXTENDS_KEY,
            "must be the path of a base scenario file, as a string".into(),
        ));
    };
    let folder = path.parent().unwrap_or(Path::new("."));
    Ok(Some(folder.join(name)))
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}

/// Merges `layer` into `into`: tables key by key, anything else replaced; notes who set what.
fn merge(
    into: &mut toml::Table,
    layer: toml::Table,
    prefix: &str,
    file: &Path,
    provenance: &mut Vec<(String, PathBuf)>,
) {
    for (key, value) in layer {
        let path = if prefix.is_empty() {
            key.clone()
        } else {
            format!("{prefix}.{key}")
        };
        match (into.get_mut(&key), value) {
            (Some(toml::Value::Table(base)), toml::Value::Table(table)) => {
                merge(base, table, &path, file, provenance);
            }
            (_, toml::Value::Table(table)) => {
                let mut fresh = toml::Table::new();
                merge(&mut fresh, table, &path, file, provenance);
                into.insert(key, toml::Value::Table(fresh));
            }
            (_, value) => {
                provenance.push((path, file.to_path_buf()));
                into.insert(key, value);
            }
        }
    }
}
