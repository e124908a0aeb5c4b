//! `extends = "BASE.toml"`: a scenario file that says only what differs from its base.

use std::path::{Path, PathBuf};

use twincell::scenario::{Override, Scenario};

mod common;

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).expect("folder");
    }
    std::fs::write(&path, text).expect("writes");
    path
}

fn paper_text() -> String {
    common::read(&common::scenario_path("paper_50.toml"))
}

#[test]
fn an_extending_file_is_its_base_with_its_own_keys_merged_in() {
    let dir = common::out_dir("scenario_extends", "merge");
    write(&dir, "base/paper.toml", &paper_text());
    let child = write(
        &dir,
        "suite/fast.toml",
        "extends = \"../base/paper.toml\"\nname = \"fast\"\n\n[conveyor]\nspeed_m_s = 0.4\n\n\
         [bottle]\nenabled = true\n",
    );
    let merged = Scenario::load(&child).expect("loads");
    // The same scenario written out whole.
    let whole_text = paper_text()
        .replace("name = \"paper_50\"", "name = \"fast\"")
        .replace("speed_m_s = 0.25", "speed_m_s = 0.4");
    let whole = Scenario::from_toml(&whole_text, Path::new("whole.toml")).expect("loads");
    assert_eq!(merged, whole);
    // Other conveyor keys come from the base: tables merge key by key.
    assert_eq!(merged.conveyor.length_m, 1.6);
}

#[test]
fn arrays_of_tables_replace_the_base_whole_and_bases_chain() {
    let dir = common::out_dir("scenario_extends", "chain");
    write(&dir, "paper.toml", &paper_text());
    write(
        &dir,
        "middle.toml",
        "extends = \"paper.toml\"\nname = \"middle\"\ntrials = 3\n",
    );
    let catalogue: String = paper_text()
        .split("[[part_types]]")
        .skip(1)
        .map(|chunk| format!("[[part_types]]{chunk}"))
        .collect::<String>()
        .replace("[[bins]]", "\n[[bins]]");
    let child = write(
        &dir,
        "top.toml",
        &format!("extends = \"middle.toml\"\nname = \"top\"\n\n{catalogue}"),
    );
    let top = Scenario::load(&child).expect("loads");
    assert_eq!(top.name, "top");
    assert_eq!(top.trials, 3, "from the middle file");
    assert_eq!(top.part_types.len(), 6);
    assert_eq!(top.bins.len(), 4);
    let sources = Scenario::source_files(&child).expect("sources");
    let names: Vec<String> = sources
        .iter()
        .map(|(p, _)| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["top.toml", "middle.toml", "paper.toml"]);
}

