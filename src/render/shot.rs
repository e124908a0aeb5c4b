//! One camera shot of the pick station: the scenario's camera, a scene drawn the way the
//! scenario draws trials (part type, roundness, position; the bottle standing or lying), and the
//! realism drawn for the frame (lights, stains and dirt, pose jitter, sensor effects), plus the
//! ground truth of every labelled object as the rendered camera sees it.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::Serialize;

use super::error::RenderError;
use super::renderer::{Exposure, GpuScene, Light, MAX_STAIN_BLOBS, Renderer, StainBlob};
use super::scene::{ObjectKind, Scene, SceneObject};
use super::sensor::SensorDraw;
use crate::camera::CameraCalibration;
use crate::cell::{Cell, CellError, CellModel};
use crate::rng::SimRng;
use crate::scenario::{Scenario, SensorSection};

/// Salt that keeps shot streams apart from trial streams of the same seed.
const SHOT_SALT: u64 = 0x43_414D_4552_4131;
/// Objects whose box in the image is narrower than this (a sliver at the border) get no label.
pub const MIN_LABEL_SIDE_PX: u32 = 4;
/// Blobs per oil stain (an irregular patch of overlapping lobes).
const STAIN_LOBES: u64 = 3;

/// Why a shot could not be made.
#[derive(Debug, thiserror::Error)]
pub enum ShotError {
    /// The cell could not be built.
    #[error(transparent)]
    Cell(#[from] CellError),
    /// Rendering failed.
    #[error(transparent)]
    Render(#[from] RenderError),
    /// The scenario's camera cannot see the pick station.
    #[error("scenario: camera: {0}")]
    Camera(String),
}

/// The scenario's camera as calibrated: where it is and what it is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraRig {
    /// The calibration perception gets (end-face plane at the belt's top until a part is known).
    pub calibration: CameraCalibration,
    /// Image width, pixels.
    pub width_px: u32,
    /// Image height, pixels.
    pub height_px: u32,
}

impl CameraRig {
    /// The camera of `scenario`'s `[camera]` section.
    pub fn from_scenario(scenario: &Scenario) -> Result<Self, ShotError> {
        let camera = &scenario.camera;
        let (eye, target) = camera.eye_and_target(&scenario.conveyor);
        let looking =
            CameraCalibration::look_at(&Point3::from(eye), &Point3::from(target), &Vector3::x())
                .ok_or_else(|| {
                    ShotError::Camera("the camera looks along the belt's axis".into())
                })?;
        // The roll turns the camera about its own z axis, the optical axis.
        let world_from_camera = if camera.roll_deg == 0.0 {
            looking
        } else {
            looking
                * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), camera.roll_deg.to_radians())
        };
        let [w, h] = camera.resolution_px;
        Ok(Self {
            calibration: CameraCalibration::from_fov(
                w,
                h,
                camera.horizontal_fov_deg.to_radians(),
                world_from_camera,
                scenario.conveyor.belt_center_m[2],
            ),
            width_px: w,
            height_px: h,
        })
    }

    /// The same camera at another resolution (same field of view, principal point centred).
    pub fn with_resolution(&self, width_px: u32, height_px: u32) -> Self {
        let hfov = 2.0 * (f64::from(self.width_px) / 2.0 / self.calibration.fx_px).atan();
        Self {
            calibration: CameraCalibration::from_fov(
                width_px,
                height_px,
                hfov,
                self.calibration.world_from_camera,
                self.calibration.end_face_height_m,
            ),
            width_px,
            height_px,
        }
    }
}

/// Ground truth of one labelled object in a rendered image.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ObjectTruth {
    /// Class name: the part type or `bottle`.
    pub class: String,
    /// Class index: the part type's index in the scenario, the bottle after them.
    pub class_id: usize,
    /// Pixels covered by the object's projected silhouette, clipped to the image: first and last
    /// column and row, inclusive (pixel centres at integers).
    pub bbox_px: [u32; 4],
    /// The object's index in the scene.
    pub object_index: usize,
    /// The object's position in the world (a part's centre, a bottle's base), m.
    pub position_m: [f64; 3],
    /// For parts: the true bore.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bore: Option<BoreTruth>,
}

/// A part's true bore as the camera sees it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BoreTruth {
    /// Projected bore centre (end-face plane), pixels.
    pub centre_px: [f64; 2],
    /// Mean projected radius, pixels.
    pub radius_px: f64,
    /// Projected `Rmax - Rmin` about the projected centre, pixels.
    pub roundness_px: f64,
    /// Mean bore radius, mm.
    pub radius_mm: f64,
    /// True roundness `Rmax - Rmin`, mm.
    pub roundness_mm: f64,
    /// Height of the end face above the world origin, m.
    pub end_face_height_m: f64,
}

