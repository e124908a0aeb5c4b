//! The bore's roundness and diameter on the end-face plane under a tilted camera (issue 24):
//! parts of known bore form rendered by cameras drawn over the envelope (tilts 0-35°, any
//! azimuth but the robot's side, any roll, 0.35-1.2 m from the pick station), measured as the
//! closed loop measures its target (the part's area of interest read at the sensor's full pitch,
//! the bore finder with its circularity check widened by the part's foreshortening, the edge cast
//! onto the plane at the type's height) against the truth.
//!
//! The edge points, cast onto the true end-face plane, lie on the true edge: averaged over 15°
//! arcs, within 0.011 mm of it all round the bore at 30° (ideal sensor, 0.6 m, 6 shots): the
//! image edges are right, on the far side (where the bore's wall is in view) as elsewhere. What went wrong was the circle fitted
//! to them on the plane: rays spread evenly in the image lie unevenly there (denser where the
//! plane is foreshortened), and the unweighted fit's centre followed the denser arcs, moving by
//! up to 0.035 mm for a lobed bore at 30°, which the roundness about that centre read as out of
//! round. Run with `--nocapture` for each shot's figures.

mod common;

use image::imageops::grayscale;
use nalgebra::{Point3, Vector3};
use twincell::cell::{Cell, CellModel};
use twincell::perception::calibration::MeasureOnPlane;
use twincell::perception::roundness::DEFAULT_MAX_UPR;
use twincell::perception::{BoreDetector, BoreDetectorParams};
use twincell::render::{CameraRig, ObjectKind, Renderer, RendererOptions, Scene, Shot};
use twincell::rng::SimRng;
use twincell::scenario::{CameraSection, Scenario, SensorSection};
use twincell::station::camera_percept::{find_in_window, part_window};

/// Cameras drawn, and shots each.
const CAMERAS: usize = 10;
const SHOTS: u64 = 8;

/// A shot's allowance ([`allowance_mm`]): a share of a pixel of the area of interest, plus a
/// floor, mm.
const ALLOWANCE_PX: f64 = 0.1;
const ALLOWANCE_FLOOR_MM: f64 = 0.01;

/// Bounds on the errors (measured minus true) over their shot's allowance: the roundness
/// error's 95th percentile and largest magnitude, then the bore diameter's; with the ideal
/// sensor (the geometry alone) and with paper_50's realism (whose camera pose jitter the
/// calibration does not know, and which moves the diameter). Measured over these 80 shots:
/// ideal 0.45, 0.74, 0.14, 0.23; realism 0.55, 0.71, 1.02, 1.13. With the roundness read on the
/// raw low-passed profile (main at fecb02a, before the edge noise was taken out of each
/// harmonic, `perception::roundness_noise`), the cameras then drawn at 0.4 and 0.9 m read
/// roundness 0.76, 1.00 ideal and 0.75, 0.90 with realism; with the circle fitted unweighted
/// on the plane (main at 16d7d3f), ideal: 1.71, 2.86, 1.68, 5.38.
const IDEAL_BOUNDS: [f64; 4] = [0.7, 0.9, 0.5, 0.5];
const REALISM_BOUNDS: [f64; 4] = [0.7, 0.9, 1.5, 2.5];

/// Tilt of camera `k` of `n`: one in each of `n` equal bands of 0-35°.
fn tilt_deg(k: usize, n: usize, rng: &mut SimRng) -> f64 {
    let band = 35.0 / n as f64;
    band * (k as f64 + rng.uniform())
}

/// Errors of one shot, mm: roundness, bore diameter, and the largest residual of an edge point
/// from the true edge on the true end-face plane (about their mean).
struct ShotErrors {
    roundness_mm: f64,
    diameter_mm: f64,
    edge_residual_mm: f64,
}