#[test]
fn errors_name_the_file_that_set_the_key() {
    let dir = common::out_dir("scenario_extends", "errors");
    let bad_base = paper_text().replace("width_m = 0.32", "width_m = -0.32");
    write(&dir, "bad_base.toml", &bad_base);
    let child = write(
        &dir,
        "child.toml",
        "extends = \"bad_base.toml\"\nname = \"child\"\n",
    );
    let error = Scenario::load(&child).expect_err("the base's belt width is negative");
    assert!(error.file.ends_with("bad_base.toml"), "{error}");
    assert_eq!(error.key, "conveyor.width_m");

    write(&dir, "paper.toml", &paper_text());
    let own = write(
        &dir,
        "own.toml",
        "extends = \"paper.toml\"\nname = \"own\"\n[conveyor]\nspeed_m_s = -1.0\n",
    );
    let error = Scenario::load(&own).expect_err("its own belt speed is negative");
    assert!(error.file.ends_with("own.toml"), "{error}");
    assert_eq!(error.key, "conveyor.speed_m_s");

    let unknown = write(
        &dir,
        "unknown.toml",
        "extends = \"paper.toml\"\n[conveyor]\nspeeed_m_s = 1.0\n",
    );
    let error = Scenario::load(&unknown).expect_err("an unknown key");
    assert!(error.file.ends_with("unknown.toml"), "{error}");
    assert!(error.reason.contains("speeed_m_s"), "{error}");
    assert_eq!(error.key, "conveyor.speeed_m_s");

    // A value of the wrong type is named by its whole path, in an extending file, in a plain
    // one (with its line), and inside an array of tables.
    let typed = write(
        &dir,
        "typed.toml",
        "extends = \"paper.toml\"\n[conveyor]\ntracking = \"yes\"\n",
    );
    let error = Scenario::load(&typed).expect_err("a string for a boolean");
    assert!(error.file.ends_with("typed.toml"), "{error}");
    assert_eq!(error.key, "conveyor.tracking");
    assert!(error.reason.contains("invalid type"), "{error}");
    let plain = paper_text().replace("speed_m_s = 0.25", "speed_m_s = \"fast\"");
    let error = Scenario::from_toml(&plain, Path::new("plain.toml")).expect_err("a string");
    assert_eq!(error.key, "conveyor.speed_m_s");
    assert!(error.reason.contains("(line "), "{error}");
    let unknown_plain = paper_text().replace("[conveyor]", "[conveyor]\nspeeed_m_s = 1.0");
    let error = Scenario::from_toml(&unknown_plain, Path::new("plain.toml")).expect_err("unknown");
    assert_eq!(error.key, "conveyor.speeed_m_s");
    let in_array = paper_text().replacen("accepts = [", "accepts = 3\nx = [", 1);
    let error = Scenario::from_toml(&in_array, Path::new("plain.toml")).expect_err("not a list");
    assert!(error.key.starts_with("bins[0]."), "{error}");

    let missing = write(&dir, "missing.toml", "extends = \"nowhere.toml\"\n");
    let error = Scenario::load(&missing).expect_err("no such base");
    assert!(error.file.ends_with("missing.toml"), "{error}");
    assert_eq!(error.key, "extends");
    assert!(error.reason.contains("nowhere.toml"), "{error}");

    write(&dir, "a.toml", "extends = \"b.toml\"\n");
    let b = write(&dir, "b.toml", "extends = \"a.toml\"\n");
    let error = Scenario::load(&b).expect_err("a cycle");
    assert!(error.reason.contains("cycle"), "{error}");

    let number = write(&dir, "number.toml", "extends = 3\n");
    let error = Scenario::load(&number).expect_err("not a path");
    assert_eq!(error.key, "extends");
}

#[test]
fn a_key_may_repeat_its_base_and_overrides_apply_to_the_merged_document() {
    let dir = common::out_dir("scenario_extends", "overrides");
    write(&dir, "paper.toml", &paper_text());
    let child = write(
        &dir,
        "same.toml",
        "extends = \"paper.toml\"\nseed = 731\n[conveyor]\nspeed_m_s = 0.25\n",
    );
    let same = Scenario::load(&child).expect("a key equal to its base's");
    assert_eq!(same, common::paper_50());
    let set: Override = "part_types.axle_c44.grip_force_n=80"
        .parse()
        .expect("override");
    let overridden = Scenario::load_with(&child, &[set]).expect("override applies");
    assert_eq!(overridden.part_types[5].grip_force_n, Some(80.0));
    let bad: Override = "conveyor.width_m=-1".parse().expect("override");
    let error = Scenario::load_with(&child, &[bad]).expect_err("negative width");
    assert!(error.reason.contains("--set"), "{error}");
}

#[test]
fn every_shipped_scenario_loads_and_the_suite_says_only_what_differs() {
    let mut files = Vec::new();
    for folder in ["scenarios", "scenarios/suite"] {
        for entry in std::fs::read_dir(common::root().join(folder)).expect("folder") {
            let path = entry.expect("entry").path();
            if path.extension().is_some_and(|e| e == "toml") {
                files.push(path);
            }
        }
    }
    files.sort();
    assert!(files.len() >= 10, "{files:?}");
    for path in &files {
        Scenario::load(path).unwrap_or_else(|e| panic!("{e}"));
        let text = common::read(path);
        let is_base = path.ends_with("paper_50.toml");
        assert_eq!(
            text.lines().any(|l| l.starts_with("extends = ")),
            !is_base,
            "{}",
            path.display()
        );
    }
}
