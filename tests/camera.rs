//! The cell's camera: rendering agrees with the calibration, golden images, dataset export.
//!
//! These tests render on whatever adapter wgpu finds (the software adapter on a machine without a
//! GPU) and fail, naming the problem, when there is none: they never skip.
//! Regenerate the golden images with `TWINCELL_UPDATE_GOLDEN=1 cargo test --release --test camera`.

mod common;

use std::path::{Path, PathBuf};

use image::RgbImage;
use nalgebra::Vector3;
use twincell::cell::CellModel;
use twincell::perception::BoreDetector;
use twincell::perception::calibration::MeasureOnPlane;
use twincell::render::dataset::{self, image_stem, is_val};
use twincell::render::{CameraRig, ObjectKind, Renderer, RendererOptions, Scene, Shot};
use twincell::scenario::{Scenario, SensorSection};

fn renderer(options: RendererOptions) -> Renderer {
    match Renderer::new(options) {
        Ok(r) => {
            eprintln!("adapter: {}", r.adapter_name());
            r
        }
        Err(e) => panic!("no renderer: {e}"),
    }
}

fn shot(scenario: &Scenario, rig: &CameraRig, sensor: &SensorSection, index: u64) -> Shot {
    match Shot::pick_station(
        &CellModel::with_urdf(scenario.clone(), None).expect("cell model"),
        rig,
        sensor,
        index,
    ) {
        Ok(s) => s,
        Err(e) => panic!("shot {index}: {e}"),
    }
}

/// The projected true bore centre lands within 0.25 px of the rendered bore's measured centre,
/// for every part type at nine places across the field of view.
#[test]
fn projected_bore_centre_matches_the_rendered_bore_across_the_field_of_view() {
    let scenario = common::scenario("smoke.toml");
    let Ok(rig) = CameraRig::from_scenario(&scenario) else {
        panic!("camera");
    };
    let mut renderer = renderer(RendererOptions::default());
    let detector = BoreDetector::default();
    let mut worst: f64 = 0.0;
    let mut errors = Vec::new();
    let mut index = 0;
    for gx in [-1.0, 0.0, 1.0] {
        for gy in [-1.0, 0.0, 1.0] {
            // Find a shot of the next part type, then move its part to this grid place.
            let mut s = shot(&scenario, &rig, &SensorSection::ideal(), index);
            index += 1;
            s.scene.objects.retain(|o| o.kind != ObjectKind::Bottle);
            let Some(part_index) = s
                .scene
                .objects
                .iter()
                .position(|o| matches!(o.kind, ObjectKind::Part(_)))
            else {
                panic!("no part");
            };
            let part = &mut s.scene.objects[part_index];
            let target = Vector3::new(0.05 + gx * 0.15, -0.45 + gy * 0.085, 0.0);
            let t = &mut part.world_from_object.translation.vector;
            t.x = target.x;
            t.y = target.y;
            let image = match s.render(&mut renderer) {
                Ok(i) => i,
                Err(e) => panic!("{e}"),
            };
            let truths = s.truth(&scenario);
            let Some(bore) = truths.iter().find_map(|t| t.bore) else {
                panic!("part out of view at grid ({gx}, {gy})");
            };
            let gray = image::DynamicImage::ImageRgb8(image).to_luma8();
            let found = match detector.detect(&gray) {
                Ok(f) => f,
                Err(e) => panic!("{e}"),
            };
            let Some(best) = found.iter().min_by(|a, b| {
                let da =
                    (a.centre_px[0] - bore.centre_px[0]).hypot(a.centre_px[1] - bore.centre_px[1]);
                let db =
                    (b.centre_px[0] - bore.centre_px[0]).hypot(b.centre_px[1] - bore.centre_px[1]);
                da.total_cmp(&db)
            }) else {
                panic!("no bore found at grid ({gx}, {gy})");
            };
            let error = (best.centre_px[0] - bore.centre_px[0])
                .hypot(best.centre_px[1] - bore.centre_px[1]);
            eprintln!(
                "grid ({gx:+}, {gy:+}): truth ({:.2}, {:.2}) r {:.2} px, rendered ({:.2}, {:.2}) r {:.2} px: centre error {error:.3} px",
                bore.centre_px[0],
                bore.centre_px[1],
                bore.radius_px,
                best.centre_px[0],
                best.centre_px[1],
                best.radius_px
            );
            worst = worst.max(error);
            errors.push(error);
        }
    }
    eprintln!("worst centre error {worst:.3} px");
    assert!(
        worst <= 0.25,
        "worst centre error {worst:.3} px over {errors:?}"
    );
}

