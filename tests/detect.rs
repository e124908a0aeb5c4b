//! The shipped detector on freshly rendered images, checked against the renderer's ground truth
//! (not against recorded outputs). It finds tube end faces (class `tube`) and foreign objects
//! (`foreign`): on the two catalogues' own pick-station shots (seeds 4242, the paper's, and 4243,
//! scenarios/suite/catalogue_b.toml) and on family shots drawn over the whole tube family and
//! camera envelope (seeds 4244 and 4245; with bottles set in front of tubes, 4246 and 4247). No
//! training or held-out set uses these seeds (see
//! training/make_data.sh). Renders on whatever adapter wgpu finds (the software one without a
//! GPU) and fails, naming the problem, when there is none.

mod common;

use twincell::cell::CellModel;
use twincell::detect::{Detection, Detector, DetectorModel};
use twincell::render::family::{family_model, family_shot};
use twincell::render::{CameraRig, ObjectTruth, Renderer, RendererOptions, Shot};
use twincell::scenario::{Scenario, SensorSection};

const SEED: u64 = 4242;
const IMAGES_PER_SENSOR: u64 = 12;

/// `scenarios/NAME` at `seed`, at the detector's resolution, as `twincell dataset
/// --resolution 640 480` renders it.
fn scenario_at(name: &str, seed: u64) -> Scenario {
    let mut s = common::scenario(name);
    s.seed = seed;
    s.camera.resolution_px = [640, 480];
    s
}

fn scenario() -> Scenario {
    scenario_at("paper_50.toml", SEED)
}

/// Strong noise, stains, dirt and badly balanced light (make_data.sh's harsh sets).
fn harsh() -> SensorSection {
    SensorSection {
        noise_sigma: 7.0,
        salt_pepper_fraction: 0.003,
        illumination_gradient: 0.35,
        vignetting: 0.45,
        max_stains: 5,
        max_dirt: 14,
        light_jitter_deg: 25.0,
        intensity_jitter: 0.4,
        pose_jitter_m: 0.0005,
        pose_jitter_deg: 0.05,
    }
}

fn iou(a: [f32; 4], b: [f32; 4]) -> f32 {
    let iw = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
    let ih = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    let area = |r: [f32; 4]| (r[2] - r[0]) * (r[3] - r[1]);
    iw * ih / (area(a) + area(b) - iw * ih)
}

/// A truth box's pixel edges (the truth holds inclusive first/last columns and rows).
fn edges(t: &ObjectTruth) -> [f32; 4] {
    let [x0, y0, x1, y1] = t.bbox_px.map(|v| v as f32);
    [x0, y0, x1 + 1.0, y1 + 1.0]
}

/// The detector's class for a truth: `foreign` for a bottle, `tube` for any part.
fn class_of(truth: &ObjectTruth) -> &'static str {
    if truth.class == "bottle" || truth.class == "foreign" {
        "foreign"
    } else {
        "tube"
    }
}

/// Detections against truths, by class.
#[derive(Debug, Default)]
struct Tally {
    truths: usize,
    found: usize,
    detections: usize,
    correct: usize,
    bottle_as_tube: usize,
    misses: Vec<String>,
}

impl Tally {
    fn add(&mut self, label: &str, truths: &[ObjectTruth], found: &[Detection]) {
        self.truths += truths.len();
        self.detections += found.len();
        for t in truths {
            let hit = found
                .iter()
                .any(|d| d.class_name == class_of(t) && iou(d.box_px, edges(t)) >= 0.5);
            if hit {
                self.found += 1;
            } else {
                self.misses.push(format!(
                    "{label}: {} at {:?} missed; got {found:?}",
                    t.class, t.bbox_px
                ));
            }
        }
        for d in found {
            let best = truths
                .iter()
                .max_by(|a, b| iou(d.box_px, edges(a)).total_cmp(&iou(d.box_px, edges(b))));
            let Some(t) = best.filter(|t| iou(d.box_px, edges(t)) >= 0.5) else {
                continue;
            };
            if class_of(t) == d.class_name {
                self.correct += 1;
            } else if class_of(t) == "foreign" {
                self.bottle_as_tube += 1;
            }
        }
    }
}

fn shipped() -> Detector {
    match Detector::load_default() {
        Ok(d) => d,
        Err(e) => panic!("{e}"),
    }
}

/// Renders `per_sensor` pick-station images of `scenario` with its own sensor realism and as
/// many harsh ones, and tallies the shipped detector's output against their truth.
fn tally_renders(scenario: &Scenario, per_sensor: u64) -> Tally {
    let rig = match CameraRig::from_scenario(scenario) {
        Ok(r) => r,
        Err(e) => panic!("camera: {e}"),
    };
    let mut renderer = common::renderer(scenario);
    let mut detector = shipped();
    let model = CellModel::with_urdf(scenario.clone(), None).expect("cell model");
    let mut tally = Tally::default();
    for (name, sensor) in [("default", scenario.sensor.clone()), ("harsh", harsh())] {
        for index in 0..per_sensor {
            let shot = match Shot::pick_station(&model, &rig, &sensor, index) {
                Ok(s) => s,
                Err(e) => panic!("shot {index}: {e}"),
            };
            let image = match shot.render(&mut renderer) {
                Ok(i) => i,
                Err(e) => panic!("render {index}: {e}"),
            };
            let truths = shot.truth(scenario);
            let found = match detector.detect(&image) {
                Ok(f) => f,
                Err(e) => panic!("detect {index}: {e}"),
            };
            tally.add(&format!("{name} {index}"), &truths, &found);
        }
    }
    eprintln!("{tally:?}");
    tally
}

