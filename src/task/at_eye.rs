//! What stopped the belt at the photo-eye, known by its track: the look's items join the
//! stream's tracks, the item at the beam is a track, and what the track has been seen as over
//! every look (not this look's box alone) says whether it is a part to pick or a bottle to let
//! through. The truth (which body breaks the beam) only chooses the part the judge follows and
//! judges the identification.

use nalgebra::Point3;

use super::cell_data::CellData;
use super::sorter::Sorter;
use super::tracking::{BeltTracking, TrueItem};
use crate::cell::CellModel;
use crate::outcome::{Failure, FailureReason, Misidentification};
use crate::scenario::PartTypeId;
use crate::station::{
    CameraPerception, ItemKind, SeenItem, Sighting, StationItem, TargetRule, TrackId,
};

/// Spacing of the points along the photo-eye's beam that the camera checks, m.
const BEAM_SAMPLE_M: f64 = 0.005;
/// Heights above the belt of the beam's sampled lines (it spans 10-50 mm), m.
const BEAM_HEIGHTS_M: [f64; 3] = [0.01, 0.03, 0.05];

/// What perception says stopped the belt.
pub(crate) enum AtEye {
    /// A part, to be picked; the camera's look, when it took one.
    Part(Option<Box<Sighting>>),
    /// A bottle, to be let through.
    Bottle,
}

/// What truly breaks the beam: the part and the bottle there, by their registry indices.
pub(crate) struct AtBeamTruth {
    part: Option<usize>,
    bottle: Option<usize>,
}

impl BeltTracking {
    /// Notes, for the judge, what truly stood at the beam when the cell named `track` there.
    fn note_truth(&mut self, track: TrackId, truth: &AtBeamTruth) {
        let item = match (truth.part, truth.bottle) {
            (Some(i), _) => TrueItem::Part(i),
            (None, Some(i)) => TrueItem::Bottle(i),
            (None, None) => return,
        };
        self.truth_at_eye.push((track, item));
    }
}