fn golden_dir() -> PathBuf {
    common::root().join("tests/golden")
}

/// Compares with a golden image: a pixel differs when a channel is off by more than 8 levels;
/// at most 0.5 % of the pixels may differ (adapters rasterise edges slightly differently).
fn check_golden(name: &str, image: &RgbImage) {
    let path = golden_dir().join(name);
    if std::env::var_os("TWINCELL_UPDATE_GOLDEN").is_some() {
        if let Err(e) = std::fs::create_dir_all(golden_dir())
            .and_then(|()| image.save(&path).map_err(std::io::Error::other))
        {
            panic!("cannot write {}: {e}", path.display());
        }
        eprintln!("updated {}", path.display());
        return;
    }
    let golden = match image::open(&path) {
        Ok(g) => g.to_rgb8(),
        Err(e) => panic!(
            "cannot read golden image {} ({e}); regenerate with TWINCELL_UPDATE_GOLDEN=1",
            path.display()
        ),
    };
    assert_eq!(golden.dimensions(), image.dimensions(), "{name}: size");
    let differing = golden
        .pixels()
        .zip(image.pixels())
        .filter(|(a, b)| a.0.iter().zip(b.0.iter()).any(|(x, y)| x.abs_diff(*y) > 8))
        .count();
    let share = differing as f64 / f64::from(image.width() * image.height());
    eprintln!("{name}: {differing} pixels differ ({:.3} %)", share * 100.0);
    assert!(
        share <= 0.005,
        "{name}: {:.3} % of pixels differ",
        share * 100.0
    );
}

/// The realism of the scenario without the per-pixel noise (which would make golden files large).
fn golden_sensor(scenario: &Scenario) -> SensorSection {
    SensorSection {
        noise_sigma: 0.0,
        salt_pepper_fraction: 0.0,
        ..scenario.sensor.clone()
    }
}

#[test]
fn golden_pick_station_640x480() {
    let scenario = common::scenario("smoke.toml");
    let Ok(rig) = CameraRig::from_scenario(&scenario) else {
        panic!("camera");
    };
    let rig = rig.with_resolution(640, 480);
    let mut renderer = renderer(RendererOptions::default());
    let s = shot(&scenario, &rig, &golden_sensor(&scenario), 3);
    let image = match s.render(&mut renderer) {
        Ok(i) => i,
        Err(e) => panic!("{e}"),
    };
    assert_eq!(image.dimensions(), (640, 480));
    check_golden("pick_station_640x480.png", &image);
}

#[test]
fn golden_pick_station_1280x960() {
    let scenario = common::scenario("smoke.toml");
    let Ok(rig) = CameraRig::from_scenario(&scenario) else {
        panic!("camera");
    };
    assert_eq!((rig.width_px, rig.height_px), (1280, 960));
    let mut renderer = renderer(RendererOptions::default());
    let s = shot(&scenario, &rig, &golden_sensor(&scenario), 5);
    let image = match s.render(&mut renderer) {
        Ok(i) => i,
        Err(e) => panic!("{e}"),
    };
    check_golden("pick_station_1280x960.png", &image);
}

fn read_tree(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            panic!("cannot list {}", d.display());
        };
        for entry in entries.flatten() {
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let Ok(bytes) = std::fs::read(&path) else {
                    panic!("cannot read {}", path.display());
                };
                let Ok(relative) = path.strip_prefix(dir) else {
                    panic!("path outside the tree");
                };
                files.push((relative.to_path_buf(), bytes));
            }
        }
    }
    files.sort();
    files
}

