//! From a camera's sighting to the planner's percept: the target part's type, place and bore,
//! and the bottles and other parts near it as obstacles.

use nalgebra::Point3;

use super::camera_percept::Sighting;
use super::percept::{Percept, bottle_obstacle, part_obstacle};
use crate::scenario::{BottleSection, Catalogue, PartTypeId};

/// Things on the belt within this distance of the part are obstacles to its pick, m.
pub const NEIGHBOURHOOD_M: f64 = 0.45;
/// How much a bottle seen by the camera is grown as an obstacle, for the uncertainty of a pose
/// fitted to its box, m.
const SEEN_BOTTLE_GROWTH_M: f64 = 0.004;

/// What the station knows of the cell to turn a sighting into a percept.
#[derive(Debug, Clone, Copy)]
pub struct StationModel<'a> {
    /// The scenario's part types.
    pub catalogue: &'a Catalogue,
    /// The foreign object's size.
    pub bottle: &'a BottleSection,
    /// Top of the belt, world z, m.
    pub belt_top_z: f64,
}

impl Sighting {
    /// What this sighting means for the pick, or `None` when it holds no target part.
    pub fn percept(&self, station: &StationModel<'_>) -> Option<Percept> {
        let target = self.target.as_ref()?;
        let part_type = PartTypeId(target.type_index);
        let kind = station.catalogue.part(part_type);
        let centre = target.centre_in_world;
        let near = |x: f64, y: f64| (x - centre.x).hypot(y - centre.y) < NEIGHBOURHOOD_M;
        let mut obstacles = Vec::new();
        for bottle in &self.bottles {
            for pose in &bottle.poses {
                let t = pose.world_from_bottle.translation.vector;
                if near(t.x, t.y) {
                    obstacles.push(bottle_obstacle(
                        station.bottle,
                        &pose.world_from_bottle,
                        pose.lying,
                        SEEN_BOTTLE_GROWTH_M,
                    ));
                }
            }
        }
        for other in &self.other_parts {
            let p = other.centre_in_world;
            if near(p.x, p.y) {
                let other_type = station.catalogue.part(PartTypeId(other.type_index));
                let height_m = other_type.height_m;
                obstacles.push(part_obstacle(
                    &Point3::new(p.x, p.y, station.belt_top_z + height_m / 2.0),
                    other_type.outer_radius_m(),
                    height_m,
                ));
            }
        }
        let (roundness_mm, bore_diameter_mm) = match &target.bore {
            Some((_, plane)) => (Some(plane.roundness_m * 1e3), Some(plane.diameter_m * 1e3)),
            None => (None, None),
        };
        Some(Percept {
            part_type,
            part_xy: [centre.x, centre.y],
            part_outer_radius_m: kind.outer_radius_m(),
            part_height_m: kind.height_m,
            roundness_mm,
            bore_diameter_mm,
            inconsistency: target.inconsistency.clone(),
            unidentified: target.unidentified.clone(),
            obstacles,
        })
    }
}
