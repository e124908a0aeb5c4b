//! The cell's camera perception (`--perception camera`, the product): the pick station rendered
//! as the calibrated camera sees it, the detector's boxes, the paper's metrology in the target
//! part's area of interest (its box read again at the sensor's full pitch, `[camera]
//! roi_scale` times the frame's), and what those mean in the world through the calibration.
//!
//! Everything here works from the images and the calibration alone; the world is only rendered,
//! never read. Each worker thread takes a renderer from a pool and puts it back; the pool's
//! renderers share one device and its compiled shaders ([`Renderer::sibling`]), and the detector is
//! loaded once per process and shared ([`Detector::shared`]). Results do not depend on which
//! instance served a trial.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use image::RgbImage;
use nalgebra::Point3;

pub use super::area_of_interest::{
    find_in_window, measure_found, measure_in_window, part_window, tube_from_box,
};
use super::area_of_interest::{tube_type_from_box, union_of_overlapping};
use super::bore_floor::station_bore_params;
use super::bottle_evidence::bottle_sightings;
use super::bottle_fit::{BottleFitter, BottlePose};
use super::bottle_unboxed::BeltBand;
use super::measured_tube::{BeltScene, MeasuredTube};
use super::sighting_percept::touched_borders;
use super::type_reader::TypeReader;
use crate::camera::CameraCalibration;
use crate::detect::{
    Detection, Detector, DetectorModel, FOREIGN_CLASSES, SharedDetector, is_foreign_class,
};
use crate::perception::calibration::PlaneBore;
use crate::perception::{Bore, BoreDetector};
use crate::render::{CameraRig, Renderer, RendererOptions, Scene, Shot};
use crate::rng::SimRng;
use crate::scenario::{Scenario, TypeBy};

/// A detector box counts as covering a point of the photo-eye's beam within this margin, px.
const BEAM_MARGIN_PX: f64 = 2.0;
/// Foreshortening (image roundness over radius of a round bore seen off the vertical) the bore
/// finder's own circularity check already allows for: an overhead camera's parts, up to about
/// 20 degrees off its axis, keep the finder as it is.
const FORESHORTENING_ALLOWANCE: f64 = 0.07;
/// A measured bore diameter further than this from the detected type's nominal one contradicts
/// the detection, m (neighbouring types differ by at least 4 mm).
const TYPE_DIAMETER_TOLERANCE_M: f64 = 0.002;

/// Why the camera pipeline could not run at all (as opposed to finding nothing).
#[derive(Debug, thiserror::Error)]
pub enum CameraPerceptionError {
    /// No renderer could be made or a frame could not be rendered.
    #[error("camera: {0}")]
    Render(#[from] crate::render::RenderError),
    /// The detector model could not be loaded or run.
    #[error("detector: {0}")]
    Detect(#[from] crate::detect::DetectError),
    /// The scenario's camera cannot see the pick station.
    #[error("camera: {0}")]
    Camera(String),
    /// A scenario part type that the detector was not trained on.
    #[error(
        "perception.type_by: \"detector\" needs a model whose classes name the scenario's types, \
         and type {name:?} is not a class of the detector model {model} (classes: {classes}); \
         name the type by measurement (type_by = \"measurement\", the default)"
    )]
    UnknownType {
        /// The scenario's type name.
        name: String,
        /// The detector's network.
        model: DetectorModel,
        /// The model's classes.
        classes: String,
    },
}

/// What the camera saw of one part.
#[derive(Debug, Clone)]
pub struct PartSighting {
    /// Index into [`Sighting::detections`].
    pub detection: usize,
    /// Index of the detected type in the scenario's `part_types`.
    pub type_index: usize,
    /// End-face centre in the world: the measured bore centre, or the box centre on the end-face
    /// plane when no bore was measured.
    pub centre_in_world: Point3<f64>,
    /// The bore as fitted in the image (full-image pixels) and measured on the end-face plane.
    pub bore: Option<(Bore, PlaneBore)>,
    /// Set when the measurement contradicts the detected type (the sorter rejects such a part).
    pub inconsistency: Option<String>,
    /// Set when the type was to be named by measurement and no type, or several, fit (the
    /// sorter rejects such a part); `type_index` is then only the geometry it is handled with.
    pub unidentified: Option<String>,
}