/// A 1,000-image dataset exports byte for byte the same twice, splits 90/10, and every label's
/// box contains, and fits within 2 px, its object's whole silhouette in an independent id render
/// of that object alone.
#[test]
fn thousand_image_dataset_is_deterministic_and_boxes_hold_their_silhouettes() {
    let scenario = common::scenario("smoke.toml");
    let Ok(rig) = CameraRig::from_scenario(&scenario) else {
        panic!("camera");
    };
    // Reduced resolution keeps the test to a few seconds per hundred images; same field of view.
    let rig = rig.with_resolution(320, 240);
    let count: u64 = 1000;
    let root = common::out_dir("camera", "dataset");
    let (a, b) = (root.join("a"), root.join("b"));
    let mut renderer = renderer(RendererOptions::default());
    for dir in [&a, &b] {
        match dataset::export(
            &CellModel::with_urdf(scenario.clone(), None).expect("cell model"),
            &rig,
            &mut renderer,
            count,
            dir,
        ) {
            Ok(summary) => {
                assert_eq!(
                    (summary.train, summary.val),
                    (count as usize * 9 / 10, count as usize / 10)
                );
                eprintln!("{summary:?}");
                assert!(
                    summary
                        .objects_per_class
                        .iter()
                        .all(|(_, n)| *n as u64 > count / 20)
                );
            }
            Err(e) => panic!("{e}"),
        }
    }
    let (files_a, files_b) = (read_tree(&a), read_tree(&b));
    assert_eq!(files_a.len(), 2 * count as usize + 1);
    assert!(files_a == files_b, "the two exports differ");
    let Ok(yaml) = std::fs::read_to_string(a.join("data.yaml")) else {
        panic!("no data.yaml");
    };
    assert!(
        yaml.contains("train: images/train") && yaml.contains("6: bottle"),
        "{yaml}"
    );

    let (w, h) = (rig.width_px, rig.height_px);
    let (mut boxes, mut tight) = (0usize, 0usize);
    for index in 0..count {
        let split = if is_val(index) { "val" } else { "train" };
        let label_path = a
            .join("labels")
            .join(split)
            .join(format!("{}.txt", image_stem(index)));
        let Ok(labels) = std::fs::read_to_string(&label_path) else {
            panic!("no {}", label_path.display());
        };
        let s = shot(&scenario, &rig, &scenario.sensor, index);
        let truths = s.truth(&scenario);
        let lines: Vec<&str> = labels.lines().collect();
        assert_eq!(lines.len(), truths.len(), "image {index}");
        assert!(
            truths.iter().any(|t| t.bore.is_some()),
            "image {index}: no part labelled"
        );
        for (line, truth) in lines.iter().zip(&truths) {
            let fields: Vec<f64> = line
                .split(' ')
                .skip(1)
                .filter_map(|v| v.parse().ok())
                .collect();
            assert_eq!(fields.len(), 4, "{line}");
            let class: usize = line
                .split(' ')
                .next()
                .and_then(|c| c.parse().ok())
                .unwrap_or(usize::MAX);
            assert_eq!(class, truth.class_id);
            // The object's whole silhouette, unoccluded: an id render of the object alone.
            let alone = Scene {
                objects: vec![s.scene.objects[truth.object_index].clone()],
                blur: None,
            };
            let gpu = renderer.upload(&alone);
            let ids = match renderer.render_ids(&gpu, &s.exposure) {
                Ok(ids) => ids,
                Err(e) => panic!("{e}"),
            };
            // Back from normalised YOLO to pixel-edge coordinates.
            let (x0, x1) = (
                (fields[0] - fields[2] / 2.0) * f64::from(w),
                (fields[0] + fields[2] / 2.0) * f64::from(w),
            );
            let (y0, y1) = (
                (fields[1] - fields[3] / 2.0) * f64::from(h),
                (fields[1] + fields[3] / 2.0) * f64::from(h),
            );
            let id = 1;
            let mut seen = [u32::MAX, u32::MAX, 0, 0];
            for (x, y, pixel) in ids.enumerate_pixels() {
                if pixel.0[0] != id {
                    continue;
                }
                let (px, py) = (f64::from(x), f64::from(y));
                assert!(
                    px >= x0 - 1e-3
                        && px + 1.0 <= x1 + 1e-3
                        && py >= y0 - 1e-3
                        && py + 1.0 <= y1 + 1e-3,
                    "image {index}: {} pixel ({x}, {y}) outside its box [{x0:.2}, {y0:.2}, {x1:.2}, {y1:.2}]",
                    truth.class
                );
                seen = [
                    seen[0].min(x),
                    seen[1].min(y),
                    seen[2].max(x),
                    seen[3].max(y),
                ];
            }
            boxes += 1;
            let [bx0, by0, bx1, by1] = truth.bbox_px;
            if seen[0] <= bx0 + 2 && seen[1] <= by0 + 2 && seen[2] + 2 >= bx1 && seen[3] + 2 >= by1
            {
                tight += 1;
            } else if boxes - tight < 12 {
                eprintln!(
                    "loose: image {index} {} box {:?} silhouette {seen:?}",
                    truth.class, truth.bbox_px
                );
            }
        }
    }
    // Boxes are not padded either: each touches its silhouette's extent within 2 px.
    eprintln!("{tight} of {boxes} boxes within 2 px of their silhouette");
    assert_eq!(tight, boxes, "loose boxes");
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_bad_camera_setting_names_its_key() {
    let path = common::scenario_path("smoke.toml");
    let text = common::read(&path);
    for (extra, key) in [
        ("[camera]\nmsaa_samples = 3\n", "camera.msaa_samples"),
        (
            "[camera]\nhorizontal_fov_deg = 0.0\n",
            "camera.horizontal_fov_deg",
        ),
        (
            "[camera]\nlook_at_m = [1.0, -0.45, 1.28]\n",
            "camera.look_at_m",
        ),
        ("[sensor]\nnoise_sigma = -1.0\n", "sensor.noise_sigma"),
        ("[sensor]\nmax_dirt = 40\n", "sensor.max_dirt"),
        (
            "[lighting]\nambient = 0.2\nlights = [{ direction = [0.0, 0.0, 0.0], intensity = 1.0 }]\n",
            "lighting.lights[0].direction",
        ),
    ] {
        match Scenario::from_toml(&format!("{text}\n{extra}"), &path) {
            Ok(_) => panic!("accepted {extra}"),
            Err(e) => assert_eq!(e.key, key, "{e}"),
        }
    }
}

/// Metrology on rendered images at `width_px` x `height_px`: bore diameter and roundness
/// measured by `perception` (bore detector, then the calibration's on-plane fit) against the true
/// bore, in mm; and the number of bores missed.
fn metrology_errors(
    sensor: &SensorSection,
    shots: u64,
    width_px: u32,
    height_px: u32,
) -> (Vec<f64>, Vec<f64>, usize) {
    use twincell::perception::roundness::DEFAULT_MAX_UPR;
    let scenario = common::scenario("smoke.toml");
    let Ok(rig) = CameraRig::from_scenario(&scenario) else {
        panic!("camera");
    };
    let rig = rig.with_resolution(width_px, height_px);
    let mut renderer = renderer(RendererOptions::default());
    let detector = BoreDetector::default();
    let (mut diameter, mut roundness, mut missed) = (Vec::new(), Vec::new(), 0);
    for index in 0..shots {
        let s = shot(&scenario, &rig, sensor, index);
        let image = match s.render(&mut renderer) {
            Ok(i) => i,
            Err(e) => panic!("{e}"),
        };
        let Some(truth) = s.truth(&scenario).iter().find_map(|t| t.bore) else {
            panic!("no part");
        };
        let gray = image::DynamicImage::ImageRgb8(image).to_luma8();
        let found = detector.detect(&gray).unwrap_or_default();
        let Some(bore) = found.iter().find(|b| {
            (b.centre_px[0] - truth.centre_px[0]).hypot(b.centre_px[1] - truth.centre_px[1])
                < 0.3 * truth.radius_px
        }) else {
            eprintln!("shot {index}: bore missed");
            missed += 1;
            continue;
        };
        let calibration = rig
            .calibration
            .with_end_face_height(truth.end_face_height_m);
        let Ok(measured) = calibration.measure_on_plane(bore, DEFAULT_MAX_UPR) else {
            eprintln!("shot {index}: no measurement on the plane");
            missed += 1;
            continue;
        };
        diameter.push((measured.diameter_m * 1e3 - 2.0 * truth.radius_mm).abs());
        roundness.push((measured.roundness_m * 1e3 - truth.roundness_mm).abs());
    }
    (diameter, roundness, missed)
}

fn mean_and_p95(v: &mut [f64]) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
    let p95 = v
        .get(((v.len() as f64 * 0.95).ceil() as usize).saturating_sub(1))
        .copied()
        .unwrap_or(f64::NAN);
    (mean, p95)
}

