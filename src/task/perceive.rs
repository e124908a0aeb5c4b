//! The percept adapters: the camera's look at the pick station (the product) or the truth read
//! from the world (the oracle, for diagnosis), both turned into the planner's [`Percept`].

use nalgebra::{Isometry3, Point3, Vector3};

use super::observer::{BoreView, DetectionView, PerceptionFrame};
use super::trial::Trial;
use crate::outcome::{Failure, FailureReason, PartRecord, fail};
use crate::render::Scene;
use crate::rng::SimRng;
use crate::scenario::{Catalogue, PartTypeId};
use crate::station::{
    CameraPerception, Percept, Sighting, StationItem, TargetRule, bottle_obstacle, part_obstacle,
};

/// Things on the belt within this distance of the part are obstacles to its pick, m.
const NEIGHBOURHOOD_M: f64 = 0.45;
/// How much a bottle seen by the camera is grown as an obstacle, for the uncertainty of a pose
/// fitted to its box, m.
const SEEN_BOTTLE_GROWTH_M: f64 = 0.004;
/// Salt that keeps the camera's realism stream apart from the trial's physics stream.
const CAMERA_SALT: u64 = 0x4C4F_4F4B;

impl Trial<'_> {
    /// What perception says about the part at the station: from `seen` when the camera has
    /// already looked, else from a new look (or the oracle).
    pub(crate) fn perceive(&mut self, seen: Option<Sighting>) -> Result<Percept, Failure> {
        match (self.camera, seen) {
            (_, Some(sighting)) => self.percept_from(&sighting),
            (Some(camera), None) => {
                let sighting = self.look(camera, TargetRule::NearestStation)?;
                self.percept_from(&sighting)
            }
            (None, None) => {
                // The oracle stands in for the camera's frames, and waits out a blackout too.
                self.await_frames()?;
                self.perceive_oracle()
            }
        }
    }

    /// The product: render the pick station as the camera sees it (every part and bottle on the
    /// belt), detect, and measure the target part chosen by `rule`.
    pub(crate) fn look(
        &mut self,
        camera: &CameraPerception,
        rule: TargetRule,
    ) -> Result<Sighting, Failure> {
        self.await_frames()?;
        let scene = Scene::from_cell(&self.cell, self.scenario);
        let mut rng = SimRng::derive(self.seed ^ CAMERA_SALT, self.shots);
        self.shots += 1;
        let belt = &self.scenario.conveyor;
        let station = Point3::new(
            belt.photo_eye_x_m,
            belt.belt_center_m[1],
            self.cell.belt_top_z,
        );
        let sighting = camera
            .look(
                self.scenario,
                scene,
                &mut rng,
                &station,
                self.cell.belt_top_z,
                rule,
            )
            .map_err(|e| Failure::new(FailureReason::PerceptionError, e.to_string()))?;
        self.timing.render_ms += sighting.render_ms;
        self.timing.detect_ms += sighting.detect_ms;
        self.timing.metrology_ms += sighting.metrology_ms;
        let truth = self.part_record();
        let catalogue = self.catalogue;
        self.observer()
            .perception(|| perception_frame(&sighting, &truth, catalogue));
        Ok(sighting)
    }

    /// What a camera sighting means for the pick: the target part's type, place and bore, and the
    /// bottles and other parts near it as obstacles.
    fn percept_from(&self, sighting: &Sighting) -> Result<Percept, Failure> {
        let Some(target) = &sighting.target else {
            return fail(
                FailureReason::NotDetected,
                format!(
                    "no part detected at the pick station ({} detections)",
                    sighting.detections.len()
                ),
            );
        };
        let part_type = PartTypeId(target.type_index);
        let kind = self.catalogue.part(part_type);
        let part_height_m = kind.height_m;
        let centre = target.centre_in_world;
        let near = |x: f64, y: f64| (x - centre.x).hypot(y - centre.y) < NEIGHBOURHOOD_M;
        let mut obstacles = Vec::new();
        for bottle in &sighting.bottles {
            for pose in &bottle.poses {
                let t = pose.world_from_bottle.translation.vector;
                if near(t.x, t.y) {
                    obstacles.push(bottle_obstacle(
                        &self.scenario.bottle,
                        &pose.world_from_bottle,
                        pose.lying,
                        SEEN_BOTTLE_GROWTH_M,
                    ));
                }
            }
        }
        for other in &sighting.other_parts {
            let p = other.centre_in_world;
            if near(p.x, p.y) {
                let other_type = self.catalogue.part(PartTypeId(other.type_index));
                let height_m = other_type.height_m;
                obstacles.push(part_obstacle(
                    &Point3::new(p.x, p.y, self.cell.belt_top_z + height_m / 2.0),
                    other_type.outer_radius_m(),
                    height_m,
                ));
            }
        }
        let (roundness_mm, bore_diameter_mm) = match &target.bore {
            Some((_, plane)) => (Some(plane.roundness_m * 1e3), Some(plane.diameter_m * 1e3)),
            None => (None, None),
        };
        Ok(Percept {
            part_type,
            part_xy: [centre.x, centre.y],
            part_outer_radius_m: kind.outer_radius_m(),
            part_height_m,
            roundness_mm,
            bore_diameter_mm,
            inconsistency: target.inconsistency.clone(),
            obstacles,
        })
    }

    /// Ground truth read from the world (diagnosis mode): the part at the pick station, and
    /// the bottles and other parts near it as obstacles.
    fn perceive_oracle(&self) -> Result<Percept, Failure> {
        let items = &self.cell.items;
        let handled = &items.parts()[self.current];
        let Some(part_pose) = self.cell.body_pose(handled.body) else {
            return fail(FailureReason::NotDetected, "part body missing");
        };
        let near = |pose: &Isometry3<f64>| {
            let d = pose.translation.vector - part_pose.translation.vector;
            d.x.hypot(d.y) < NEIGHBOURHOOD_M && (d.z).abs() < 0.1
        };
        let mut obstacles = Vec::new();
        for bottle in items.bottles() {
            let Some(pose) = self.cell.body_pose(bottle.body).filter(near) else {
                continue;
            };
            let lying = bottle.lying || (pose.rotation * Vector3::z()).z.abs() < 0.7;
            obstacles.push(bottle_obstacle(&self.scenario.bottle, &pose, lying, 0.0));
        }
        for (i, other) in items.parts().iter().enumerate() {
            if i == self.current {
                continue;
            }
            let Some(pose) = self.cell.body_pose(other.body).filter(near) else {
                continue;
            };
            obstacles.push(part_obstacle(
                &Point3::from(pose.translation.vector),
                other.instance.outer_radius_m,
                other.instance.height_m,
            ));
        }
        let part = &handled.instance;
        Ok(Percept {
            part_type: PartTypeId(part.type_index),
            part_xy: [part_pose.translation.x, part_pose.translation.y],
            part_outer_radius_m: part.outer_radius_m,
            part_height_m: part.height_m,
            roundness_mm: Some(part.bore.roundness_m() * 1000.0),
            bore_diameter_mm: Some(part.bore.mean_diameter_m() * 1000.0),
            inconsistency: None,
            obstacles,
        })
    }
}