/// Recall and precision (right class at IoU >= 0.5) of at least `least` each, and at most
/// `bottles_as_tubes` bottles reported as a tube.
fn assert_accurate(tally: &Tally, min_truths: usize, least: f64, bottles_as_tubes: usize) {
    assert!(
        tally.truths >= min_truths,
        "too few labelled objects: {}",
        tally.truths
    );
    let recall = tally.found as f64 / tally.truths as f64;
    let precision = tally.correct as f64 / tally.detections.max(1) as f64;
    assert!(
        tally.bottle_as_tube <= bottles_as_tubes,
        "bottles reported as tubes: {tally:?}"
    );
    assert!(recall >= least, "recall {recall:.3}: {:#?}", tally.misses);
    assert!(precision >= least, "precision {precision:.3}: {tally:?}");
}

/// The detector knows no catalogue: its classes are a tube's end face and a foreign object.
#[test]
fn shipped_detector_finds_tubes_not_catalogue_entries() {
    let detector = shipped();
    assert_eq!(detector.class_names(), ["tube", "foreign"]);
}

/// On 24 fresh renders of the paper's cell (12 with its sensor realism, 12 harsh), every part
/// and bottle is found as a tube or a foreign object at IoU >= 0.5 in at least 95 % of cases, at
/// least 95 % of the detections are right, and no bottle is reported as a tube.
#[test]
fn shipped_detector_finds_the_paper_parts_and_bottles() {
    let tally = tally_renders(&scenario(), IMAGES_PER_SENSOR);
    assert_accurate(&tally, 40, 0.95, 0);
}

/// The second part catalogue (other bores and walls; scenarios/suite/catalogue_b.toml): on 36
/// fresh renders (18 default, 18 harsh), the same.
#[test]
fn shipped_detector_finds_the_second_catalogue() {
    let scenario = scenario_at("suite/catalogue_b.toml", 4243);
    let tally = tally_renders(&scenario, 18);
    assert_accurate(&tally, 60, 0.95, 0);
}

/// Family shots of the paper's cell, `per_seed` a seed, one seed per sensor (`None`: the
/// scenario's own), staged with bottles in front of tubes when `occlude`: the tally over every
/// object, the tally over the tubes less than 0.9 in view alone (its truths and finds; its
/// detections are the whole images'), and the steepest tilt drawn.
fn tally_family(
    seeds: [(u64, Option<SensorSection>); 2],
    per_seed: u64,
    occlude: bool,
) -> (Tally, Tally, f64) {
    let mut detector = shipped();
    let (mut tally, mut hidden) = (Tally::default(), Tally::default());
    let mut steepest: f64 = 0.0;
    for (seed, sensor) in seeds {
        let mut scenario = scenario_at("paper_50.toml", seed);
        if let Some(sensor) = sensor {
            scenario.sensor = sensor;
        }
        let rig = match CameraRig::from_scenario(&scenario) {
            Ok(r) => r,
            Err(e) => panic!("camera: {e}"),
        };
        let mut renderer = common::renderer(&scenario);
        let model = CellModel::with_urdf(scenario.clone(), None).expect("cell model");
        let model = family_model(&model).expect("family cell model");
        for index in 0..per_seed {
            let family = match family_shot(&model, &rig, index, occlude) {
                Ok(s) => s,
                Err(e) => panic!("shot {index}: {e}"),
            };
            steepest = steepest.max(family.camera.tilt_deg);
            let image = match family.shot.render(&mut renderer) {
                Ok(i) => i,
                Err(e) => panic!("render {index}: {e}"),
            };
            let found = match detector.detect(&image) {
                Ok(f) => f,
                Err(e) => panic!("detect {index}: {e}"),
            };
            let label = format!("seed {seed} image {index} ({:?})", family.camera);
            let truths = family.truth();
            tally.add(&label, &truths, &found);
            // The tubes a bottle hides in part: their truths, matched to the drawn tubes by place.
            let partly: Vec<ObjectTruth> = truths
                .iter()
                .filter(|t| {
                    t.class == "tube"
                        && family.tubes.iter().any(|d| {
                            d.face_visible < 0.9
                                && (0..3).all(|k| (d.position_m[k] - t.position_m[k]).abs() < 1e-9)
                        })
                })
                .cloned()
                .collect();
            hidden.add(&label, &partly, &found);
        }
    }
    eprintln!("{tally:?}");
    eprintln!("partly hidden: {} of {} found", hidden.found, hidden.truths);
    (tally, hidden, steepest)
}