/// Measures `shots` renders and asserts no bore is missed and both the diameter and the
/// roundness errors stay within `mean_mm` on average and `p95_mm` at the 95th percentile.
fn assert_metrology(name: &str, sensor: &SensorSection, size: (u32, u32), limits: (f64, f64)) {
    let (mean_mm, p95_mm) = limits;
    let (mut diameter, mut roundness, missed) = metrology_errors(sensor, 60, size.0, size.1);
    let (d_mean, d_p95) = mean_and_p95(&mut diameter);
    let (r_mean, r_p95) = mean_and_p95(&mut roundness);
    eprintln!(
        "{name} {}x{}: {} bores measured, {missed} missed; diameter error mean {d_mean:.4} mm \
         p95 {d_p95:.4} mm; roundness error mean {r_mean:.4} mm p95 {r_p95:.4} mm",
        size.0,
        size.1,
        diameter.len()
    );
    assert_eq!(missed, 0, "{name}: missed bores");
    assert!(
        d_mean <= mean_mm && d_p95 <= p95_mm,
        "{name}: diameter error mean {d_mean} p95 {d_p95} mm"
    );
    assert!(
        r_mean <= mean_mm && r_p95 <= p95_mm,
        "{name}: roundness error mean {r_mean} p95 {r_p95} mm"
    );
}

