//! The cell's camera perception (`--perception camera`, the product): the pick station rendered
//! as the calibrated camera sees it, the detector's boxes, the paper's metrology inside the part's
//! box, and what those mean in the world through the calibration.
//!
//! Everything here works from the image and the calibration alone; the world is only rendered,
//! never read. Renderers and detectors are expensive to make, so each worker thread takes one from
//! a pool and puts it back: results do not depend on which instance served a trial.

use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

use image::{GrayImage, RgbImage};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};

use crate::detect::{Detection, Detector};
use crate::perception::calibration::{CameraCalibration, PlaneBore};
use crate::perception::roundness::DEFAULT_MAX_UPR;
use crate::perception::{Bore, BoreDetector};
use crate::render::mesh::Mesh;
use crate::render::{CameraRig, Renderer, RendererOptions, Scene, Shot};
use crate::rng::SimRng;
use crate::scenario::Scenario;

/// Share of a part box's side added on every side before the metrology looks inside it.
const BOX_MARGIN: f64 = 0.15;
/// A measured bore diameter further than this from the detected type's nominal one contradicts
/// the detection, m (neighbouring types differ by at least 4 mm).
const TYPE_DIAMETER_TOLERANCE_M: f64 = 0.002;
/// Yaw steps of the lying-bottle search over a full turn.
const LYING_YAW_STEPS: usize = 72;
/// Fixed-point iterations that move a bottle hypothesis until its box centre meets the detection.
const BOTTLE_FIT_ITERATIONS: usize = 12;
/// A bottle hypothesis within this box residual of the best one is kept as well, pixels.
const BOTTLE_AMBIGUITY_PX: f64 = 2.0;

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
        "part_types: type {name:?} is not a class of the detector model {model} (classes: {classes})"
    )]
    UnknownType {
        /// The scenario's type name.
        name: String,
        /// The model file.
        model: PathBuf,
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
}

/// One pose of the bottle that explains its detected box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BottlePose {
    /// The bottle's pose (origin at its base centre, its axis along local z).
    pub world_from_bottle: Isometry3<f64>,
    /// Lying on its side.
    pub lying: bool,
    /// RMS distance between the box this pose projects to and the detected box, pixels.
    pub residual_px: f64,
}

/// What the camera saw of one bottle: every pose that explains its box about equally well.
#[derive(Debug, Clone)]
pub struct BottleSighting {
    /// Index into [`Sighting::detections`].
    pub detection: usize,
    /// The poses, best first.
    pub poses: Vec<BottlePose>,
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
    options: RendererOptions,
    model_path: PathBuf,
    renderers: Mutex<Vec<Renderer>>,
    detectors: Mutex<Vec<Detector>>,
    bore_detector: BoreDetector,
    /// The part types' detector classes, by scenario type index.
    type_of_class: Vec<Option<usize>>,
    bottle_class: Option<usize>,
    /// Vertices of the bottle's mesh in its own frame (the silhouette model of the pose fit).
    bottle_points: Vec<Point3<f64>>,
}