/// What the camera saw of one bottle: every pose that explains its box about equally well.
#[derive(Debug, Clone)]
pub struct BottleSighting {
    /// Index into [`Sighting::detections`].
    pub detection: usize,
    /// The poses, best first.
    pub poses: Vec<BottlePose>,
}

/// How the look picks the part whose bore it measures.
#[derive(Debug, Clone, PartialEq)]
pub enum TargetRule {
    /// The part whose box centre lies nearest the station's pixel (a single-part trial: the
    /// part is the only one at the station).
    NearestStation,
    /// Whatever breaks the photo-eye's beam, given as points along it in the world: among the
    /// detections whose boxes cover a projected beam point, the one nearest the station's pixel.
    /// When that is a bottle no bore is measured.
    AtBeam(Vec<Point3<f64>>),
}

/// What the camera takes to be standing at the pick station.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StationItem {
    /// A part: [`Sighting::target`].
    Part,
    /// A bottle: [`Sighting::bottles`]`[index]`.
    Bottle(usize),
}

/// One look at the pick station.
#[derive(Debug, Clone)]
pub struct Sighting {
    /// The image as the sensor delivered it.
    pub image: RgbImage,
    /// The detector's boxes, in image pixels.
    pub detections: Vec<Detection>,
    /// The part at the pick station, when one was detected.
    pub target: Option<PartSighting>,
    /// Other parts in view (obstacles), their centres on the end-face plane from their boxes.
    pub other_parts: Vec<PartSighting>,
    /// Bottles in view.
    pub bottles: Vec<BottleSighting>,
    /// What stands at the station, by the look's [`TargetRule`]; `None` when nothing does.
    pub at_station: Option<StationItem>,
    /// Wall-clock cost of rendering, detection and metrology, ms.
    pub render_ms: f64,
    /// Detector time, ms.
    pub detect_ms: f64,
    /// Metrology time (bore finding and fits, bottle pose fits), ms.
    pub metrology_ms: f64,
}

/// The camera pipeline shared by the worker threads of a batch.
pub struct CameraPerception {
    rig: CameraRig,
    roi_scale: u32,
    /// The binning the detector reads the frame through ([`crate::render::reader_bin`]).
    frame_bin: u32,
    model: DetectorModel,
    renderers: Mutex<Vec<Renderer>>,
    /// The renderers' options: a look that finds every pooled renderer in use takes another on
    /// the process's device for them ([`Renderer::shared`]).
    options: RendererOptions,
    detector: Arc<SharedDetector>,
    bore_detector: BoreDetector,
    /// The scenario type each detector class names (by measurement: the one of that name, or
    /// the bulkiest, until the target is measured).
    type_of_class: Vec<Option<usize>>,
    type_reader: TypeReader,
    bottle_class: Option<usize>,
    bottle_fitter: BottleFitter,
}

impl std::fmt::Debug for CameraPerception {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CameraPerception")
            .field("rig", &self.rig)
            .field("model", &self.model)
            .finish_non_exhaustive()
    }
}