/// At the default 1280x960 (about 3.1 px/mm on the end face) the metrology meets the goal with
/// the ideal sensor and with the scenario's realism (noise, uneven light, vignetting, oil stains
/// and dirt on the end faces, camera jitter): over 60 shots each, no bore missed, mean error at
/// most 0.05 mm and 95th percentile at most 0.1 mm for both the bore diameter and its roundness.
#[test]
fn rendered_bores_measure_to_truth_within_hundredths_of_a_millimetre() {
    assert_metrology(
        "ideal sensor",
        &SensorSection::ideal(),
        (1280, 960),
        (0.05, 0.1),
    );
    assert_metrology(
        "scenario realism",
        &common::scenario("smoke.toml").sensor,
        (1280, 960),
        (0.05, 0.1),
    );
}

/// At 640x480 (about 1.55 px/mm, so 0.05 mm is 0.08 px) the goal is out of reach; this guards
/// the accuracy reached there with the scenario's realism: no bore missed, diameter and
/// roundness within 0.15 mm on average and 0.25 mm at the 95th percentile.
#[test]
fn rendered_bores_at_640x480_measure_to_a_tenth_of_a_millimetre() {
    assert_metrology(
        "scenario realism",
        &common::scenario("smoke.toml").sensor,
        (640, 480),
        (0.15, 0.25),
    );
}

/// The arm at its home pose stays out of the camera's view of the pick station.
#[test]
fn the_arm_at_home_does_not_occlude_the_pick_station() {
    let scenario = common::scenario("smoke.toml");
    let Ok(rig) = CameraRig::from_scenario(&scenario) else {
        panic!("camera");
    };
    let rig = rig.with_resolution(320, 240);
    let mut renderer = renderer(RendererOptions::default());
    let s = shot(&scenario, &rig, &SensorSection::ideal(), 0);
    let robot: Vec<u32> = s
        .scene
        .objects
        .iter()
        .enumerate()
        .filter(|(_, o)| o.name.ends_with("_Link"))
        .map(|(i, _)| i as u32 + 1)
        .collect();
    assert!(
        robot.len() >= 6,
        "robot links in the scene: {}",
        robot.len()
    );
    let gpu = renderer.upload(&s.scene);
    let ids = match renderer.render_ids(&gpu, &s.exposure) {
        Ok(ids) => ids,
        Err(e) => panic!("{e}"),
    };
    let robot_pixels = ids.pixels().filter(|p| robot.contains(&p.0[0])).count();
    assert_eq!(
        robot_pixels, 0,
        "the arm covers {robot_pixels} pixels of the view"
    );
}

/// A renderer draws images of many sizes into a few size-class targets, made once each (the
/// camera batch's memory stays flat, issue 17), and an image comes out the same whichever
/// images the shared target held before.
#[test]
fn images_of_many_sizes_share_a_few_targets_and_come_out_the_same() {
    let scenario = common::scenario("smoke.toml");
    let Ok(rig) = CameraRig::from_scenario(&scenario) else {
        panic!("camera");
    };
    let sensor = golden_sensor(&scenario);
    let mut renderer = renderer(RendererOptions::default());
    let mut draw = |w: u32, h: u32| {
        let s = shot(&scenario, &rig.with_resolution(w, h), &sensor, 7);
        match s.render(&mut renderer) {
            Ok(i) => i,
            Err(e) => panic!("{w} x {h}: {e}"),
        }
    };
    let first = draw(200, 150);
    // Sizes from 64 x 48 to 512 x 512, drawn by a fixed LCG.
    let mut state: u64 = 0x2545_f491_4f6c_dd1d;
    let mut next = |lo: u32, hi: u32| {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        lo + ((state >> 33) % u64::from(hi - lo + 1)) as u32
    };
    let mut classes = std::collections::BTreeSet::from([(256, 256)]);
    for _ in 0..14 {
        let (w, h) = (next(64, 512), next(48, 512));
        classes.insert((w.div_ceil(256) * 256, h.div_ceil(256) * 256));
        let image = draw(w, h);
        assert_eq!(image.dimensions(), (w, h));
    }
    let again = draw(200, 150);
    assert!(
        first == again,
        "the 200 x 150 image changed after other sizes"
    );
    let made = renderer.target_allocations();
    assert_eq!(
        made,
        classes.len() as u64,
        "{made} targets for {} size classes",
        classes.len()
    );
}