/// Stages shot `index` of `scenario` as `twincell calibrate` does (the part where the belt stops
/// it, the bottles keeping their offsets) and measures it; `None` when no bore was found.
fn measure_shot(
    scenario: &Scenario,
    model: &CellModel,
    rig: &CameraRig,
    renderer: &mut Renderer,
    seed: u64,
    index: u64,
) -> Option<ShotErrors> {
    let mut rng = SimRng::derive(seed, index);
    let cell = Cell::build(model, &mut rng).unwrap_or_else(|e| panic!("{e}"));
    let (scene, object_index) = Scene::at_photo_eye(&cell, scenario)?;
    let ObjectKind::Part(part) = scene.objects[object_index].kind.clone() else {
        return None;
    };
    let world_from_part = scene.objects[object_index].world_from_object;
    let face_true = world_from_part * Point3::new(0.0, 0.0, part.height_m / 2.0);
    let type_height_m = scenario.part_types[part.type_index].height_mm / 1e3;
    let face_z = cell.belt_top_z + type_height_m;
    let shot = Shot::of_scene(scenario, rig, &scenario.sensor, scene, &mut rng);
    let truth = shot
        .truth(scenario)
        .into_iter()
        .find(|t| t.object_index == object_index && t.bore.is_some())?;
    let [x0, y0, x1, y1] = truth.bbox_px.map(f64::from);
    let box_px = [x0, y0, x1 + 1.0, y1 + 1.0];
    let roi = scenario.camera.roi_scale;
    let window = part_window(&box_px, (rig.width_px, rig.height_px), roi)?;
    let gpu = renderer.upload(&shot.scene);
    let image = shot
        .render_window(renderer, &gpu, &window)
        .unwrap_or_else(|e| panic!("{e}"));
    // The closed loop's circularity allowance for the part's foreshortening.
    let eye = rig.calibration.origin_in_world();
    let ray = face_true - eye;
    let cos = (-ray.z / ray.norm()).clamp(0.0, 1.0);
    let mut params = BoreDetectorParams::default().at_scale(f64::from(roi));
    params.max_roundness_ratio += (2.0 * (1.0 - cos) / (1.0 + cos) - 0.07).max(0.0);
    let bore = find_in_window(
        &BoreDetector::new(params),
        &grayscale(&image),
        &window,
        &box_px,
    )?;
    let calibration = window.calibration(&rig.calibration.with_end_face_height(face_z));
    let plane = calibration
        .measure_on_plane(&bore, DEFAULT_MAX_UPR)
        .unwrap_or_else(|e| panic!("{e}"));
    // Each edge point cast onto the true end-face plane through the camera the frame was really
    // taken from, against the true edge there.
    let camera = window.calibration(&shot.exposure.camera);
    let normal = world_from_part.rotation * Vector3::z();
    let residuals: Vec<f64> = bore
        .edge_points_px
        .iter()
        .map(|p| {
            let (o, d) = (camera.origin_in_world(), camera.pixel_to_ray(p[0], p[1]));
            let q = o + d * ((face_true - o).dot(&normal) / d.dot(&normal));
            let local = world_from_part.inverse_transform_point(&q);
            let theta = local.y.atan2(local.x);
            local.x.hypot(local.y) - part.bore.radius_at(theta)
        })
        .collect();
    let mean = residuals.iter().sum::<f64>() / residuals.len() as f64;
    Some(ShotErrors {
        roundness_mm: 1e3 * (plane.roundness_m - part.bore.roundness_m()),
        diameter_mm: 1e3 * (plane.diameter_m - part.bore.mean_diameter_m()),
        edge_residual_mm: 1e3
            * residuals
                .iter()
                .fold(0.0f64, |m, r| m.max((r - mean).abs())),
    })
}

/// The 95th percentile and the largest of `values` (reordered).
fn p95_and_max(values: &mut [f64]) -> [f64; 2] {
    values.sort_by(f64::total_cmp);
    let p95 = values[(0.95 * (values.len() - 1) as f64).round() as usize];
    [p95, values.last().copied().unwrap_or(f64::NAN)]
}

/// Figures over all shots of one sensor: the roundness and diameter errors over their shot's
/// allowance ([`allowance_mm`]), p95 and max of each.
fn figures(errors: &[(ShotErrors, f64)]) -> [f64; 4] {
    let mut roundness: Vec<f64> = errors
        .iter()
        .map(|(e, a)| e.roundness_mm.abs() / a)
        .collect();
    let mut diameter: Vec<f64> = errors
        .iter()
        .map(|(e, a)| e.diameter_mm.abs() / a)
        .collect();
    let [rp, rm] = p95_and_max(&mut roundness);
    let [dp, dm] = p95_and_max(&mut diameter);
    [rp, rm, dp, dm]
}

