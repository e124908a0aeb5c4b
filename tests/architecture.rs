//! The library's modules follow one tick of the cell, and each imports only the modules before
//! it: this test reads every `crate::` path in `src/` and fails on one that points later in the
//! order (which is also what rules out import cycles). It also keeps source files short.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The allowed order: a module may use itself and any module listed before it. Keep in step
/// with ARCHITECTURE.md and `src/lib.rs`.
const ORDER: [&str; 17] = [
    "math",
    "rng",
    "kinematics",
    "scenario",
    "outcome",
    "sim",
    "cell",
    "camera",
    "render",
    "detect",
    "perception",
    "planning",
    "control",
    "task",
    "batch",
    "record",
    "demo",
];

/// Longest source file, lines.
const MAX_LINES: usize = 600;

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        panic!("cannot read {}", dir.display());
    };
    let mut paths: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    paths.sort();
    for path in paths {
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The library module a file belongs to (`src/task/trial.rs` -> `task`), or `None` for the
/// binary's files (`main.rs`, `cli/`) and `lib.rs`.
fn module_of(path: &Path) -> Option<String> {
    let relative = path.strip_prefix(src()).ok()?;
    let first = relative.components().next()?.as_os_str().to_str()?;
    let name = first.strip_suffix(".rs").unwrap_or(first);
    (!matches!(name, "main" | "lib" | "cli")).then(|| name.to_string())
}

/// Every module named after `crate::` in the code (comments left out), with its line; a
/// `use crate::{a, b::C}` group, over several lines or not, names each of its top-level items.
fn crate_paths(text: &str) -> Vec<(usize, String)> {
    let code: String = text
        .lines()
        .map(|line| line.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n");
    let line_of = |offset: usize| code[..offset].matches('\n').count() + 1;
    let is_name = |c: char| c.is_ascii_alphanumeric() || c == '_';
    let mut found = Vec::new();
    for (at, _) in code.match_indices("crate::") {
        let after = &code[at + "crate::".len()..];
        let name: String = after.chars().take_while(|c| is_name(*c)).collect();
        if !name.is_empty() {
            found.push((line_of(at), name));
            continue;
        }
        if !after.starts_with('{') {
            continue;
        }
        // The group's top-level items: text at brace depth 1, split at commas.
        let (mut depth, mut item, mut item_at) = (0usize, String::new(), at);
        for (k, c) in after.char_indices() {
            match c {
                '{' => depth += 1,
                '}' | ',' if depth == 1 => {
                    let name: String = item.trim().chars().take_while(|c| is_name(*c)).collect();
                    if !name.is_empty() {
                        found.push((line_of(item_at), name));
                    }
                    item.clear();
                    if c == '}' {
                        break;
                    }
                    continue;
                }
                '}' => depth -= 1,
                _ => {}
            }
            if depth == 1 && c != '{' {
                if item.trim().is_empty() {
                    item_at = at + "crate::".len() + k;
                }
                item.push(c);
            }
        }
    }
    found
}

#[test]
fn every_module_imports_only_modules_before_it() {
    let rank: BTreeMap<&str, usize> = ORDER.iter().enumerate().map(|(i, m)| (*m, i)).collect();
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let mut violations = Vec::new();
    for file in &files {
        let Some(module) = module_of(file) else {
            continue;
        };
        let Some(&own) = rank.get(module.as_str()) else {
            violations.push(format!(
                "{}: module `{module}` is not in the allowed order",
                file.display()
            ));
            continue;
        };
        let Ok(text) = std::fs::read_to_string(file) else {
            panic!("cannot read {}", file.display());
        };
        for (line, used) in crate_paths(&text) {
            let Some(&other) = rank.get(used.as_str()) else {
                violations.push(format!(
                    "{}:{line}: `crate::{used}` is not a module in the allowed order",
                    file.display()
                ));
                continue;
            };
            if other > own {
                violations.push(format!(
                    "{}:{line}: `{module}` imports `{used}`, which comes after it",
                    file.display()
                ));
            }
        }
    }
    assert!(violations.is_empty(), "{}", violations.join("\n"));
}

#[test]
fn lib_declares_the_modules_in_the_allowed_order() {
    let Ok(lib) = std::fs::read_to_string(src().join("lib.rs")) else {
        panic!("cannot read src/lib.rs");
    };
    let declared: Vec<&str> = lib
        .lines()
        .filter_map(|l| l.trim().strip_prefix("pub mod "))
        .map(|l| l.trim_end_matches(';'))
        .collect();
    assert_eq!(
        declared, ORDER,
        "src/lib.rs declares its modules out of order"
    );
}

#[test]
fn the_checker_sees_imports_in_every_form() {
    let text = "use crate::sim::World;\nuse crate::{batch, render::{Scene, Shot}};\n// crate::task in a comment\nlet x = crate::detect::Detector::default_path();\nuse crate::{\n    planning::Percept,\n    control,\n};\n";
    let found = crate_paths(text);
    let names: Vec<&str> = found.iter().map(|(_, n)| n.as_str()).collect();
    assert_eq!(
        names,
        ["sim", "batch", "render", "detect", "planning", "control"]
    );
    let lines: Vec<usize> = found.iter().map(|(l, _)| *l).collect();
    assert_eq!(lines, [1, 2, 2, 4, 6, 7]);
}

#[test]
fn no_source_file_is_longer_than_the_limit() {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let long: Vec<String> = files
        .iter()
        .filter_map(|file| {
            let lines = std::fs::read_to_string(file).ok()?.lines().count();
            (lines > MAX_LINES).then(|| format!("{}: {lines} lines", file.display()))
        })
        .collect();
    assert!(
        long.is_empty(),
        "over {MAX_LINES} lines:\n{}",
        long.join("\n")
    );
}