/// What the camera saw, as an observer is shown it: the image, the detector's boxes, and the
/// target's bore with the truth beside the measurement.
fn perception_frame(
    sighting: &Sighting,
    truth: &PartRecord,
    catalogue: &Catalogue,
) -> PerceptionFrame {
    let detections = sighting
        .detections
        .iter()
        .map(|d| DetectionView {
            class_name: d.class_name.clone(),
            score: d.score,
            box_px: d.box_px,
        })
        .collect();
    let bores = sighting
        .target
        .iter()
        .filter_map(|t| t.bore.as_ref())
        .map(|(bore, plane)| BoreView {
            centre_px: bore.centre_px,
            radius_px: bore.radius_px,
            contour_px: bore.edge_points_px.clone(),
            measured_roundness_mm: Some(plane.roundness_m * 1e3),
            true_roundness_mm: Some(truth.true_roundness_mm),
            measured_diameter_mm: Some(plane.diameter_m * 1e3),
            true_diameter_mm: Some(truth.true_bore_diameter_mm),
        })
        .collect();
    let station = sighting.at_station.map(|item| match item {
        StationItem::Bottle(_) => "bottle".to_owned(),
        StationItem::Part => sighting.target.as_ref().map_or_else(
            || "a part".to_owned(),
            |t| catalogue.part(PartTypeId(t.type_index)).name.clone(),
        ),
    });
    PerceptionFrame {
        image: sighting.image.clone(),
        detections,
        bores,
        station,
    }
}