/// A staged shot, ready to render.
#[derive(Debug, Clone)]
pub struct Shot {
    /// The scene.
    pub scene: Scene,
    /// The exposure: the real camera pose, lights and stains.
    pub exposure: Exposure,
    /// The calibrated camera perception is given (without the pose jitter).
    pub rig: CameraRig,
    /// The sensor's effects for this frame.
    pub sensor: SensorDraw,
}

impl Shot {
    /// Stages shot `index` of `model`'s scenario: the cell built as for a trial (its own seed
    /// stream),
    /// the part moved to a random place under the camera with the bottle keeping its drawn
    /// offset from it, and the frame's realism from `sensor`.
    pub fn pick_station(
        model: &CellModel,
        rig: &CameraRig,
        sensor: &SensorSection,
        index: u64,
    ) -> Result<Self, ShotError> {
        let scenario = model.scenario();
        let mut rng = SimRng::derive(scenario.seed ^ SHOT_SALT, index);
        let cell = Cell::build(model, &mut rng)?;
        let mut scene = Scene::from_cell(&cell, scenario);
        let Some(first) = cell.items.parts().first() else {
            return Err(ShotError::Camera("the cell has no part".into()));
        };
        let (part, part_body) = (&first.instance, first.body);
        let Some(world_from_part) = cell.body_pose(part_body) else {
            return Err(ShotError::Camera("the part has no body".into()));
        };
        let face_z = world_from_part.translation.z + part.height_m / 2.0;
        let (x_low, x_high) = visible_x_range(rig, face_z, part.outer_radius_m + 0.01)?;
        let x = rng.range(x_low, x_high);
        let offset = Vector3::new(x - world_from_part.translation.x, 0.0, 0.0);
        scene.translate_body(part_body, &offset);
        for bottle in cell.items.bottles() {
            scene.translate_body(bottle.body, &offset);
        }
        Ok(Self::of_scene(scenario, rig, sensor, scene, &mut rng))
    }

    /// A shot of `scene` as it stands (the closed loop's view of the live cell): the frame's
    /// camera pose jitter, lights, stains and sensor effects drawn from `rng`.
    pub fn of_scene(
        scenario: &Scenario,
        rig: &CameraRig,
        sensor: &SensorSection,
        scene: Scene,
        rng: &mut SimRng,
    ) -> Self {
        let exposure = draw_exposure(scenario, rig, sensor, &scene, rng);
        let sensor_draw = SensorDraw::draw(sensor, rng);
        Self {
            scene,
            exposure,
            rig: *rig,
            sensor: sensor_draw,
        }
    }

    /// Renders the shot: the image as the sensor delivers it, at the renderer's MSAA.
    pub fn render(&self, renderer: &mut Renderer) -> Result<image::RgbImage, RenderError> {
        let gpu = renderer.upload(&self.scene);
        let mut image = renderer.render(&gpu, &self.exposure)?;
        self.sensor.apply(&mut image);
        Ok(image)
    }

    /// Renders the frame a look's detector reads, from the shot's scene as already uploaded to
    /// `renderer` ([`Renderer::upload`]), so that the frame and its areas of interest share one
    /// upload: the image as the sensor delivers it, drawn with one sample per pixel.
    ///
    /// The detector reads the frame through block means (4 x 4 frame pixels per input pixel at
    /// 1280 x 960), which already average 16 samples per input pixel; MSAA's four per frame
    /// pixel cost more than half of the frame's render and barely move what it reads. The
    /// metrology reads its areas of interest ([`Shot::render_window`]) at full MSAA, where the
    /// sub-pixel edges matter.
    pub fn render_uploaded(
        &self,
        renderer: &mut Renderer,
        gpu: &GpuScene,
    ) -> Result<image::RgbImage, RenderError> {
        let blur = self.scene.blur.as_ref();
        let single = Renderer::render_single_sample;
        let mut image = super::motion_blur::render(renderer, gpu, &self.exposure, blur, single)?;
        self.sensor.apply(&mut image);
        Ok(image)
    }