/// The bore finder for a part whose box is `box_px` in `calibration`'s frame, standing on a
/// plane at `z_m`: `shared`, its circularity check widened by the foreshortening of an end face
/// seen at the part's angle from the vertical (a round bore images as an ellipse of axis ratio
/// `cos(angle)`; the plane measurement undoes it, the image check must let it through). The
/// closed loop and `twincell calibrate`'s study both find bores through it.
pub(super) fn bore_detector_at<'a>(
    shared: &'a BoreDetector,
    calibration: &CameraCalibration,
    box_px: &[f64; 4],
    z_m: f64,
) -> std::borrow::Cow<'a, BoreDetector> {
    let [x0, y0, x1, y1] = *box_px;
    let Ok(on_plane) = calibration.pixel_to_height((x0 + x1) / 2.0, (y0 + y1) / 2.0, z_m) else {
        return std::borrow::Cow::Borrowed(shared);
    };
    let ray = on_plane - calibration.origin_in_world();
    let cos = (-ray.z / ray.norm()).clamp(0.0, 1.0);
    let foreshortening = 2.0 * (1.0 - cos) / (1.0 + cos);
    if foreshortening <= FORESHORTENING_ALLOWANCE {
        return std::borrow::Cow::Borrowed(shared);
    }
    let mut params = shared.params;
    params.max_roundness_ratio += foreshortening - FORESHORTENING_ALLOWANCE;
    std::borrow::Cow::Owned(BoreDetector::new(params))
}

/// Takes an instance from `pool`, or makes one.
fn take<T, E>(pool: &Mutex<Vec<T>>, make: impl FnOnce() -> Result<T, E>) -> Result<T, E> {
    let pooled = pool.lock().ok().and_then(|mut items| items.pop());
    match pooled {
        Some(item) => Ok(item),
        None => make(),
    }
}

/// Puts an instance back into `pool`.
fn give_back<T>(pool: &Mutex<Vec<T>>, item: T) {
    if let Ok(mut items) = pool.lock() {
        items.push(item);
    }
}

impl CameraPerception {
    /// The pipeline for `scenario` with the detector's network `model`: takes a renderer on the
    /// process's device and the process's detector for `model` (making them if no pipeline has),
    /// so that a missing adapter or model fails here, before any trial.
    pub fn new(scenario: &Scenario, model: DetectorModel) -> Result<Self, CameraPerceptionError> {
        let rig = CameraRig::from_scenario(scenario)
            .map_err(|e| CameraPerceptionError::Camera(e.to_string()))?;
        let options = RendererOptions {
            msaa_samples: scenario.camera.msaa_samples,
            supersample: scenario.camera.supersample,
        };
        // The shipped network loads on a thread of its own from here: it overlaps the
        // renderer's making (the device, its pipelines) as well as the first trials.
        let detector = Detector::shared(&model)?;
        let renderer = Renderer::shared(options)?;
        let classes = detector.class_names().to_vec();
        let class_index = |name: &str| classes.iter().position(|c| c == name);
        let type_reader = TypeReader::new(scenario);
        let mut type_of_class = vec![None; classes.len()];
        if type_reader.type_by() == TypeBy::Measurement {
            // The detector only has to find a tube (the shipped one's `tube` class; any class
            // but the foreign object's in a model trained per catalogue). Parts other than the
            // target are not measured: as obstacles they take the type the class names where it
            // is one of the scenario's, else the bulkiest (the larger obstacle).
            for (class, name) in classes.iter().enumerate() {
                if !is_foreign_class(name) {
                    let named = scenario.part_types.iter().position(|t| &t.name == name);
                    type_of_class[class] = Some(named.unwrap_or(type_reader.bulkiest()));
                }
            }
        }
        let by_detector = type_reader.type_by() == TypeBy::Detector;
        for (type_index, part_type) in scenario
            .part_types
            .iter()
            .enumerate()
            .filter(|_| by_detector)
        {
            let Some(class) = class_index(&part_type.name) else {
                return Err(CameraPerceptionError::UnknownType {
                    name: part_type.name.clone(),
                    model,
                    classes: classes.join(", "),
                });
            };
            type_of_class[class] = Some(type_index);
        }
        let tallest_part_m = scenario
            .part_types
            .iter()
            .map(|t| t.height_mm / 1e3)
            .fold(0.0, f64::max);
        let bottle_fitter = BottleFitter::new(rig.calibration, &scenario.bottle)
            .with_part_height(tallest_part_m)
            .with_belt(BeltBand::of(&scenario.conveyor))
            .with_frame(rig.width_px, rig.height_px);
        Ok(Self {
            rig,
            roi_scale: scenario.camera.roi_scale,
            frame_bin: crate::render::reader_bin(
                (rig.width_px, rig.height_px),
                (detector.card().input_width, detector.card().input_height),
            ),
            model,
            options,
            renderers: Mutex::new(vec![renderer]),
            detector,
            bore_detector: BoreDetector::new(station_bore_params(
                scenario,
                &rig.calibration,
                scenario.camera.roi_scale,
            )),
            type_of_class,
            type_reader,
            bottle_class: FOREIGN_CLASSES.iter().find_map(|name| class_index(name)),
            bottle_fitter,
        })
    }

