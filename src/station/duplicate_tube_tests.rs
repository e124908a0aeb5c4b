//! A tube boxed twice (its end face and its whole body, from a tilted camera) is one tube: the
//! second box is not an obstacle beside the target; a tube touching the target is.

use nalgebra::Point3;

use super::*;
use crate::rng::SimRng;
use crate::scenario::{BottleSection, Catalogue, Scenario};
use crate::station::PartSighting;

const BELT_TOP_Z: f64 = 0.7;

fn part(type_index: usize, x: f64, y: f64) -> PartSighting {
    PartSighting {
        detection: 0,
        type_index,
        centre_in_world: Point3::new(x, y, BELT_TOP_Z + 0.06),
        bore: None,
        inconsistency: None,
        unidentified: None,
    }
}

fn sighting(target: PartSighting, others: Vec<PartSighting>) -> Sighting {
    Sighting::of_parts(Vec::new(), Some(target), others)
}

#[test]
fn a_second_box_on_the_target_is_no_obstacle_and_a_touching_tube_is() {
    let text = include_str!("../../scenarios/paper_50.toml");
    let scenario = match Scenario::from_toml(text, std::path::Path::new("paper_50.toml")) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    };
    let catalogue = Catalogue::of(&scenario);
    let bottle = BottleSection::default();
    let station = StationModel {
        catalogue: &catalogue,
        bottle: &bottle,
        belt_top_z: BELT_TOP_Z,
    };
    let types = scenario.part_types.len() as u64;
    let radius = |t: usize| scenario.part_types[t].outer_diameter_mm / 2000.0;
    let mut rng = SimRng::new(77);
    for _ in 0..200 {
        let (t, o) = (rng.below(types) as usize, rng.below(types) as usize);
        let (x, y) = (rng.range(-0.05, 0.1), rng.range(-0.5, -0.4));
        let heading = rng.range(0.0, std::f64::consts::TAU);
        let at = |d: f64| part(o, x + d * heading.cos(), y + d * heading.sin());
        // Inside the larger footprint: the same tube seen twice.
        let inside = rng.range(0.0, 0.98) * radius(t).max(radius(o));
        let Some(p) = sighting(part(t, x, y), vec![at(inside)]).percept(&station) else {
            panic!("no percept");
        };
        assert!(
            p.obstacles.is_empty(),
            "{inside} m apart: {:?}",
            p.obstacles.len()
        );
        // Touching or apart: another tube, an obstacle.
        let apart = radius(t) + radius(o) + rng.range(0.0, 0.05);
        let Some(p) = sighting(part(t, x, y), vec![at(apart)]).percept(&station) else {
            panic!("no percept");
        };
        assert_eq!(p.obstacles.len(), 1, "{apart} m apart");
        assert_eq!(p.obstacles[0].name, "other part");
    }
}