    /// Ground truth of the labelled objects (parts and the bottle) in the image; an object cut
    /// to a sliver under [`MIN_LABEL_SIDE_PX`] by the image border is left out.
    pub fn truth(&self, scenario: &Scenario) -> Vec<ObjectTruth> {
        let camera = &self.exposure.camera;
        let (w, h) = (self.exposure.width_px, self.exposure.height_px);
        let mut truths = Vec::new();
        for (index, object) in self.scene.objects.iter().enumerate() {
            let (class, class_id, bore) = match &object.kind {
                ObjectKind::Part(part) => {
                    let face_z = object.world_from_object.translation.z + part.height_m / 2.0;
                    let bore = bore_truth(camera, object, part, face_z);
                    (part.type_name.clone(), part.type_index, bore)
                }
                ObjectKind::Bottle => ("bottle".to_string(), scenario.part_types.len(), None),
                ObjectKind::Scenery => continue,
            };
            let Some(bbox_px) = silhouette_box(camera, object, w, h) else {
                continue;
            };
            let t = object.world_from_object.translation.vector;
            truths.push(ObjectTruth {
                class,
                class_id,
                bbox_px,
                object_index: index,
                position_m: [t.x, t.y, t.z],
                bore,
            });
        }
        truths
    }
}

/// The range of part-centre x under the camera at height `z`, keeping `margin_m` inside the
/// image's left and right edges on the row through the principal point.
fn visible_x_range(rig: &CameraRig, z: f64, margin_m: f64) -> Result<(f64, f64), ShotError> {
    let c = &rig.calibration;
    let edge = |u: f64| {
        c.pixel_to_height(u, c.cy_px, z)
            .map(|p| p.x)
            .map_err(|e| ShotError::Camera(e.to_string()))
    };
    let (a, b) = (edge(0.0)?, edge(f64::from(rig.width_px) - 1.0)?);
    let (low, high) = (a.min(b) + margin_m, a.max(b) - margin_m);
    if low >= high {
        return Err(ShotError::Camera(
            "the field of view is too narrow for a part at the pick station".into(),
        ));
    }
    Ok((low, high))
}

/// Draws the frame's camera pose jitter, lights and stains.
fn draw_exposure(
    scenario: &Scenario,
    rig: &CameraRig,
    sensor: &SensorSection,
    scene: &Scene,
    rng: &mut SimRng,
) -> Exposure {
    let gaussian3 = |rng: &mut SimRng, sigma: f64| {
        Vector3::new(rng.normal(), rng.normal(), rng.normal()) * sigma
    };
    let shift = gaussian3(rng, sensor.pose_jitter_m);
    let tilt = gaussian3(rng, sensor.pose_jitter_deg.to_radians());
    let jitter = Isometry3::from_parts(
        Translation3::from(shift),
        UnitQuaternion::from_scaled_axis(tilt),
    );
    let mut camera = rig.calibration;
    camera.world_from_camera *= jitter;

    let lights = scenario
        .lighting
        .lights
        .iter()
        .map(|spec| {
            let direction = Vector3::from(spec.direction).normalize();
            let any = if direction.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            };
            let axis = direction.cross(&any).normalize();
            let spin = UnitQuaternion::from_axis_angle(
                &nalgebra::Unit::new_normalize(direction),
                rng.range(0.0, std::f64::consts::TAU),
            );
            let angle = rng.range(0.0, sensor.light_jitter_deg.to_radians());
            let tilt =
                UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(spin * axis), angle);
            let scale = 1.0 + rng.range(-sensor.intensity_jitter, sensor.intensity_jitter);
            Light {
                direction_in_world: tilt * direction,
                intensity: spec.intensity * scale,
            }
        })
        .collect();

    let mut stains = Vec::new();
    if let Some((object, part)) = scene.part() {
        let top = part.height_m / 2.0;
        let bore_r = part.bore.mean_diameter_m() / 2.0;
        let on_face = |rng: &mut SimRng, r_low: f64| {
            let r = rng.range(r_low, part.outer_radius_m);
            let t = rng.range(0.0, std::f64::consts::TAU);
            object.world_from_object * Point3::new(r * t.cos(), r * t.sin(), top)
        };
        for _ in 0..rng.below(u64::from(sensor.max_stains) + 1) {
            let centre = on_face(rng, bore_r);
            for _ in 0..STAIN_LOBES {
                let lobe = centre + Vector3::new(rng.normal(), rng.normal(), 0.0) * 0.0015;
                stains.push(StainBlob {
                    centre_in_world: lobe,
                    radius_m: rng.range(0.0015, 0.004),
                    transmission: rng.range(0.55, 0.8),
                    soft_edge: 0.6,
                });
            }
        }
        for _ in 0..rng.below(u64::from(sensor.max_dirt) + 1) {
            stains.push(StainBlob {
                centre_in_world: on_face(rng, bore_r),
                radius_m: rng.range(0.0002, 0.0007),
                transmission: rng.range(0.3, 0.6),
                soft_edge: 0.4,
            });
        }
        stains.truncate(MAX_STAIN_BLOBS);
    }
    Exposure {
        camera,
        width_px: rig.width_px,
        height_px: rig.height_px,
        ambient: scenario.lighting.ambient,
        lights,
        stains,
    }
}