/// The error a shot's measurement is allowed, mm: [`ALLOWANCE_PX`] of the area of interest's
/// pixel on the end-face plane at the station (the frame's pixel over `roi_scale`, stretched by
/// the tilt's foreshortening) plus [`ALLOWANCE_FLOOR_MM`]: a camera twice as far reads its edges
/// on a pixel twice as coarse.
fn allowance_mm(scenario: &Scenario, distance_m: f64, tilt_rad: f64) -> f64 {
    let camera = &scenario.camera;
    let frame_px_mm = 1e3 * distance_m * 2.0 * (camera.horizontal_fov_deg.to_radians() / 2.0).tan()
        / f64::from(camera.resolution_px[0]);
    let roi_px_mm = frame_px_mm / f64::from(camera.roi_scale) / tilt_rad.cos();
    ALLOWANCE_PX * roi_px_mm + ALLOWANCE_FLOOR_MM
}

/// Measures every camera's shots with `sensor` (the scenario's realism, or none).
fn measure_cameras(ideal: bool) -> Vec<(ShotErrors, f64)> {
    let base = common::paper_50();
    let station = CameraSection::pick_station(&base.conveyor);
    let mut renderer = Renderer::new(RendererOptions {
        msaa_samples: base.camera.msaa_samples,
        supersample: base.camera.supersample,
    })
    .unwrap_or_else(|e| panic!("{e}"));
    let mut rng = SimRng::new(2431);
    let mut errors = Vec::new();
    let mut missed = 0;
    for k in 0..CAMERAS {
        let tilt = tilt_deg(k, CAMERAS, &mut rng);
        // Any direction but the robot's side (+y), where the cell's posts stand in the view.
        let azimuth: f64 = rng.range(150.0, 390.0);
        let roll = rng.range(-180.0, 180.0);
        // Near and far by turns, over the envelope's 0.35-1.2 m.
        let distance = if k % 2 == 0 {
            rng.range(0.35, 0.7)
        } else {
            rng.range(0.7, 1.2)
        };
        let (t, a) = (tilt.to_radians(), azimuth.to_radians());
        let mut scenario = base.clone();
        scenario.camera.position_m = Some([
            station[0] + distance * t.sin() * a.cos(),
            station[1] + distance * t.sin() * a.sin(),
            station[2] + distance * t.cos(),
        ]);
        scenario.camera.look_at_m = Some(station);
        scenario.camera.roll_deg = roll;
        if ideal {
            scenario.sensor = SensorSection::ideal();
        }
        let model = CellModel::new(scenario.clone(), &common::scenario_path("paper_50.toml"))
            .unwrap_or_else(|e| panic!("{e}"));
        let rig = CameraRig::from_scenario(&scenario).unwrap_or_else(|e| panic!("{e}"));
        let allowance = allowance_mm(&scenario, distance, t);
        for index in 0..SHOTS {
            let seed = 2431 + k as u64;
            let Some(e) = measure_shot(&scenario, &model, &rig, &mut renderer, seed, index) else {
                missed += 1;
                continue;
            };
            eprintln!(
                "{}camera {k}: tilt {tilt:4.1}° azimuth {azimuth:3.0}° roll {roll:4.0}° \
                 {distance} m, shot {index}: roundness error {:+.4} mm, diameter {:+.4} mm, \
                 largest edge residual {:.4} mm",
                if ideal { "ideal " } else { "" },
                e.roundness_mm,
                e.diameter_mm,
                e.edge_residual_mm
            );
            errors.push((e, allowance));
        }
    }
    let total = CAMERAS * SHOTS as usize;
    assert!(
        missed * 10 <= total,
        "{missed} of {total} shots measured no bore"
    );
    errors
}

#[test]
fn roundness_on_the_plane_holds_under_tilted_cameras() {
    for (ideal, bounds) in [(true, IDEAL_BOUNDS), (false, REALISM_BOUNDS)] {
        let errors = measure_cameras(ideal);
        let found = figures(&errors);
        let name = if ideal {
            "ideal sensor"
        } else {
            "paper_50's realism"
        };
        eprintln!(
            "{name}, {} shots, errors over their allowance: roundness p95 {:.2}, max {:.2}; \
             diameter p95 {:.2}, max {:.2}",
            errors.len(),
            found[0],
            found[1],
            found[2],
            found[3]
        );
        for (what, (value, bound)) in [
            "roundness p95",
            "roundness max",
            "diameter p95",
            "diameter max",
        ]
        .iter()
        .zip(found.iter().zip(bounds))
        {
            assert!(
                value <= &bound,
                "{name}: {what} error over its allowance {value:.2} > {bound}"
            );
        }
    }
}
