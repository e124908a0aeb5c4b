//! The stream's items tracked along the belt: every look (the camera's, or in oracle mode the
//! truth's view of the same stretch) joins the trial's [`TrackSet`] at the belt encoder's count,
//! and the item at the photo-eye is known by its track.

use nalgebra::{Isometry3, Point3, Vector3};

use super::cell_data::CellData;
use crate::cell::CellModel;
use crate::control::ENCODER_M_PER_COUNT;
use crate::outcome::{CollectedRecord, Failure, FailureReason, Phase};
use crate::render::CameraRig;
use crate::scenario::{BottleSection, ConveyorSection};
use crate::station::{
    BeltFrame, BeltPoint, ItemKind, ItemSighting, Percept, SeenItem, Sighting, Track, TrackEnd,
    TrackId, TrackSet, TrackerParams, TubeEnvelope, ViewSpan, bottle_obstacle, part_obstacle,
};

/// Looks in a row that may miss a track in view before it is counted lost: one look may miss
/// an item (a box the detector dropped) without its losing its identity.
const MAX_MISSED_LOOKS: u32 = 1;
/// The gate as a share of the feeder's spacing: two neighbours' predictions are a spacing
/// apart, so a sighting can lie within the gate of one of them only.
const GATE_SHARE_OF_SPACING: f64 = 0.4;
/// The gate's most, m: what a footprint's centre may move between looks (the fit's error and
/// an item's slip on the belt), however sparse the stream.
const GATE_MAX_M: f64 = 0.08;
/// An item this far from the belt's top (its centre, m) is off the belt: the truth's view of
/// the belt in oracle mode leaves it out.
const ON_BELT_M: f64 = 0.2;
/// Belt travel past the belt's end after which an item carried off it has fallen into the
/// collector below, m.
const FALL_CLEARANCE_M: f64 = 0.15;
/// Time for what fell to come to rest in the collector, s.
const COLLECTOR_REST_S: f64 = 1.0;
/// A tracked bottle whose predicted place lies this near a bottle of the percept is that one, m.
const TRACKED_SAME_M: f64 = 0.1;

/// An item of the world the oracle's view saw: a part or a bottle by its registry index.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum TrueItem {
    Part(usize),
    Bottle(usize),
}

/// A stream's tracks and the frame they are kept in.
pub(crate) struct BeltTracking {
    pub(crate) frame: BeltFrame,
    /// The stretch of belt the camera sees.
    pub(crate) view: ViewSpan,
    pub(crate) tracks: TrackSet,
    /// The judge's bookkeeping: the true item at the photo-eye each time the cell named a
    /// track there (never read by the cell's decisions).
    pub(crate) truth_at_eye: Vec<(TrackId, TrueItem)>,
    /// The size (outer radius, height, m) of the type each latched part's look named, by
    /// track.
    sizes: Vec<(TrackId, [f64; 2])>,
}

impl BeltTracking {
    /// The tracking of a stream of `model`'s, on a belt whose top is at `belt_top_z`.
    pub(crate) fn new(model: &CellModel, belt_top_z: f64) -> Self {
        let scenario = model.scenario();
        let belt = &scenario.conveyor;
        let frame = BeltFrame {
            station_in_world: Point3::new(belt.photo_eye_x_m, belt.belt_center_m[1], belt_top_z),
            travel: Vector3::x_axis(),
        };
        // The belt's whole length when the camera cannot be made (the look fails then anyway).
        let view = CameraRig::from_scenario(scenario).map_or(
            ViewSpan {
                from_m: -belt.length_m,
                to_m: belt.length_m,
            },
            |rig| frame.view_span(&rig.calibration, rig.width_px, rig.height_px),
        );
        let gate_m = (scenario.stream.spacing_m * GATE_SHARE_OF_SPACING).min(GATE_MAX_M);
        let tracks = TrackSet::new(TrackerParams {
            m_per_count: ENCODER_M_PER_COUNT,
            gate_m,
            max_missed_looks: MAX_MISSED_LOOKS,
        });
        Self {
            frame,
            view,
            tracks,
            truth_at_eye: Vec::new(),
            sizes: Vec::new(),
        }
    }