impl std::fmt::Debug for CameraPerception {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CameraPerception")
            .field("rig", &self.rig)
            .field("model_path", &self.model_path)
            .finish_non_exhaustive()
    }
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
    /// The pipeline for `scenario` with the detector model at `model_path`: makes one renderer
    /// and loads the model once, so that a missing adapter or model fails here, before any trial.
    pub fn new(scenario: &Scenario, model_path: PathBuf) -> Result<Self, CameraPerceptionError> {
        let rig = CameraRig::from_scenario(scenario)
            .map_err(|e| CameraPerceptionError::Camera(e.to_string()))?;
        let options = RendererOptions {
            msaa_samples: scenario.camera.msaa_samples,
            supersample: scenario.camera.supersample,
        };
        let renderer = Renderer::new(options)?;
        let detector = Detector::load(&model_path)?;
        let classes = detector.class_names().to_vec();
        let class_index = |name: &str| classes.iter().position(|c| c == name);
        let mut type_of_class = vec![None; classes.len()];
        for (type_index, part_type) in scenario.part_types.iter().enumerate() {
            let Some(class) = class_index(&part_type.name) else {
                return Err(CameraPerceptionError::UnknownType {
                    name: part_type.name.clone(),
                    model: model_path,
                    classes: classes.join(", "),
                });
            };
            type_of_class[class] = Some(type_index);
        }
        // The mesh repeats vertices per face; the silhouette needs each point once.
        let mut bottle_points: Vec<Point3<f64>> =
            Mesh::bottle(scenario.bottle.radius_m, scenario.bottle.height_m)
                .vertices
                .iter()
                .map(|v| v.position)
                .collect();
        bottle_points.sort_by(|a, b| {
            (a.x, a.y, a.z)
                .partial_cmp(&(b.x, b.y, b.z))
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        bottle_points.dedup();
        Ok(Self {
            rig,
            options,
            model_path,
            renderers: Mutex::new(vec![renderer]),
            detectors: Mutex::new(vec![detector]),
            bore_detector: BoreDetector::default(),
            type_of_class,
            bottle_class: class_index("bottle"),
            bottle_points,
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
    ) -> Result<Sighting, CameraPerceptionError> {
        let started = Instant::now();
        let shot = Shot::of_scene(scenario, &self.rig, &scenario.sensor, scene, rng);
        let mut renderer = take(&self.renderers, || Renderer::new(self.options))?;
        let image = shot.render(&mut renderer);
        give_back(&self.renderers, renderer);
        let image = image?;
        let render_ms = started.elapsed().as_secs_f64() * 1e3;

        let started = Instant::now();
        let mut detector = take(&self.detectors, || Detector::load(&self.model_path))?;
        let detections = detector.detect(&image);
        give_back(&self.detectors, detector);
        let detections = detections?;
        let detect_ms = started.elapsed().as_secs_f64() * 1e3;

        let started = Instant::now();
        let gray = image::imageops::grayscale(&image);
        let station_px = self.rig.calibration.project(station_in_world);
        let mut target: Option<(f64, usize)> = None;
        let mut parts = Vec::new();
        let mut bottles = Vec::new();
        for (index, detection) in detections.iter().enumerate() {
            if Some(detection.class_id) == self.bottle_class {
                bottles.push(BottleSighting {
                    detection: index,
                    poses: self.fit_bottle(scenario, &detection.box_px, belt_top_z_m),
                });
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
        let mut target_sighting = None;
        let mut other_parts = Vec::new();
        for (k, (index, type_index, centre_px)) in parts.into_iter().enumerate() {
            let is_target = target.is_some_and(|(_, t)| t == k);
            let face_m = belt_top_z_m + scenario.part_types[type_index].height_mm / 1000.0;
            let calibration = self.rig.calibration.with_end_face_height(face_m);
            // Only the target's bore is measured; other parts are obstacles.
            let bore = if is_target {
                self.measure_in_box(&gray, &detections[index].box_px, &calibration)
            } else {
                None
            };
            let centre_in_world = match &bore {
                Some((_, plane)) => plane.centre_in_world,
                None => match calibration.pixel_to_plane(centre_px[0], centre_px[1]) {
                    Ok(p) => p,
                    Err(_) => continue,
                },
            };
            let nominal_m = scenario.part_types[type_index].bore_diameter_mm / 1000.0;
            let inconsistency = bore.as_ref().and_then(|(_, plane)| {
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
            };
            if is_target {
                target_sighting = Some(sighting);
            } else {
                other_parts.push(sighting);
            }
        }
        let metrology_ms = started.elapsed().as_secs_f64() * 1e3;
        Ok(Sighting {
            image,
            detections,
            target: target_sighting,
            other_parts,
            bottles,
            render_ms,
            detect_ms,
            metrology_ms,
        })
    }

    /// Finds the bore inside a part's box (widened by [`BOX_MARGIN`]) and measures it on the
    /// end-face plane; the bore nearest the box centre wins. `None` when there is none.
    fn measure_in_box(
        &self,
        gray: &GrayImage,
        box_px: &[f32; 4],
        calibration: &CameraCalibration,
    ) -> Option<(Bore, PlaneBore)> {
        let [x0, y0, x1, y1] = box_px.map(f64::from);
        let (mx, my) = ((x1 - x0) * BOX_MARGIN, (y1 - y0) * BOX_MARGIN);
        let clamp = |v: f64, size: u32| v.clamp(0.0, f64::from(size)) as u32;
        let (left, top) = (clamp(x0 - mx, gray.width()), clamp(y0 - my, gray.height()));
        let right = clamp((x1 + mx).ceil() + 1.0, gray.width());
        let bottom = clamp((y1 + my).ceil() + 1.0, gray.height());
        if right <= left || bottom <= top {
            return None;
        }
        let crop =
            image::imageops::crop_imm(gray, left, top, right - left, bottom - top).to_image();
        let bores = self.bore_detector.detect(&crop).ok()?;
        let centre = [(x0 + x1) / 2.0, (y0 + y1) / 2.0];
        let (dx, dy) = (f64::from(left), f64::from(top));
        let bore = bores
            .into_iter()
            .map(|mut bore| {
                bore.centre_px = [bore.centre_px[0] + dx, bore.centre_px[1] + dy];
                for p in &mut bore.edge_points_px {
                    *p = [p[0] + dx, p[1] + dy];
                }
                bore
            })
            .filter(|b| (x0..=x1).contains(&b.centre_px[0]) && (y0..=y1).contains(&b.centre_px[1]))
            .min_by(|a, b| {
                let d = |b: &Bore| (b.centre_px[0] - centre[0]).hypot(b.centre_px[1] - centre[1]);
                d(a).total_cmp(&d(b))
            })?;
        let plane = calibration.measure_on_plane(&bore, DEFAULT_MAX_UPR).ok()?;
        Some((bore, plane))
    }

    /// The box `world_from_bottle` projects to: the extremes of the bottle mesh's vertices.
    fn bottle_box(&self, world_from_bottle: &Isometry3<f64>) -> Option<[f64; 4]> {
        let mut b = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for point in &self.bottle_points {
            let [u, v] = self.rig.calibration.project(&(world_from_bottle * point))?;
            b = [b[0].min(u), b[1].min(v), b[2].max(u), b[3].max(v)];
        }
        Some(b)
    }

    /// Poses of a bottle (standing, or lying at any yaw) that explain its detected box: each
    /// hypothesis is slid over the belt until its projected box is centred on the detection, then
    /// scored by the RMS difference of the four sides. The best pose and every pose within
    /// [`BOTTLE_AMBIGUITY_PX`] of it are returned (a lying bottle seen from above can look the
    /// same at mirrored yaws), best first.
    fn fit_bottle(
        &self,
        scenario: &Scenario,
        box_px: &[f32; 4],
        belt_top_z_m: f64,
    ) -> Vec<BottlePose> {
        let detected = box_px.map(f64::from);
        let (r, h) = (scenario.bottle.radius_m, scenario.bottle.height_m);
        let pose_at = |lying: bool, yaw: f64, x: f64, y: f64| {
            if lying {
                Isometry3::from_parts(
                    Translation3::new(x, y, belt_top_z_m + r),
                    UnitQuaternion::from_euler_angles(0.0, 0.0, yaw)
                        * UnitQuaternion::from_euler_angles(0.0, std::f64::consts::FRAC_PI_2, 0.0),
                ) * Isometry3::translation(0.0, 0.0, -h / 2.0)
            } else {
                Isometry3::from_parts(
                    Translation3::new(x, y, belt_top_z_m),
                    UnitQuaternion::identity(),
                )
            }
        };
        let centre = [
            (detected[0] + detected[2]) / 2.0,
            (detected[1] + detected[3]) / 2.0,
        ];
        let mut hypotheses = vec![(false, 0.0)];
        hypotheses.extend((0..LYING_YAW_STEPS).map(|k| {
            (
                true,
                std::f64::consts::TAU * k as f64 / LYING_YAW_STEPS as f64,
            )
        }));
        let mut poses: Vec<BottlePose> = Vec::new();
        for (lying, yaw) in hypotheses {
            let mid_z = belt_top_z_m + if lying { r } else { h / 2.0 };
            let Ok(start) = self
                .rig
                .calibration
                .pixel_to_height(centre[0], centre[1], mid_z)
            else {
                continue;
            };
            let (mut x, mut y) = (start.x, start.y);
            let mut fitted = None;
            for _ in 0..BOTTLE_FIT_ITERATIONS {
                let Some(b) = self.bottle_box(&pose_at(lying, yaw, x, y)) else {
                    break;
                };
                fitted = Some(b);
                // Move by the centre offset, measured on the plane through the bottle's middle.
                let predicted = [(b[0] + b[2]) / 2.0, (b[1] + b[3]) / 2.0];
                let (Ok(at), Ok(want)) = (
                    self.rig
                        .calibration
                        .pixel_to_height(predicted[0], predicted[1], mid_z),
                    self.rig
                        .calibration
                        .pixel_to_height(centre[0], centre[1], mid_z),
                ) else {
                    break;
                };
                x += want.x - at.x;
                y += want.y - at.y;
            }
            let Some(b) = fitted else {
                continue;
            };
            let residual_px =
                ((0..4).map(|k| (b[k] - detected[k]).powi(2)).sum::<f64>() / 4.0).sqrt();
            poses.push(BottlePose {
                world_from_bottle: pose_at(lying, yaw, x, y),
                lying,
                residual_px,
            });
        }
        poses.sort_by(|a, b| a.residual_px.total_cmp(&b.residual_px));
        let best = poses.first().map_or(0.0, |p| p.residual_px);
        // Keep distinct explanations only: the planner sees a bottle as its bounding cylinder,
        // the same whichever end is the base, so poses whose axes nearly agree are one.
        let mut kept: Vec<BottlePose> = Vec::new();
        for pose in poses {
            if pose.residual_px > best + BOTTLE_AMBIGUITY_PX {
                break;
            }
            let same = kept.iter().any(|k| same_cylinder(k, &pose, h));
            if !same {
                kept.push(pose);
            }
        }
        kept
    }
}

/// Whether two bottle poses occupy nearly the same bounding cylinder (axes within 10 degrees,
/// middles within 1 cm), for a bottle `height_m` tall.
fn same_cylinder(a: &BottlePose, b: &BottlePose, height_m: f64) -> bool {
    if a.lying != b.lying {
        return false;
    }
    let axis = |p: &BottlePose| p.world_from_bottle.rotation * nalgebra::Vector3::z();
    let middle = |p: &BottlePose| p.world_from_bottle * Point3::new(0.0, 0.0, height_m / 2.0);
    axis(a).dot(&axis(b)).abs() > 10f64.to_radians().cos() && (middle(a) - middle(b)).norm() < 0.01
}