/// Family shots (`twincell dataset --family`): 40 images of each sensor realism, each with its
/// own camera drawn over the whole envelope (tilt 0-35 degrees in any direction, 0.35-1.2 m,
/// any roll, 35-80 degrees of field of view) and its own tubes over the whole family (bores
/// 8-90 mm, outer/bore 1.15-3, heights 30-120 mm, steel finishes): recall and precision of at
/// least 0.95, at most one bottle as a tube, and the tilts drawn reach past 30 degrees.
#[test]
fn shipped_detector_finds_family_tubes_over_the_camera_envelope() {
    let (tally, _, steepest) = tally_family([(4244, None), (4245, Some(harsh()))], 40, false);
    assert!(steepest > 30.0, "steepest tilt drawn {steepest}");
    // The goal is no bottle as a tube anywhere in the envelope; not met on the held-out images
    // (3 of their 579 bottles, assets/models/detector.json), none in these 80 images.
    assert_accurate(&tally, 120, 0.95, 1);
}

/// Family shots with a bottle set down between a tube and the camera in half of them (`twincell
/// dataset --family --occlude`; 200 images of seed 4246 with the scenario's sensor, 200 of 4247
/// harsh): the tubes with 0.5-0.9 of their end face in view are found at least HIDDEN_RECALL of
/// the time, and over every object recall and precision stay at least 0.9 with at most one
/// bottle as a tube. Measured: 45 of 55 partly hidden tubes, recall 0.972, precision 0.931, one
/// bottle as a tube; the detector shipped before the occluded training data (until the evening
/// of 5 December 2026) found 24 of the 55, with 4 bottles as tubes.
#[test]
fn shipped_detector_finds_tubes_a_bottle_partly_hides() {
    const HIDDEN_RECALL: f64 = 0.7;
    let (tally, hidden, _) = tally_family([(4246, None), (4247, Some(harsh()))], 200, true);
    assert!(
        hidden.truths >= 40,
        "too few partly hidden tubes: {}",
        hidden.truths
    );
    let recall = hidden.found as f64 / hidden.truths as f64;
    assert!(
        recall >= HIDDEN_RECALL,
        "partly hidden tubes: {} of {} found: {:#?}",
        hidden.found,
        hidden.truths,
        hidden.misses
    );
    assert_accurate(&tally, 120, 0.9, 1);
}

/// Detection is deterministic: the same image twice gives the same bytes, and the network built
/// into the binary gives the same as the shipped file.
#[test]
fn detection_repeats_exactly() {
    let scenario = scenario();
    let Ok(rig) = CameraRig::from_scenario(&scenario) else {
        panic!("camera");
    };
    let mut renderer = match Renderer::new(RendererOptions::default()) {
        Ok(r) => r,
        Err(e) => panic!("no renderer: {e}"),
    };
    let shot = match Shot::pick_station(
        &CellModel::with_urdf(scenario.clone(), None).expect("cell model"),
        &rig,
        &scenario.sensor,
        100,
    ) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    };
    let image = match shot.render(&mut renderer) {
        Ok(i) => i,
        Err(e) => panic!("{e}"),
    };
    let mut detector = match Detector::load_default() {
        Ok(d) => d,
        Err(e) => panic!("{e}"),
    };
    let (Ok(a), Ok(b)) = (detector.detect(&image), detector.detect(&image)) else {
        panic!("detect");
    };
    assert!(!a.is_empty());
    assert_eq!(a, b);
    // The network built into the binary is the file the crate ships.
    let shipped =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/models/detector.onnx");
    let mut from_file = match Detector::open(&DetectorModel::File(shipped)) {
        Ok(d) => d,
        Err(e) => panic!("{e}"),
    };
    assert_eq!(from_file.card(), detector.card());
    let Ok(c) = from_file.detect(&image) else {
        panic!("detect");
    };
    assert_eq!(a, c);
}

/// A model card that is missing or names a bad threshold is refused, naming file and field.
#[test]
fn bad_model_card_is_refused_with_its_file_and_field() {
    let dir = common::out_dir("detect", "card");
    let onnx = dir.join("net.onnx");
    let shipped =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/models/detector.onnx");
    std::fs::copy(&shipped, &onnx).unwrap_or_else(|e| panic!("{e}"));
    let Err(e) = Detector::load(&onnx) else {
        panic!("loaded without a card");
    };
    assert!(e.to_string().contains("net.json"), "{e}");
    let card =
        std::fs::read_to_string(shipped.with_extension("json")).unwrap_or_else(|e| panic!("{e}"));
    let bad = card.replacen("\"score_threshold\": ", "\"score_threshold\": 7", 1);
    std::fs::write(dir.join("net.json"), bad).unwrap_or_else(|e| panic!("{e}"));
    let Err(e) = Detector::load(&onnx) else {
        panic!("loaded a bad card");
    };
    assert!(e.to_string().contains("score_threshold"), "{e}");
}
