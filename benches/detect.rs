//! The detector's cost per frame (`cargo bench --bench detect`): one rendered 640x480
//! pick-station image through the shipped network on ort's tract backend (letterbox to the
//! card's input, network, decoding and NMS), the letterbox alone, and the network alone (named
//! after its input size).

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use twincell::cell::CellModel;
use twincell::detect::Detector;
use twincell::render::{CameraRig, Renderer, RendererOptions, Shot};
use twincell::scenario::Scenario;

fn detect_benches(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/paper_50.toml");
    let mut scenario = match Scenario::load(&path) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    };
    scenario.camera.resolution_px = [640, 480];
    let Ok(rig) = CameraRig::from_scenario(&scenario) else {
        panic!("camera");
    };
    let mut renderer = match Renderer::new(RendererOptions::default()) {
        Ok(r) => r,
        Err(e) => panic!("{e}"),
    };
    let shot = match Shot::pick_station(
        &CellModel::with_urdf(scenario.clone(), None).expect("cell model"),
        &rig,
        &scenario.sensor,
        0,
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
    let mut group = c.benchmark_group("detect");
    group.measurement_time(Duration::from_secs(10));
    group.sample_size(30);
    group.bench_function("detect_640x480", |b| {
        b.iter(|| match detector.detect(black_box(&image)) {
            Ok(d) => black_box(d),
            Err(e) => panic!("{e}"),
        })
    });
    group.bench_function("letterbox_640x480", |b| {
        b.iter(|| match detector.preprocess(black_box(&image)) {
            Ok(input) => black_box(input),
            Err(e) => panic!("{e}"),
        })
    });
    let input = match detector.preprocess(&image) {
        Ok((input, _)) => input,
        Err(e) => panic!("{e}"),
    };
    let card = detector.card();
    let network = format!("network_{}x{}", card.input_width, card.input_height);
    group.bench_function(network, |b| {
        b.iter(|| match detector.run_raw(black_box(&input)) {
            Ok(raw) => black_box(raw),
            Err(e) => panic!("{e}"),
        })
    });
    group.finish();
}

criterion_group!(benches, detect_benches);
criterion_main!(benches);