impl Sorter<'_> {
    /// Points along the photo-eye's beam across the belt, world.
    fn beam_points(model: &CellModel, data: &CellData) -> Vec<Point3<f64>> {
        let belt = &model.scenario().conveyor;
        let samples = (belt.width_m / BEAM_SAMPLE_M).ceil().max(1.0) as usize;
        let mut points = Vec::with_capacity((samples + 1) * BEAM_HEIGHTS_M.len());
        for height in BEAM_HEIGHTS_M {
            for k in 0..=samples {
                let y = belt.belt_center_m[1] - belt.width_m / 2.0
                    + belt.width_m * k as f64 / samples as f64;
                points.push(Point3::new(
                    belt.photo_eye_x_m,
                    y,
                    data.cell.belt_top_z + height,
                ));
            }
        }
        points
    }

    /// The truth at the beam; the part the judge follows becomes the one there.
    fn truth_at_beam(&mut self, data: &CellData) -> AtBeamTruth {
        let at_eye = data.cell.bodies_at_photo_eye();
        let items = &data.cell.items;
        let part = items.parts().iter().position(|p| at_eye.contains(&p.body));
        if let Some(i) = part {
            self.current = i;
        }
        let bottle = items
            .bottles()
            .iter()
            .position(|b| at_eye.contains(&b.body));
        AtBeamTruth { part, bottle }
    }

    /// Identifies what stopped the belt, by its track.
    pub(crate) fn identify_at_eye(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
    ) -> Result<AtEye, Failure> {
        let truth = self.truth_at_beam(data);
        self.station_track = None;
        let Some(camera) = self.camera else {
            return self.identify_by_oracle(data, &truth);
        };
        let beam = TargetRule::AtBeam(Self::beam_points(model, data));
        let sighting = self.look(model, data, camera, beam)?;
        let Some(tracking) = self.tracking.as_mut() else {
            return Err(Failure::new(
                FailureReason::Panic,
                "a stream without tracks",
            ));
        };
        let seen = tracking.see_look(model, data, camera.rig(), &sighting);
        let track_of = |item: SeenItem| seen.iter().find(|(s, _)| *s == item).map(|(_, t)| *t);
        let station = match sighting.at_station {
            Some(StationItem::Part) => track_of(SeenItem::Target),
            Some(StationItem::Bottle(i)) => track_of(SeenItem::Bottle(i)),
            None => tracking.nearest_beam(data),
        };
        let Some(station) = station else {
            return Err(Failure::new(
                FailureReason::NotDetected,
                format!(
                    "nothing detected at the photo-eye ({} detections in view, {} tracks open)",
                    sighting.detections.len(),
                    tracking
                        .tracks
                        .tracks()
                        .iter()
                        .filter(|t| t.is_open())
                        .count()
                ),
            ));
        };
        self.station_track = Some(station);
        tracking.note_truth(station, &truth);
        let kind = tracking.track(station).map_or(ItemKind::Part, |t| t.kind());
        let at_eye = match kind {
            ItemKind::Bottle => AtEye::Bottle,
            ItemKind::Part if track_of(SeenItem::Target) == Some(station) => {
                AtEye::Part(Some(Box::new(sighting)))
            }
            // The look measured another part, or none: look again at the track's place.
            ItemKind::Part => AtEye::Part(Some(Box::new(
                self.look_at_track(model, data, camera, station)?,
            ))),
        };
        self.judge_identification(model, data, &truth, &at_eye)?;
        Ok(at_eye)
    }

    /// A look whose target is the part nearest track `track`'s predicted place; fails when the
    /// part it measures is not that track's.
    fn look_at_track(
        &mut self,
        model: &CellModel,
        data: &mut CellData,
        camera: &CameraPerception,
        track: TrackId,
    ) -> Result<Sighting, Failure> {
        let not_found = || {
            Failure::new(
                FailureReason::NotDetected,
                format!(
                    "the part tracked at the photo-eye (track {}) was not found",
                    track.0
                ),
            )
        };
        let Some(at) = self
            .tracking
            .as_ref()
            .and_then(|t| t.predicted_in_world(data, track))
        else {
            return Err(not_found());
        };
        let sighting = self.look_near(model, data, camera, TargetRule::NearestStation, &at)?;
        let Some(tracking) = self.tracking.as_mut() else {
            return Err(not_found());
        };
        let seen = tracking.see_look(model, data, camera.rig(), &sighting);
        let target = seen.iter().find(|(s, _)| *s == SeenItem::Target);
        match target {
            Some((_, t)) if *t == track => Ok(sighting),
            _ => Err(not_found()),
        }
    }

    /// Oracle mode: the truth's view joins the tracks; the item at the beam is the track of the
    /// body that breaks it.
    fn identify_by_oracle(
        &mut self,
        data: &CellData,
        truth: &AtBeamTruth,
    ) -> Result<AtEye, Failure> {
        if let Some(tracking) = self.tracking.as_mut() {
            let seen = tracking.see_truth(data);
            let at_beam = match (truth.part, truth.bottle) {
                (Some(i), _) => Some(TrueItem::Part(i)),
                (None, Some(i)) => Some(TrueItem::Bottle(i)),
                (None, None) => None,
            };
            self.station_track = seen
                .iter()
                .find(|(item, _)| Some(*item) == at_beam)
                .map(|(_, t)| *t);
            if let Some(station) = self.station_track {
                tracking.note_truth(station, truth);
            }
        }
        match (truth.part, truth.bottle) {
            (Some(_), _) => Ok(AtEye::Part(None)),
            (None, Some(_)) => Ok(AtEye::Bottle),
            (None, None) => Err(Failure::new(
                FailureReason::NotDetected,
                "the photo-eye is blocked by neither a part nor a bottle",
            )),
        }
    }

    /// Judges the cell's identification against the truth at the beam: a part taken for a
    /// bottle, a bottle for a part, or another part measured in place of the one there, each
    /// halts the stream as `misidentified`.
    fn judge_identification(
        &mut self,
        model: &CellModel,
        data: &CellData,
        truth: &AtBeamTruth,
        at_eye: &AtEye,
    ) -> Result<(), Failure> {
        let track = self.station_track.map(|t| t.0);
        let parts = data.cell.items.parts();
        let identified = |sighting: &Option<Box<Sighting>>| {
            sighting
                .as_ref()
                .and_then(|s| s.target.as_ref())
                .map_or("a part", |t| {
                    model
                        .catalogue()
                        .part(PartTypeId(t.type_index))
                        .name
                        .as_str()
                })
                .to_owned()
        };
        let (misidentified, detail) = match (at_eye, truth.part) {
            (AtEye::Part(seen), None) => (
                Misidentification {
                    truth: "bottle".to_owned(),
                    identified: identified(seen),
                    track,
                },
                "the camera took the bottle at the photo-eye for a part",
            ),
            (AtEye::Bottle, Some(i)) => (
                Misidentification {
                    truth: parts[i].instance.type_name.clone(),
                    identified: "bottle".to_owned(),
                    track,
                },
                "the camera took the part at the photo-eye for a bottle",
            ),
            (AtEye::Part(seen), Some(i)) if !measures_true_part(data, seen, i) => (
                Misidentification {
                    truth: parts[i].instance.type_name.clone(),
                    identified: format!("another part ({})", identified(seen)),
                    track,
                },
                "the camera measured another part than the one at the photo-eye",
            ),
            _ => return Ok(()),
        };
        self.misidentified = Some(misidentified);
        Err(Failure::new(FailureReason::Misidentified, detail))
    }
}

/// The tracking a stream of `model`'s starts with.
pub(crate) fn stream_tracking(model: &CellModel, data: &CellData) -> BeltTracking {
    BeltTracking::new(model, data.cell.belt_top_z)
}

/// Whether the look's target is part `part` (its end face's centre over the part's true
/// axis, within the part's radius).
fn measures_true_part(data: &CellData, seen: &Option<Box<Sighting>>, part: usize) -> bool {
    let Some(target) = seen.as_ref().and_then(|s| s.target.as_ref()) else {
        return true;
    };
    let item = &data.cell.items.parts()[part];
    let Some(pose) = data.cell.body_pose(item.body) else {
        return true;
    };
    let d = target.centre_in_world - Point3::from(pose.translation.vector);
    d.x.hypot(d.y) <= item.instance.outer_radius_m
}
