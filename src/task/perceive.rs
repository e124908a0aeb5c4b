//! The percept adapters: the camera's look at the pick station (the product) or the truth read
//! from the world (the oracle, for diagnosis), both turned into the planner's [`Percept`].

use nalgebra::{Isometry3, Point3, Vector3};

use super::cell_data::CellData;
use super::observer::{BoreView, DetectionView, PerceptionFrame};
use super::sorter::Sorter;
use crate::cell::CellModel;
use crate::control::BELT_ACCEL_M_S2;
use crate::outcome::{Failure, FailureReason, PartRecord, fail};
use crate::render::Scene;
use crate::rng::SimRng;
use crate::scenario::{Catalogue, PartTypeId};
use crate::station::{
    BeltBand, CameraPerception, NEIGHBOURHOOD_M, Percept, Sighting, StationItem, StationModel,
    Surroundings, TargetRule, bottle_obstacle, part_obstacle,
};

/// Most belt jogs that bring a part cut by the image border into view before the cell works
/// with what it sees.
const MAX_BORDER_JOGS: usize = 3;
/// Longest a belt jog may take per metre of travel at the belt's speed, beyond a second's
/// margin, before it counts as stalled, s.
const JOG_TIME_FACTOR: f64 = 3.0;
/// Settling time after a jog, as after the belt stops at the photo-eye, s.
const JOG_SETTLE_S: f64 = 0.25;

/// Salt that keeps the camera's realism stream apart from the trial's physics stream.
const CAMERA_SALT: u64 = 0x4C4F_4F4B;

impl Sorter<'_> {
    /// What perception says about the part at the station: from `seen` when the camera has
    /// already looked, else from a new look (or the oracle).
    pub(crate) fn perceive(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        seen: Option<Sighting>,
    ) -> Result<Percept, Failure> {
        self.hidden_at_beam = false;
        match (self.camera, seen) {
            (_, Some(sighting)) => percept_from(model, data, &sighting),
            (Some(camera), None) => {
                let mut sighting = self.look(model, data, camera, TargetRule::NearestStation)?;
                // A part cut by the image border, or still upstream of the view behind the
                // bottle that stopped the belt, is carried towards the view's centre and looked
                // at again, a few times at most.
                let rig = camera.rig();
                for _ in 0..MAX_BORDER_JOGS {
                    self.hidden_at_beam = hidden_at_beam(model, data, &sighting);
                    if self.hidden_at_beam {
                        return Err(Failure::new(
                            FailureReason::NotDetected,
                            format!(
                                "the item at the photo-eye is hidden from the camera: no part \
                                 in view, and the {} bottle(s) it sees stand clear of the beam",
                                sighting.bottles.len()
                            ),
                        ));
                    }
                    let frame_px = (rig.width_px, rig.height_px);
                    let belt_top_z = data.cell.belt_top_z;
                    let calibration = &rig.calibration;
                    let around = surroundings_to_see(model, &sighting, belt_top_z);
                    let bottle_length_m = model.scenario().bottle.height_m;
                    let jog = sighting
                        .border_jog_m(calibration, frame_px, belt_top_z)
                        .or_else(|| {
                            sighting.surroundings_jog_m(calibration, frame_px, around.as_ref()?)
                        })
                        .or_else(|| {
                            let reach_m = around.as_ref()?.reach_m;
                            sighting.cut_neighbour_jog_m(
                                calibration,
                                frame_px,
                                reach_m,
                                bottle_length_m,
                            )
                        });
                    let Some(jog_m) = jog else {
                        break;
                    };
                    data.jog_belt(model, jog_m)?;
                    sighting = self.look(model, data, camera, TargetRule::NearestStation)?;
                }
                percept_from(model, data, &sighting)
            }
            (None, None) => {
                // The oracle stands in for the camera's frames, and waits out a blackout too.
                data.await_frames(model)?;
                perceive_oracle(model, data, self.current)
            }
        }
    }

    /// The product: render the pick station as the camera sees it (every part and bottle on the
    /// belt), detect, and measure the target part chosen by `rule`.
    pub(crate) fn look(
        &self,
        model: &CellModel,
        data: &mut CellData,
        camera: &CameraPerception,
        rule: TargetRule,
    ) -> Result<Sighting, Failure> {
        let belt = &model.scenario().conveyor;
        let belt_top_z = data.cell.belt_top_z;
        let station = Point3::new(belt.photo_eye_x_m, belt.belt_center_m[1], belt_top_z);
        self.look_near(model, data, camera, rule, &station)
    }

    /// [`Self::look`] with `station` (world, on the belt's top) as the point the target is
    /// chosen nearest to.
    pub(crate) fn look_near(
        &self,
        model: &CellModel,
        data: &mut CellData,
        camera: &CameraPerception,
        rule: TargetRule,
        station: &Point3<f64>,
    ) -> Result<Sighting, Failure> {
        data.await_frames(model)?;
        let scenario = model.scenario();
        let scene = Scene::from_cell(&data.cell, scenario);
        let mut rng = SimRng::derive(data.seed ^ CAMERA_SALT, data.shots);
        data.shots += 1;
        let belt_top_z = data.cell.belt_top_z;
        let sighting = camera
            .look(scenario, scene, &mut rng, station, belt_top_z, rule)
            .map_err(|e| Failure::new(FailureReason::PerceptionError, e.to_string()))?;
        data.timing.render_ms += sighting.render_ms;
        data.timing.detect_ms += sighting.detect_ms;
        data.timing.metrology_ms += sighting.metrology_ms;
        let truth = self.part_record(model, data);
        let catalogue = model.catalogue();
        data.observe_perception(|| perception_frame(&sighting, &truth, catalogue));
        Ok(sighting)
    }
}