    /// Bottles the tracks hold on the belt that `percept` does not: each bottle track open or
    /// carried out of view downstream (not lost, not picked), at the place the encoder
    /// predicts, while it is still on the belt and no bottle of the percept stands within
    /// [`TRACKED_SAME_M`] of it, joins the percept's obstacles as a standing bottle as wide as
    /// the track's footprint was long. The camera sees the station; the arm carries parts past
    /// the belt beyond it, where a bottle the camera saw earlier may still ride (a lying reading
    /// cannot be trusted out of view: standing is the tall case).
    /// `count` is the encoder's count now.
    pub(crate) fn add_tracked_bottles(&self, model: &CellModel, count: i64, percept: &mut Percept) {
        let scenario = model.scenario();
        for (track, point) in self.riding(model, ItemKind::Bottle, count) {
            if holds_near(percept, "bottle", &point) {
                continue;
            }
            let bottle = BottleSection {
                radius_m: scenario.bottle.radius_m.max(track.half_length_m),
                ..scenario.bottle.clone()
            };
            let pose = Isometry3::translation(point.x, point.y, point.z);
            percept
                .obstacles
                .push(bottle_obstacle(&bottle, &pose, false, 0.0));
        }
    }

    /// The tracks of `kind` still riding on the belt at encoder count `count` (open, or carried
    /// out of view downstream; not lost, not picked, not past the belt's end), each with the
    /// place the encoder predicts for it, world (on the belt's top).
    fn riding<'t>(
        &'t self,
        model: &CellModel,
        kind: ItemKind,
        count: i64,
    ) -> impl Iterator<Item = (&'t Track, Point3<f64>)> + 't {
        let end_along_m = end_along_m(&model.scenario().conveyor);
        let m = self.tracks.params().m_per_count;
        self.tracks.tracks().iter().filter_map(move |track| {
            let riding = matches!(track.end, None | Some(TrackEnd::LeftView));
            if track.kind() != kind || !riding {
                return None;
            }
            let at = track.predicted(count, m);
            (at.along_m <= end_along_m).then(|| (track, self.frame.world_from_belt(&at)))
        })
    }

    /// Notes the size of the part on track `id` as its look measured it: outer radius and
    /// height, m.
    pub(crate) fn note_size(&mut self, id: TrackId, radius_m: f64, height_m: f64) {
        self.sizes.retain(|(t, _)| *t != id);
        self.sizes.push((id, [radius_m, height_m]));
    }

    /// Parts the tracks hold on the belt that `percept` does not: each part track still riding
    /// (open, or carried out of view downstream), other than `own` (the part picked), at the
    /// place the encoder predicts for `count`, while it is on the belt and neither the picked
    /// part nor another part of the percept stands within [`TRACKED_SAME_M`] of it, joins the
    /// percept's obstacles as a standing tube of the size its own look named
    /// ([`Self::note_size`]), or of the catalogue's widest and tallest where none has: a look
    /// that saw it upstream of the part it measured (the arm's way down to a part on a held
    /// belt passes over the belt behind it) did not measure it.
    pub(crate) fn add_tracked_parts(
        &self,
        model: &CellModel,
        count: i64,
        percept: &mut Percept,
        own: Option<TrackId>,
    ) {
        let tubes = tube_envelope(model);
        let [px, py] = percept.part_xy;
        for (track, point) in self.riding(model, ItemKind::Part, count) {
            let picked = (px - point.x).hypot(py - point.y) < TRACKED_SAME_M;
            if Some(track.id) == own || picked || holds_near(percept, "other part", &point) {
                continue;
            }
            let [radius_m, height_m] = self
                .sizes
                .iter()
                .find(|(t, _)| *t == track.id)
                .map_or([tubes.outer_radius_m, tubes.height_m], |(_, size)| *size);
            let centre = Point3::new(point.x, point.y, point.z + height_m / 2.0);
            percept
                .obstacles
                .push(part_obstacle(&centre, radius_m, height_m));
        }
    }

    /// The encoder's count now.
    pub(crate) fn count(data: &CellData) -> i64 {
        data.belt.encoder_counts()
    }

    /// Joins a camera look's items to the tracks; returns each item's track.
    pub(crate) fn see_look(
        &mut self,
        model: &CellModel,
        data: &CellData,
        rig: &CameraRig,
        sighting: &Sighting,
    ) -> Vec<(SeenItem, TrackId)> {
        let tubes = tube_envelope(model);
        let items = self.frame.items_of(
            sighting,
            &rig.calibration,
            (rig.width_px, rig.height_px),
            model.scenario().bottle.height_m,
            &tubes,
        );
        let found: Vec<ItemSighting> = items.iter().map(|(_, s)| *s).collect();
        let ids = self.tracks.update(Self::count(data), &found, &self.view);
        items.into_iter().map(|(seen, _)| seen).zip(ids).collect()
    }

    /// Oracle mode: joins the items the truth shows on the belt in the camera's view, at their
    /// true kind and place; returns each item's track.
    pub(crate) fn see_truth(&mut self, data: &CellData) -> Vec<(TrueItem, TrackId)> {
        let cell = &data.cell;
        let bodies = cell
            .items
            .parts()
            .iter()
            .enumerate()
            .map(|(i, p)| (TrueItem::Part(i), ItemKind::Part, p.body))
            .chain(
                cell.items
                    .bottles()
                    .iter()
                    .enumerate()
                    .map(|(i, b)| (TrueItem::Bottle(i), ItemKind::Bottle, b.body)),
            );
        let mut items = Vec::new();
        for (item, kind, body) in bodies {
            let Some(pose) = cell.body_pose(body) else {
                continue;
            };
            let centre = Point3::from(pose.translation.vector);
            let at = self.frame.belt_from_world(&centre);
            if (centre.z - cell.belt_top_z).abs() < ON_BELT_M && self.view.contains(at.along_m) {
                items.push((
                    item,
                    ItemSighting {
                        kind,
                        score: 1.0,
                        at,
                        half_length_m: 0.0,
                    },
                ));
            }
        }
        let found: Vec<ItemSighting> = items.iter().map(|(_, s)| *s).collect();
        let ids = self.tracks.update(Self::count(data), &found, &self.view);
        items.into_iter().map(|(item, _)| item).zip(ids).collect()
    }

    /// The open track in view whose predicted footprint lies nearest the photo-eye's beam;
    /// of those that span it, the one seen by the most looks.
    pub(crate) fn nearest_beam(&self, data: &CellData) -> Option<TrackId> {
        let count = Self::count(data);
        let m = self.tracks.params().m_per_count;
        self.tracks
            .tracks()
            .iter()
            .filter(|t| t.is_open() && self.view.contains(t.predicted(count, m).along_m))
            .map(|t| (t.distance_along_m(count, m, 0.0), t.looks, t.id))
            .min_by(|a, b| a.0.total_cmp(&b.0).then(b.1.cmp(&a.1)))
            .map(|(_, _, id)| id)
    }

    /// Where track `id` stands now, world (on the belt's top).
    pub(crate) fn predicted_in_world(&self, data: &CellData, id: TrackId) -> Option<Point3<f64>> {
        let at: BeltPoint = self.tracks.predicted(id, Self::count(data))?;
        Some(self.frame.world_from_belt(&at))
    }

    /// The track `id`.
    pub(crate) fn track(&self, id: TrackId) -> Option<&Track> {
        self.tracks.track(id)
    }

    /// Tracks opened so far.
    pub(crate) fn opened(&self) -> u32 {
        u32::try_from(self.tracks.tracks().len()).unwrap_or(u32::MAX)
    }

    /// The tracks the cell let through (`passed`) that its encoder has carried past the belt's
    /// end (`end_along_m`) by `margin_m`.
    fn carried_off(&self, data: &CellData, passed: &[TrackId], end_along_m: f64) -> Vec<TrackId> {
        let count = Self::count(data);
        let m = self.tracks.params().m_per_count;
        passed
            .iter()
            .copied()
            .filter(|&id| {
                self.tracks
                    .track(id)
                    .is_some_and(|t| t.predicted(count, m).along_m > end_along_m)
            })
            .collect()
    }

    /// In a scenario with a collector, runs the belt until the encoder says every item the
    /// cell let through (`passed`) has been carried off its end, then matches what lies in
    /// the collector to those tracks: each item there with the track whose truth it is, when
    /// the cell expected it (absent otherwise), and each expected track with nothing there as
    /// `none`.
    pub(crate) fn collect(
        &self,
        model: &CellModel,
        data: &mut CellData,
        passed: &[TrackId],
    ) -> Result<Vec<CollectedRecord>, Failure> {
        let Some(collector) = model.catalogue().collector_bin() else {
            return Ok(Vec::new());
        };
        let belt = &model.scenario().conveyor;
        let end_along_m = end_along_m(belt);
        let rearmost = passed
            .iter()
            .filter_map(|&id| self.tracks.predicted(id, Self::count(data)))
            .map(|p| p.along_m)
            .fold(f64::INFINITY, f64::min);
        if rearmost.is_finite() && rearmost < end_along_m + FALL_CLEARANCE_M {
            let travel_m = end_along_m + FALL_CLEARANCE_M - rearmost;
            data.phase = Phase::Pass;
            data.belt.run_at(belt.speed_m_s);
            let start = Self::count(data);
            let limit_s = data.cell.world.time_s() + 2.0 * travel_m / belt.speed_m_s + 2.0;
            while ((Self::count(data) - start) as f64) * self.tracks.params().m_per_count < travel_m
            {
                if data.cell.world.time_s() > limit_s {
                    return Err(Failure::new(
                        FailureReason::Timeout,
                        "the belt did not carry the let-through items to the collector",
                    ));
                }
                data.step(model)?;
            }
            data.belt.run_at(0.0);
            data.settle(model, COLLECTOR_REST_S)?;
        }
        let expected = self.carried_off(data, passed, end_along_m);
        let cell = &data.cell;
        let bin = &cell.bins[collector.0];
        let in_collector = |body| {
            cell.body_pose(body)
                .is_some_and(|p| bin.contains(&p.translation.vector))
        };
        let parts = cell.items.parts().iter().enumerate();
        let bottles = cell.items.bottles().iter().enumerate();
        let arrived = parts
            .filter(|(_, p)| in_collector(p.body))
            .map(|(i, p)| (TrueItem::Part(i), p.instance.type_name.clone()))
            .chain(
                bottles
                    .filter(|(_, b)| in_collector(b.body))
                    .map(|(i, _)| (TrueItem::Bottle(i), "bottle".to_owned())),
            );
        let seen_as = |id: TrackId| self.tracks.track(id).map(|t| t.kind().as_str().to_owned());
        let mut records = Vec::new();
        let mut matched = Vec::new();
        for (item, truth) in arrived {
            let track = self
                .truth_at_eye
                .iter()
                .find(|(id, t)| *t == item && expected.contains(id))
                .map(|(id, _)| *id);
            matched.extend(track);
            records.push(CollectedRecord {
                truth,
                track: track.map(|t| t.0),
                seen_as: track.and_then(seen_as),
            });
        }
        for id in expected.into_iter().filter(|id| !matched.contains(id)) {
            records.push(CollectedRecord {
                truth: "none".to_owned(),
                track: Some(id.0),
                seen_as: seen_as(id),
            });
        }
        Ok(records)
    }
}

/// The belt's downstream end, along its travel from the station, m.
fn end_along_m(belt: &ConveyorSection) -> f64 {
    belt.belt_center_m[0] + belt.length_m / 2.0 - belt.photo_eye_x_m
}

#[cfg(test)]
#[path = "tracked_bottles_tests.rs"]
mod tracked_bottles_tests;

/// Whether `percept` holds an obstacle named `name` whose centre stands within
/// [`TRACKED_SAME_M`] of `point` on the belt's plane.
fn holds_near(percept: &Percept, name: &str, point: &Point3<f64>) -> bool {
    percept.obstacles.iter().any(|o| {
        o.name == name && {
            let d = o.world_from_shape.translation.vector - point.coords;
            d.x.hypot(d.y) < TRACKED_SAME_M
        }
    })
}

/// The catalogue's widest and tallest tube.
fn tube_envelope(model: &CellModel) -> TubeEnvelope {
    let part_types = &model.scenario().part_types;
    TubeEnvelope {
        outer_radius_m: part_types
            .iter()
            .map(|t| t.outer_diameter_mm / 2000.0)
            .fold(0.0, f64::max),
        height_m: part_types
            .iter()
            .map(|t| t.height_mm / 1000.0)
            .fold(0.0, f64::max),
    }
}