/// Inclusive pixel box of an object's projected mesh clipped to the image: each projected
/// triangle is clipped to the image rectangle, so a box of an object cut by the image border fits
/// the part that is in the image.
pub(crate) fn silhouette_box(
    camera: &CameraCalibration,
    object: &SceneObject,
    width_px: u32,
    height_px: u32,
) -> Option<[u32; 4]> {
    // The image spans [-0.5, size - 0.5] in pixel-centre coordinates.
    let bounds = [
        -0.5,
        -0.5,
        f64::from(width_px) - 0.5,
        f64::from(height_px) - 0.5,
    ];
    let mut low = [f64::INFINITY; 2];
    let mut high = [f64::NEG_INFINITY; 2];
    let points: Vec<Option<[f64; 2]>> = object.world_points().map(|p| camera.project(&p)).collect();
    for triangle in points.chunks_exact(3) {
        let (Some(a), Some(b), Some(c)) = (triangle[0], triangle[1], triangle[2]) else {
            continue;
        };
        for p in clip_to_rect(vec![a, b, c], bounds) {
            for k in 0..2 {
                low[k] = low[k].min(p[k]);
                high[k] = high[k].max(p[k]);
            }
        }
    }
    if !low[0].is_finite() || high[0] - low[0] <= 0.0 || high[1] - low[1] <= 0.0 {
        return None;
    }
    // Pixel i spans [i - 0.5, i + 0.5]: every pixel the clipped silhouette touches.
    let first = |v: f64| (v + 0.5).floor().max(0.0);
    let last = |v: f64, size: u32| ((v + 0.5).ceil() - 1.0).min(f64::from(size) - 1.0);
    let (x0, y0) = (first(low[0]), first(low[1]));
    let (x1, y1) = (last(high[0], width_px), last(high[1], height_px));
    let min_side = f64::from(MIN_LABEL_SIDE_PX) - 1.0;
    (x1 - x0 >= min_side && y1 - y0 >= min_side)
        .then_some([x0 as u32, y0 as u32, x1 as u32, y1 as u32])
}

/// Clips a convex polygon to the rectangle `[x0, y0, x1, y1]` (Sutherland-Hodgman).
fn clip_to_rect(mut polygon: Vec<[f64; 2]>, rect: [f64; 4]) -> Vec<[f64; 2]> {
    // Each edge as (axis, limit, keep the side below the limit).
    let edges = [
        (0, rect[0], false),
        (0, rect[2], true),
        (1, rect[1], false),
        (1, rect[3], true),
    ];
    for (axis, limit, below) in edges {
        let inside = |p: &[f64; 2]| {
            if below {
                p[axis] <= limit
            } else {
                p[axis] >= limit
            }
        };
        let mut out = Vec::with_capacity(polygon.len() + 2);
        for i in 0..polygon.len() {
            let (a, b) = (polygon[i], polygon[(i + 1) % polygon.len()]);
            match (inside(&a), inside(&b)) {
                (true, true) => out.push(b),
                (true, false) | (false, true) => {
                    let t = (limit - a[axis]) / (b[axis] - a[axis]);
                    let cut = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
                    out.push(cut);
                    if inside(&b) {
                        out.push(b);
                    }
                }
                (false, false) => {}
            }
        }
        polygon = out;
        if polygon.is_empty() {
            break;
        }
    }
    polygon
}

/// The true bore of a part as `camera` sees it.
fn bore_truth(
    camera: &CameraCalibration,
    object: &SceneObject,
    part: &crate::sim::PartInstance,
    face_z: f64,
) -> Option<BoreTruth> {
    let top = part.height_m / 2.0;
    let centre = camera.project(&(object.world_from_object * Point3::new(0.0, 0.0, top)))?;
    let n = 1440;
    let mut radii = Vec::with_capacity(n);
    for i in 0..n {
        let t = std::f64::consts::TAU * i as f64 / n as f64;
        let r = part.bore.radius_at(t);
        let edge = object.world_from_object * Point3::new(r * t.cos(), r * t.sin(), top);
        let p = camera.project(&edge)?;
        radii.push((p[0] - centre[0]).hypot(p[1] - centre[1]));
    }
    let mean = radii.iter().sum::<f64>() / n as f64;
    let max = radii.iter().copied().fold(f64::MIN, f64::max);
    let min = radii.iter().copied().fold(f64::MAX, f64::min);
    Some(BoreTruth {
        centre_px: centre,
        radius_px: mean,
        roundness_px: max - min,
        radius_mm: part.bore.mean_diameter_m() * 500.0,
        roundness_mm: part.bore.roundness_m() * 1000.0,
        end_face_height_m: face_z,
    })
}
