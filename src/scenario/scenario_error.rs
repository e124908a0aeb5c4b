//! The error a scenario file that cannot be used gives: its file, the key, dotted, and the
//! reason.

use std::path::{Path, PathBuf};

/// A scenario file that cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {key}: {reason}", file.display())]
pub struct ScenarioError {
    /// The scenario file.
    pub file: PathBuf,
    /// The offending key, dotted (`bins[2].size_m`).
    pub key: String,
    /// What is wrong.
    pub reason: String,
}

impl ScenarioError {
    /// Wraps a TOML parse error, naming the key at the error's location.
    pub(super) fn from_toml(file: &Path, text: &str, error: &toml::de::Error) -> Self {
        let key = error
            .span()
            .and_then(|span| text.get(span))
            .map(|s| s.trim().trim_matches('"').to_string())
            .unwrap_or_default();
        Self {
            file: file.to_path_buf(),
            key,
            reason: with_line(text, error),
        }
    }

    /// Wraps an error of reading the parsed document into a scenario, naming the key by its
    /// dotted path (`conveyor.tracking`, `bins[2].size_m`; an unknown key by the section that
    /// holds it and its own name); `text`, when the document is one file's, gives the line.
    pub(super) fn from_path_error(
        file: &Path,
        text: Option<&str>,
        error: &serde_path_to_error::Error<toml::de::Error>,
    ) -> Self {
        let inner = error.inner();
        let reason = match text {
            Some(text) => with_line(text, inner),
            None => inner.message().to_owned(),
        };
        Self {
            file: file.to_path_buf(),
            key: dotted_key(error),
            reason,
        }
    }
}

/// The key an error of reading a document names: its path, with the unknown field's own name
/// added when the reader names one.
pub(super) fn dotted_key(error: &serde_path_to_error::Error<toml::de::Error>) -> String {
    let path = error.path().to_string();
    let path = if path == "." { String::new() } else { path };
    let message = error.inner().message();
    let unknown = message
        .strip_prefix("unknown field `")
        .and_then(|rest| rest.split('`').next());
    match unknown {
        Some(name) if !path.ends_with(name) && path.is_empty() => name.to_owned(),
        Some(name) if !path.ends_with(name) => format!("{path}.{name}"),
        _ => path,
    }
}

/// A TOML error's message, with the line it points at when it has one.
fn with_line(text: &str, error: &toml::de::Error) -> String {
    match error
        .span()
        .map(|span| text[..span.start.min(text.len())].lines().count().max(1))
    {
        Some(line) => format!("{} (line {line})", error.message()),
        None => error.message().to_string(),
    }
}
