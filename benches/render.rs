//! The camera's cost per frame (`cargo bench --bench render`): render + readback of the
//! pick-station scene at 640x480 and 1280x960 (4x MSAA), the scene's meshes already on the
//! device as in a running trial; plus the sensor effects and a whole staged shot.
//! Prints the adapter's name: without a GPU it is the software adapter (llvmpipe or lavapipe).

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use twincell::render::{CameraRig, Renderer, RendererOptions, Shot};
use twincell::scenario::Scenario;

fn render_benches(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/paper_50.toml");
    let scenario = match Scenario::load(&path) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    };
    let Ok(rig) = CameraRig::from_scenario(&scenario) else {
        panic!("camera");
    };
    let mut renderer = match Renderer::new(RendererOptions::default()) {
        Ok(r) => r,
        Err(e) => panic!("{e}"),
    };
    let adapter = renderer.adapter_name();
    eprintln!("render bench adapter: {adapter}");
    let mut group = c.benchmark_group("render");
    group.measurement_time(Duration::from_secs(5));
    for (w, h) in [(640, 480), (1280, 960)] {
        let rig = rig.with_resolution(w, h);
        let shot = match Shot::pick_station(&scenario, None, &rig, &scenario.sensor, 0) {
            Ok(s) => s,
            Err(e) => panic!("{e}"),
        };
        let gpu = renderer.upload(&shot.scene);
        group.bench_function(format!("render_readback_{w}x{h}"), |b| {
            b.iter(|| match renderer.render(&gpu, &shot.exposure) {
                Ok(image) => black_box(image),
                Err(e) => panic!("{e}"),
            })
        });
        let Ok(clean) = renderer.render(&gpu, &shot.exposure) else {
            panic!("render");
        };
        group.bench_function(format!("sensor_effects_{w}x{h}"), |b| {
            b.iter(|| {
                let mut image = clean.clone();
                shot.sensor.apply(&mut image);
                black_box(image)
            })
        });
        group.bench_function(format!("staged_shot_{w}x{h}"), |b| {
            b.iter(|| {
                let shot = match Shot::pick_station(&scenario, None, &rig, &scenario.sensor, 1) {
                    Ok(s) => s,
                    Err(e) => panic!("{e}"),
                };
                match shot.render(&mut renderer) {
                    Ok(image) => black_box(image),
                    Err(e) => panic!("{e}"),
                }
            })
        });
    }
    group.finish();
    eprintln!("render bench adapter: {adapter}");
}

criterion_group!(benches, render_benches);
criterion_main!(benches);