/// The belt around the target part the camera must see before the arm reaches for it: within
/// the part's radius, [`SURROUND_MARGIN_M`] and a bottle's diameter of its axis, so that a
/// bottle standing with its side within the margin of the part's is seen whole. `None` where
/// nothing could stand there unseen: a scenario without bottles, or a stream, whose items the
/// cell tracks as the belt brings them.
fn surroundings_to_see(
    model: &CellModel,
    sighting: &Sighting,
    belt_top_z_m: f64,
) -> Option<Surroundings> {
    let scenario = model.scenario();
    if !scenario.bottle.enabled || scenario.is_stream() {
        return None;
    }
    let target = sighting.target.as_ref()?;
    let part = model.catalogue().part(PartTypeId(target.type_index));
    Some(Surroundings {
        reach_m: part.outer_radius_m() + SURROUND_MARGIN_M + 2.0 * scenario.bottle.radius_m,
        belt_top_z_m,
        belt: BeltBand::of(&scenario.conveyor),
    })
}

/// See [`surroundings_to_see`], m.
const SURROUND_MARGIN_M: f64 = 0.02;

/// A bottle whose footprint, as fitted, comes within this of the photo-eye's beam may be what
/// breaks it, m: more than a fit's error.
const AT_BEAM_MARGIN_M: f64 = 0.02;

/// Whether what breaks the photo-eye's beam is hidden from the camera: `sighting` saw no part,
/// and every bottle it saw stands clear of the beam (each pose's footprint along the belt, its
/// axis's span grown by the radius and [`AT_BEAM_MARGIN_M`], misses the beam's line), while the
/// beam is broken. A camera leaning back along the belt sees a standing bottle behind the part
/// at the beam and not the part: jogging the belt on, as for a part still upstream, carried the
/// part out of reach.
fn hidden_at_beam(model: &CellModel, data: &CellData, sighting: &Sighting) -> bool {
    if sighting.target.is_some() || sighting.bottles.is_empty() || !data.photo_eye_reports() {
        return false;
    }
    let scenario = model.scenario();
    let (eye_x, bottle) = (scenario.conveyor.photo_eye_x_m, &scenario.bottle);
    let reach = bottle.radius_m + AT_BEAM_MARGIN_M;
    let at_beam = |world: &nalgebra::Isometry3<f64>| {
        let (a, b) = (
            world * Point3::origin(),
            world * Point3::new(0.0, 0.0, bottle.height_m),
        );
        a.x.min(b.x) - reach <= eye_x && eye_x <= a.x.max(b.x) + reach
    };
    !sighting
        .bottles
        .iter()
        .flat_map(|b| &b.poses)
        .any(|p| at_beam(&p.world_from_bottle))
}

