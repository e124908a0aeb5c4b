//! Checks a parsed URDF's link tree before the physics loader sees it: the loader indexes its
//! links by the names the joints give and panics on a name it does not know (found by the
//! `urdf` fuzz target), so every joint's links must exist, and the links must form a tree.

use std::collections::{BTreeMap, BTreeSet};

use rapier3d_urdf::urdf_rs::Robot;

/// Why `robot`'s links and joints do not form a tree the loader can build, or `None`.
pub(super) fn tree_error(robot: &Robot) -> Option<String> {
    let mut links = BTreeSet::new();
    for link in &robot.links {
        if !links.insert(link.name.as_str()) {
            return Some(format!("link `{}` is declared twice", link.name));
        }
    }
    let mut parent_of: BTreeMap<&str, &str> = BTreeMap::new();
    for joint in &robot.joints {
        for (role, link) in [("parent", &joint.parent.link), ("child", &joint.child.link)] {
            if !links.contains(link.as_str()) {
                return Some(format!(
                    "joint `{}`: its {role} link `{link}` is not a link of the file",
                    joint.name
                ));
            }
        }
        let child = joint.child.link.as_str();
        if let Some(first) = parent_of.insert(child, joint.parent.link.as_str()) {
            return Some(format!(
                "joint `{}`: link `{child}` already has the parent `{first}` (links form a tree)",
                joint.name
            ));
        }
    }
    // Walking up from any link must reach a root: a walk longer than the link count is a loop.
    for &start in &links {
        let mut link = start;
        for _ in 0..=links.len() {
            match parent_of.get(link) {
                Some(&parent) => link = parent,
                None => break,
            }
        }
        if parent_of.contains_key(link) {
            return Some(format!("the joints form a loop through link `{start}`"));
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use rapier3d_urdf::urdf_rs;

    fn robot(links: &[&str], joints: &[(&str, &str, &str)]) -> Robot {
        let mut text = String::from("<robot name=\"r\">");
        for l in links {
            text += &format!("<link name=\"{l}\"/>");
        }
        for (name, parent, child) in joints {
            text += &format!(
                "<joint name=\"{name}\" type=\"fixed\"><parent link=\"{parent}\"/>\
                 <child link=\"{child}\"/></joint>"
            );
        }
        text += "</robot>";
        match urdf_rs::read_from_string(&text) {
            Ok(r) => r,
            Err(e) => panic!("{e}"),
        }
    }

    #[test]
    fn a_chain_and_a_branching_tree_pass() {
        assert_eq!(
            tree_error(&robot(
                &["a", "b", "c"],
                &[("j1", "a", "b"), ("j2", "b", "c")]
            )),
            None
        );
        assert_eq!(
            tree_error(&robot(
                &["a", "b", "c"],
                &[("j1", "a", "b"), ("j2", "a", "c")]
            )),
            None
        );
        assert_eq!(tree_error(&robot(&["a"], &[])), None);
    }

    #[test]
    fn unknown_links_second_parents_loops_and_twice_declared_links_are_named() {
        let cases = [
            (
                robot(&["a", "b"], &[("j1", "a", "x")]),
                "joint `j1`: its child link `x`",
            ),
            (
                robot(&["a", "b"], &[("j1", "y", "b")]),
                "joint `j1`: its parent link `y`",
            ),
            (
                robot(&["a", "b", "c"], &[("j1", "a", "c"), ("j2", "b", "c")]),
                "joint `j2`: link `c` already has the parent `a`",
            ),
            (
                robot(&["a", "b", "c"], &[("j1", "b", "c"), ("j2", "c", "b")]),
                "the joints form a loop",
            ),
            (robot(&["a", "a"], &[]), "link `a` is declared twice"),
        ];
        for (r, expected) in cases {
            let Some(error) = tree_error(&r) else {
                panic!("accepted; expected {expected}");
            };
            assert!(error.starts_with(expected), "{error}");
        }
    }
}
