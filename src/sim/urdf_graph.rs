//! Checks a parsed URDF before the physics loader sees it. The loader indexes its links by the
//! names the joints give and panics on a name it does not know, and the shape library asserts
//! that a cylinder's sizes are positive (both found by the `urdf` fuzz target): so every joint's
//! links must exist, the links must form a tree, and every number must be one physics can use.

use std::collections::{BTreeMap, BTreeSet};

use rapier3d_urdf::urdf_rs::{Geometry, Pose, Robot};

/// Why a number of `robot` is one the loader cannot use (not finite, or a size, mass or inertia
/// below zero, or a joint axis of zero length), or `None`.
pub(super) fn value_error(robot: &Robot) -> Option<String> {
    let pose = |p: &Pose| p.xyz.iter().chain(p.rpy.iter()).all(|v| v.is_finite());
    for link in &robot.links {
        let name = &link.name;
        let inertial = &link.inertial;
        let i = &inertial.inertia;
        let moments = [i.ixx, i.iyy, i.izz];
        let products = [i.ixy, i.ixz, i.iyz];
        let usable = inertial.mass.value.is_finite()
            && inertial.mass.value >= 0.0
            && moments.iter().all(|v| v.is_finite() && *v >= 0.0)
            && products.iter().all(|v| v.is_finite())
            && pose(&inertial.origin);
        if !usable {
            return Some(format!(
                "link `{name}`: inertial needs a finite mass and moments of at least 0 and a finite origin"
            ));
        }
        let shapes = link
            .visual
            .iter()
            .map(|v| (&v.geometry, &v.origin, "visual"))
            .chain(
                link.collision
                    .iter()
                    .map(|c| (&c.geometry, &c.origin, "collision")),
            );
        for (geometry, origin, role) in shapes {
            let sizes: Vec<f64> = match geometry {
                Geometry::Box { size } => size.to_vec(),
                Geometry::Cylinder { radius, length } | Geometry::Capsule { radius, length } => {
                    vec![*radius, *length]
                }
                Geometry::Sphere { radius } => vec![*radius],
                Geometry::Mesh { scale, .. } => scale.as_ref().map_or(vec![1.0], |s| s.to_vec()),
            };
            if !sizes.iter().all(|v| v.is_finite() && *v > 0.0) || !pose(origin) {
                return Some(format!(
                    "link `{name}`: a {role} shape needs finite sizes above 0 and a finite origin"
                ));
            }
        }
    }
    for joint in &robot.joints {
        let axis = &joint.axis.xyz;
        let limit = &joint.limit;
        if !pose(&joint.origin)
            || !axis.iter().all(|v| v.is_finite())
            || axis.iter().all(|v| *v == 0.0)
            || ![limit.lower, limit.upper, limit.effort, limit.velocity]
                .iter()
                .all(|v| v.is_finite())
        {
            return Some(format!(
                "joint `{}`: needs a finite origin and limits and an axis of non-zero length",
                joint.name
            ));
        }
    }
    None
}

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
    fn shapes_with_sizes_at_or_below_zero_or_not_finite_are_named() {
        let with_shape = |shape: &str| {
            let text = format!(
                "<robot name=\"r\"><link name=\"a\"><collision><geometry>{shape}</geometry>\
                 </collision></link></robot>"
            );
            match urdf_rs::read_from_string(&text) {
                Ok(r) => r,
                Err(e) => panic!("{e}"),
            }
        };
        assert_eq!(
            value_error(&with_shape("<cylinder radius=\"0.1\" length=\"0.2\"/>")),
            None
        );
        for bad in [
            "<cylinder radius=\"0.1\" length=\"-0.2\"/>",
            "<cylinder radius=\"-0.0\" length=\"0.2\"/>",
            "<sphere radius=\"NaN\"/>",
            "<box size=\"1 inf 1\"/>",
            "<capsule radius=\"0\" length=\"1\"/>",
        ] {
            let Some(error) = value_error(&with_shape(bad)) else {
                panic!("{bad} accepted");
            };
            assert!(error.starts_with("link `a`: a collision shape"), "{error}");
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