impl CellData {
    /// Runs the belt downstream by `distance_m` of encoder travel at the scenario's speed and
    /// stops it (the drive's ramp taken into account), lets things settle, and notes where the
    /// bottles now rest: the belt, not the robot, moved them.
    pub(crate) fn jog_belt(&mut self, model: &CellModel, distance_m: f64) -> Result<(), Failure> {
        let speed = model.scenario().conveyor.speed_m_s;
        let start_m = self.belt.encoder_travel_m();
        let deadline_s = self.cell.world.time_s() + 1.0 + JOG_TIME_FACTOR * distance_m / speed;
        self.belt.run_at(speed);
        loop {
            let v = f64::from(self.cell.conveyor.speed_m_s());
            let stopping_m = v * v / (2.0 * BELT_ACCEL_M_S2);
            if self.belt.encoder_travel_m() - start_m + stopping_m >= distance_m {
                break;
            }
            if self.cell.world.time_s() > deadline_s {
                self.belt.run_at(0.0);
                return Err(Failure::new(
                    FailureReason::Timeout,
                    format!(
                        "the belt jog of {:.0} mm that brings the part into view stalled",
                        distance_m * 1e3
                    ),
                ));
            }
            self.step(model)?;
        }
        self.belt.run_at(0.0);
        while self.cell.conveyor.speed_m_s() > 0.0 {
            self.step(model)?;
        }
        self.settle(model, JOG_SETTLE_S)?;
        self.note_bottle_rest(model);
        Ok(())
    }
}

/// What a camera sighting means for the pick; a sighting without a target part fails.
fn percept_from(
    model: &CellModel,
    data: &CellData,
    sighting: &Sighting,
) -> Result<Percept, Failure> {
    let station = StationModel {
        catalogue: model.catalogue(),
        bottle: &model.scenario().bottle,
        belt_top_z: data.cell.belt_top_z,
    };
    sighting.percept(&station).ok_or_else(|| {
        Failure::new(
            FailureReason::NotDetected,
            format!(
                "no part detected at the pick station ({} detections)",
                sighting.detections.len()
            ),
        )
    })
}

/// Ground truth read from the world (diagnosis mode): the part at the pick station, and
/// the bottles and other parts near it as obstacles.
pub(super) fn perceive_oracle(
    model: &CellModel,
    data: &CellData,
    current: usize,
) -> Result<Percept, Failure> {
    let scenario = model.scenario();
    let items = &data.cell.items;
    let handled = &items.parts()[current];
    let Some(part_pose) = data.cell.body_pose(handled.body) else {
        return fail(FailureReason::NotDetected, "part body missing");
    };
    let near = |pose: &Isometry3<f64>| {
        let d = pose.translation.vector - part_pose.translation.vector;
        d.x.hypot(d.y) < NEIGHBOURHOOD_M && (d.z).abs() < 0.1
    };
    let mut obstacles = Vec::new();
    for bottle in items.bottles() {
        let Some(pose) = data.cell.body_pose(bottle.body).filter(near) else {
            continue;
        };
        let lying = bottle.lying || (pose.rotation * Vector3::z()).z.abs() < 0.7;
        obstacles.push(bottle_obstacle(&scenario.bottle, &pose, lying, 0.0));
    }
    for (i, other) in items.parts().iter().enumerate() {
        if i == current {
            continue;
        }
        let Some(pose) = data.cell.body_pose(other.body).filter(near) else {
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
        unidentified: None,
        obstacles,
    })
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
