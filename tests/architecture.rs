//! The library's modules follow one tick of the cell, and each imports only the modules before
//! it: this test reads every `crate::` path in `src/` and fails on one that points later in the
//! order (which is also what rules out import cycles). It also keeps source files short.

use std::path::{Path, PathBuf};

/// The allowed order, and what each module may import: only modules listed before it (which
/// rules out import cycles), and of those only the ones named. Keep in step with
/// ARCHITECTURE.md and `src/lib.rs`.
const MODULES: [(&str, &[&str]); 19] = [
    ("math", &[]),
    ("rng", &[]),
    ("kinematics", &["math"]),
    ("scenario", &["math", "kinematics"]),
    ("outcome", &[]),
    ("sim", &["math", "rng", "kinematics", "scenario", "outcome"]),
    (
        "cell",
        &["math", "rng", "kinematics", "scenario", "outcome", "sim"],
    ),
    ("camera", &["math"]),
    (
        "render",
        &["math", "rng", "scenario", "sim", "cell", "camera"],
    ),
    ("detect", &["math"]),
    // Perception works on images and the camera's calibration alone, never on the world.
    ("perception", &["math", "rng", "camera"]),
    // The perception station reads images and calibrations through the stages before it.
    (
        "station",
        &[
            "math",
            "rng",
            "scenario",
            "camera",
            "render",
            "detect",
            "perception",
        ],
    ),
    (
        "planning",
        &[
            "math",
            "rng",
            "kinematics",
            "scenario",
            "outcome",
            "sim",
            "cell",
            "station",
        ],
    ),
    // Control draws a trial's faults from the scenario's `[faults]` and the trial's seed.
    (
        "control",
        &[
            "math",
            "rng",
            "kinematics",
            "scenario",
            "outcome",
            "sim",
            "planning",
        ],
    ),
    (
        "task",
        &[
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
            "station",
            "planning",
            "control",
        ],
    ),
    ("batch", &["math", "rng", "scenario", "outcome", "task"]),
    (
        "record",
        &["math", "scenario", "outcome", "sim", "render", "task"],
    ),
    (
        "demo",
        &["math", "rng", "kinematics", "sim", "planning", "control"],
    ),
    // The environment steps a trial's data for an outside controller and judges it as the
    // task does; its trials are seeded as a batch's.
    (
        "gym",
        &[
            "math",
            "rng",
            "kinematics",
            "scenario",
            "outcome",
            "sim",
            "cell",
            "camera",
            "render",
            "task",
            "batch",
        ],
    ),
];

/// Text a module must not contain, and why: the task watches contacts through `sim`'s queries.
const FORBIDDEN: [(&str, &str, &str); 2] = [
    (
        "task",
        "narrow_phase",
        "walks the engine's narrow phase; ask `sim::World` instead",
    ),
    (
        "task",
        "NarrowPhase",
        "names the engine's narrow phase; ask `sim::World` instead",
    ),
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

/// What is wrong with `text`, the source of `file` in `module`: imports the module may not make
/// and text it must not contain.
fn violations_in(module: &str, file: &str, text: &str) -> Vec<String> {
    let Some(own) = MODULES.iter().position(|(m, _)| *m == module) else {
        return vec![format!(
            "{file}: module `{module}` is not in the allowed order"
        )];
    };
    let allowed = MODULES[own].1;
    let mut violations = Vec::new();
    for (line, used) in crate_paths(text) {
        if used == module {
            continue;
        }
        match MODULES.iter().position(|(m, _)| *m == used) {
            None => violations.push(format!(
                "{file}:{line}: `crate::{used}` is not a module in the allowed order"
            )),
            Some(other) if other > own => violations.push(format!(
                "{file}:{line}: `{module}` imports `{used}`, which comes after it"
            )),
            Some(_) if !allowed.contains(&used.as_str()) => violations.push(format!(
                "{file}:{line}: `{module}` imports `{used}`, which is not on its list"
            )),
            Some(_) => {}
        }
    }
    let code: String = text
        .lines()
        .map(|line| line.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n");
    for (m, needle, why) in FORBIDDEN {
        if m == module && code.contains(needle) {
            violations.push(format!("{file}: `{module}` {why}"));
        }
    }
    violations
}

#[test]
fn every_module_imports_only_what_its_list_allows() {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let mut violations = Vec::new();
    for file in &files {
        let Some(module) = module_of(file) else {
            continue;
        };
        let Ok(text) = std::fs::read_to_string(file) else {
            panic!("cannot read {}", file.display());
        };
        violations.extend(violations_in(&module, &file.display().to_string(), &text));
    }
    assert!(violations.is_empty(), "{}", violations.join("\n"));
}

#[test]
fn each_list_names_only_modules_before_its_own() {
    for (own, (module, allowed)) in MODULES.iter().enumerate() {
        for used in *allowed {
            let other = MODULES.iter().position(|(m, _)| m == used);
            assert!(
                other.is_some_and(|o| o < own),
                "`{module}` lists `{used}`, which is not before it"
            );
        }
    }
}

#[test]
fn deliberate_violations_are_caught() {
    let perception_reads_the_world = "use crate::sim::World;\nuse crate::camera::Calibration;\n";
    let found = violations_in("perception", "perception/x.rs", perception_reads_the_world);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].contains("`perception` imports `sim`"), "{found:?}");
    for world in ["sim", "cell", "render"] {
        let text = format!("use crate::{{math, {world}::X}};");
        let found = violations_in("perception", "perception/x.rs", &text);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!(
            found[0].contains(&format!("imports `{world}`")),
            "{found:?}"
        );
    }
    let backwards = violations_in("sim", "sim/x.rs", "use crate::task::Trial;");
    assert!(
        backwards[0].contains("which comes after it"),
        "{backwards:?}"
    );
    let walk = "let pairs = world.physics.narrow_phase.contact_pairs_with(c);";
    let found = violations_in("task", "task/x.rs", walk);
    assert!(found[0].contains("narrow phase"), "{found:?}");
    assert!(violations_in("task", "task/x.rs", "// narrow_phase in a comment").is_empty());
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
        declared,
        MODULES.map(|(m, _)| m),
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