    /// The calibrated camera.
    pub fn rig(&self) -> &CameraRig {
        &self.rig
    }

    /// Renders `scene` with the frame's realism drawn from `rng`, detects, and measures. The part
    /// whose box centre lies nearest `station_in_world`'s pixel is the target; parts and bottles
    /// stand on the belt's top surface at `belt_top_z_m`.
    pub fn look(
        &self,
        scenario: &Scenario,
        scene: Scene,
        rng: &mut SimRng,
        station_in_world: &Point3<f64>,
        belt_top_z_m: f64,
        rule: TargetRule,
    ) -> Result<Sighting, CameraPerceptionError> {
        let mut renderer = take(&self.renderers, || Renderer::shared(self.options))?;
        let sighting = self.look_with(
            &mut renderer,
            scenario,
            scene,
            rng,
            station_in_world,
            belt_top_z_m,
            &rule,
        );
        give_back(&self.renderers, renderer);
        sighting
    }

    /// [`Self::look`] on one renderer: the frame and the target's area of interest render from
    /// one upload of the scene.
    #[allow(clippy::too_many_arguments)]
    fn look_with(
        &self,
        renderer: &mut Renderer,
        scenario: &Scenario,
        scene: Scene,
        rng: &mut SimRng,
        station_in_world: &Point3<f64>,
        belt_top_z_m: f64,
        rule: &TargetRule,
    ) -> Result<Sighting, CameraPerceptionError> {
        let started = Instant::now();
        let shot = Shot::of_scene(scenario, &self.rig, &scenario.sensor, scene, rng);
        let gpu = renderer.upload(&shot.scene);
        let frame = shot.render_binned_frame(renderer, &gpu, self.frame_bin)?;
        let mut render_ms = started.elapsed().as_secs_f64() * 1e3;

        let started = Instant::now();
        let detections = self.detector.detect_binned(&frame.binned, frame.bin)?;
        let image = frame.into_frame();
        let detect_ms = started.elapsed().as_secs_f64() * 1e3;

        let started = Instant::now();
        let mut window_render_ms = 0.0;
        let station_px = self.rig.calibration.project(station_in_world);
        let mut target: Option<(f64, usize)> = None;
        let mut parts = Vec::new();
        let mut bottles = Vec::new();
        let beam_px: Vec<[f64; 2]> = match rule {
            TargetRule::NearestStation => Vec::new(),
            TargetRule::AtBeam(points) => points
                .iter()
                .filter_map(|p| self.rig.calibration.project(p))
                .collect(),
        };
        let covers_beam = |box_px: &[f64; 4]| {
            let [x0, y0, x1, y1] = *box_px;
            let m = BEAM_MARGIN_PX;
            beam_px
                .iter()
                .any(|p| (x0 - m..=x1 + m).contains(&p[0]) && (y0 - m..=y1 + m).contains(&p[1]))
        };
        let station_distance = |box_px: &[f64; 4]| {
            let [x0, y0, x1, y1] = *box_px;
            station_px.map(|[u, v]| ((x0 + x1) / 2.0 - u).hypot((y0 + y1) / 2.0 - v))
        };
        // At the beam: the nearest covering detection, part or bottle.
        let mut at_beam: Option<(f64, Option<usize>, Option<usize>)> = None;
        for (index, detection) in detections.iter().enumerate() {
            let box_px = detection.box_px.map(f64::from);
            let is_bottle = Some(detection.class_id) == self.bottle_class;
            let is_part = self
                .type_of_class
                .get(detection.class_id)
                .copied()
                .flatten()
                .is_some();
            if matches!(rule, TargetRule::AtBeam(_))
                && (is_bottle || is_part)
                && covers_beam(&box_px)
                && let Some(d) = station_distance(&box_px)
                && at_beam.is_none_or(|(best, _, _)| d < best)
            {
                let (part, bottle) = if is_bottle {
                    (None, Some(bottles.len()))
                } else {
                    (Some(parts.len()), None)
                };
                at_beam = Some((d, part, bottle));
            }
            if is_bottle {
                bottles.push((index, detection.box_px.map(f64::from)));
                continue;
            }
            let Some(type_index) = self
                .type_of_class
                .get(detection.class_id)
                .copied()
                .flatten()
            else {
                continue;
            };
            let [x0, y0, x1, y1] = detection.box_px.map(f64::from);
            let centre_px = [(x0 + x1) / 2.0, (y0 + y1) / 2.0];
            if let Some([u, v]) = station_px {
                let d = (centre_px[0] - u).hypot(centre_px[1] - v);
                if target.is_none_or(|(best, _)| d < best) {
                    target = Some((d, parts.len()));
                }
            }
            parts.push((index, type_index, centre_px));
        }
        let frame_px = (self.rig.width_px, self.rig.height_px);
        let mut at_station = target.map(|_| StationItem::Part);
        // The bottle box at the beam, if that is what is there (its sighting is fitted below).
        let mut beam_bottle = None;
        if matches!(rule, TargetRule::AtBeam(_)) {
            (target, at_station) = (None, None);
            if let Some((d, part, bottle)) = at_beam {
                if let Some(part) = part {
                    target = Some((d, part));
                    at_station = Some(StationItem::Part);
                }
                beam_bottle = bottle;
            }
        }
        let mut target_sighting = None;
        let mut other_parts = Vec::new();
        let part_boxes: Vec<[f64; 4]> = parts
            .iter()
            .map(|(index, _, _)| detections[*index].box_px.map(f64::from))
            .collect();
        for (k, (index, type_index, centre_px)) in parts.into_iter().enumerate() {
            let is_target = target.is_some_and(|(_, t)| t == k);
            // Only the target's bore is measured, in its area of interest; other parts are
            // obstacles.
            let box_px = detections[index].box_px.map(f64::from);
            // A box the frame's border cuts is not placed from its silhouette: the part is
            // jogged into view and looked at again (`Sighting::border_jog_m`).
            let cut = !touched_borders(&box_px, frame_px).is_empty();
            let mut find_in = |box_px: &[f64; 4]| -> Result<_, CameraPerceptionError> {
                let Some(window) = part_window(box_px, frame_px, self.roi_scale) else {
                    return Ok(None);
                };
                let rendered = Instant::now();
                let window_image = shot.render_window(renderer, &gpu, &window)?;
                window_render_ms += rendered.elapsed().as_secs_f64() * 1e3;
                let gray = image::imageops::grayscale(&window_image);
                let bore_detector = bore_detector_at(
                    &self.bore_detector,
                    &self.rig.calibration,
                    box_px,
                    belt_top_z_m,
                );
                Ok(find_in_window(&bore_detector, &gray, &window, box_px)
                    .map(|bore| (bore, window)))
            };
            let mut found = if is_target { find_in(&box_px)? } else { None };
            // The same part boxed twice (a box on its end face and one on the whole tube, say,
            // from a steep camera): the bore may lie outside the smaller box or be cut by its
            // window, so it is sought again in the union of the boxes that overlap the target's.
            if is_target
                && found.is_none()
                && let Some(union) = union_of_overlapping(&box_px, &part_boxes)
            {
                found = find_in(&union)?;
            }
            let (type_index, unidentified) = match self.type_reader.type_by() {
                TypeBy::Detector => (type_index, None),
                TypeBy::Measurement if is_target => {
                    let decision = match &found {
                        Some((bore, window)) => self.type_reader.decide(
                            bore,
                            &window.calibration(&self.rig.calibration),
                            belt_top_z_m,
                        ),
                        None => {
                            let mut decision = self.type_reader.unmeasured();
                            // Handled as the catalogue's tube whose silhouette fills the box.
                            let (calibration, kinds) =
                                (&self.rig.calibration, &scenario.part_types);
                            if let Some((best, _)) = (!cut)
                                .then(|| {
                                    tube_type_from_box(calibration, &box_px, belt_top_z_m, kinds)
                                })
                                .flatten()
                            {
                                decision.type_index = best;
                            }
                            decision
                        }
                    };
                    (decision.type_index, decision.unidentified)
                }
                TypeBy::Measurement => (type_index, None),
            };
            let face_m = belt_top_z_m + scenario.part_types[type_index].height_mm / 1000.0;
            let calibration = self.rig.calibration.with_end_face_height(face_m);
            let bore = found.and_then(|(bore, window)| measure_found(bore, &window, &calibration));
            let centre_in_world = match &bore {
                Some((_, plane)) => plane.centre_in_world,
                // Placed from its box: as the tube whose silhouette fills it, unless the frame's
                // border cuts the box (the part is then jogged into view and looked at again).
                None => {
                    let kind = &scenario.part_types[type_index];
                    let (radius_m, height_m) = (kind.outer_diameter_mm / 2e3, kind.height_mm / 1e3);
                    let rig_calibration = &self.rig.calibration;
                    let from_box = (!cut)
                        .then(|| {
                            tube_from_box(
                                rig_calibration,
                                &box_px,
                                belt_top_z_m,
                                radius_m,
                                height_m,
                            )
                        })
                        .flatten();
                    match from_box {
                        Some(p) => p,
                        None => match calibration.pixel_to_plane(centre_px[0], centre_px[1]) {
                            Ok(p) => p,
                            Err(_) => continue,
                        },
                    }
                }
            };
            let nominal_m = scenario.part_types[type_index].bore_diameter_mm / 1000.0;
            let by_detector = self.type_reader.type_by() == TypeBy::Detector;
            let inconsistency = bore
                .as_ref()
                .filter(|_| by_detector)
                .and_then(|(_, plane)| {
                    ((plane.diameter_m - nominal_m).abs() > TYPE_DIAMETER_TOLERANCE_M).then(|| {
                        format!(
                            "measured bore {:.2} mm contradicts the detected {} ({:.0} mm)",
                            plane.diameter_m * 1e3,
                            scenario.part_types[type_index].name,
                            nominal_m * 1e3
                        )
                    })
                });
            let sighting = PartSighting {
                detection: index,
                type_index,
                centre_in_world,
                bore,
                inconsistency,
                unidentified,
            };
            if is_target {
                target_sighting = Some(sighting);
            } else {
                other_parts.push(sighting);
            }
        }
        // The bottles, fitted clear of the tubes whose bores were measured; a single part's look
        // also looks on the belt for bottles the detector missed.
        let tubes =
            MeasuredTube::of_sightings(target_sighting.iter().chain(&other_parts), scenario);
        let single = matches!(rule, TargetRule::NearestStation);
        let belt = BeltScene::of_look(scenario, belt_top_z_m, single, &tubes);
        let fitter = &self.bottle_fitter;
        let (bottles, holder) =
            bottle_sightings(fitter, &bottles, &detections, &image, frame_px, &belt);
        if let Some(bottle) = beam_bottle {
            at_station = Some(StationItem::Bottle(holder[bottle]));
        }
        let metrology_ms = started.elapsed().as_secs_f64() * 1e3 - window_render_ms;
        render_ms += window_render_ms;
        // The scene's buffers are freed while no sibling renderer draws (`Renderer::hold_device`).
        drop((gpu, renderer.hold_device()));
        Ok(Sighting {
            image,
            detections,
            target: target_sighting,
            other_parts,
            bottles,
            at_station,
            render_ms,
            detect_ms,
            metrology_ms,
        })
    }
}
