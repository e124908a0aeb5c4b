//! The camera's cost per frame (`cargo bench --bench render`): render + readback of the
//! pick-station scene at 640x480 and 1280x960 (4x MSAA), the scene's meshes already on the
//! device as in a running trial; plus the sensor effects (and their reference implementation),
//! uploading a scene and a whole staged shot. Prints the adapter's name: without a GPU it is the software adapter (llvmpipe or
//! lavapipe).
//!
//! Two groups: `render` measures wall-clock time; `render_cpu` measures the CPU time of the whole
//! process (every thread: on a software adapter the rasteriser's threads do most of the work),
//! which a machine shared with other jobs inflates far less than wall time. `render_cpu` also
//! breaks a frame down: an empty frame (clear, MSAA resolve, readback) and the frame without
//! MSAA, and measures the sensor effects (fast and reference) by CPU time as well.
//!
//! `look_frame_*` (both groups, 1280x960): the whole frame a look hands the detector, sensor
//! effects included: drawn with one sample per pixel at the frame's size (as before issue 29's
//! binned frame), and binned 4x4 on the sensor at the detector's own resolution (320x240, 4x
//! MSAA; `Shot::render_binned`, what a look draws now).

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::measurement::Measurement;
use criterion::{BenchmarkGroup, Criterion, criterion_group, criterion_main};
use image::RgbImage;
use twincell::cell::CellModel;
use twincell::render::{
    CameraRig, Exposure, GpuScene, Renderer, RendererOptions, Scene, Shot, reader_bin,
};
use twincell::scenario::Scenario;

#[path = "common/cpu_time.rs"]
mod cpu_time;
use cpu_time::ProcessCpuTime;

const RESOLUTIONS: [(u32, u32); 2] = [(640, 480), (1280, 960)];

fn scenario() -> Scenario {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/paper_50.toml");
    match Scenario::load(&path) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    }
}

fn renderer(msaa_samples: u32) -> Renderer {
    let options = RendererOptions {
        msaa_samples,
        supersample: 1,
    };
    let renderer = match Renderer::new(options) {
        Ok(r) => r,
        Err(e) => panic!("{e}"),
    };
    eprintln!(
        "render bench adapter: {} ({msaa_samples}x MSAA)",
        renderer.adapter_name()
    );
    renderer
}

/// The bench shot (paper_50's first pick-station shot) at a resolution.
fn staged(scenario: &Scenario, rig: &CameraRig, index: u64) -> Shot {
    match Shot::pick_station(
        &CellModel::with_urdf(scenario.clone(), None).expect("cell model"),
        rig,
        &scenario.sensor,
        index,
    ) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    }
}

fn rig(scenario: &Scenario, width: u32, height: u32) -> CameraRig {
    match CameraRig::from_scenario(scenario) {
        Ok(rig) => rig.with_resolution(width, height),
        Err(e) => panic!("{e}"),
    }
}

/// One frame rendered and read back.
fn frame(renderer: &mut Renderer, gpu: &GpuScene, exposure: &Exposure) -> RgbImage {
    match renderer.render(gpu, exposure) {
        Ok(image) => image,
        Err(e) => panic!("{e}"),
    }
}

/// The look's frame for the detector, sensor effects included: one sample per pixel at the
/// frame's size, and binned at the detector's resolution (the letterbox's whole factor into the
/// shipped detector's 320x256 input: 4 at 1280x960).
fn look_frame_benches<M: Measurement>(
    group: &mut BenchmarkGroup<'_, M>,
    renderer: &mut Renderer,
    gpu: &GpuScene,
    shot: &Shot,
) {
    let (w, h) = (shot.exposure.width_px, shot.exposure.height_px);
    group.bench_function(format!("look_frame_single_sample_{w}x{h}"), |b| {
        b.iter(|| match shot.render_uploaded(renderer, gpu) {
            Ok(image) => black_box(image),
            Err(e) => panic!("{e}"),
        })
    });
    let bin = reader_bin((w, h), (320, 256));
    group.bench_function(format!("look_frame_binned_{bin}x{bin}_{w}x{h}"), |b| {
        b.iter(|| match shot.render_binned(renderer, gpu, bin) {
            Ok(image) => black_box(image),
            Err(e) => panic!("{e}"),
        })
    });
}

/// The sensor model on a clean `frame` of `shot`: the fast path, and the model's plain
/// definition, which the fast path is tested against.
fn sensor_benches<M: Measurement>(
    group: &mut BenchmarkGroup<'_, M>,
    shot: &Shot,
    frame: &RgbImage,
    (w, h): (u32, u32),
) {
    group.bench_function(format!("sensor_effects_{w}x{h}"), |b| {
        b.iter(|| {
            let mut image = frame.clone();
            shot.sensor.apply(&mut image);
            black_box(image)
        })
    });
    group.bench_function(format!("sensor_effects_reference_{w}x{h}"), |b| {
        b.iter(|| {
            let mut image = frame.clone();
            shot.sensor
                .apply_window_reference(&mut image, (0, 0), (w, h));
            black_box(image)
        })
    });
}

fn render_benches(c: &mut Criterion) {
    let scenario = scenario();
    let mut renderer = renderer(4);
    let mut group = c.benchmark_group("render");
    group.measurement_time(Duration::from_secs(5));
    group.sample_size(30);
    for (w, h) in RESOLUTIONS {
        let rig = rig(&scenario, w, h);
        let shot = staged(&scenario, &rig, 0);
        let gpu = renderer.upload(&shot.scene);
        group.bench_function(format!("render_readback_{w}x{h}"), |b| {
            b.iter(|| black_box(frame(&mut renderer, &gpu, &shot.exposure)))
        });
        // The look's frame for the detector: one sample per pixel on the same renderer.
        group.bench_function(format!("render_readback_single_sample_{w}x{h}"), |b| {
            b.iter(
                || match renderer.render_single_sample(&gpu, &shot.exposure) {
                    Ok(image) => black_box(image),
                    Err(e) => panic!("{e}"),
                },
            )
        });
        if w == 1280 {
            look_frame_benches(&mut group, &mut renderer, &gpu, &shot);
        }
        let clean = frame(&mut renderer, &gpu, &shot.exposure);
        sensor_benches(&mut group, &shot, &clean, (w, h));
        group.bench_function(format!("upload_{w}x{h}"), |b| {
            b.iter(|| black_box(renderer.upload(&shot.scene)))
        });
        group.bench_function(format!("staged_shot_{w}x{h}"), |b| {
            b.iter(|| match staged(&scenario, &rig, 1).render(&mut renderer) {
                Ok(image) => black_box(image),
                Err(e) => panic!("{e}"),
            })
        });
    }
    group.finish();
}

fn cpu_benches(c: &mut Criterion<ProcessCpuTime>) {
    let scenario = scenario();
    let mut msaa = renderer(4);
    let mut plain = renderer(1);
    let empty = msaa.upload(&Scene::default());
    let mut group = c.benchmark_group("render_cpu");
    group.measurement_time(Duration::from_secs(5));
    group.sample_size(30);
    for (w, h) in RESOLUTIONS {
        let shot = staged(&scenario, &rig(&scenario, w, h), 0);
        let gpu = msaa.upload(&shot.scene);
        group.bench_function(format!("render_readback_{w}x{h}"), |b| {
            b.iter(|| black_box(frame(&mut msaa, &gpu, &shot.exposure)))
        });
        group.bench_function(format!("empty_frame_{w}x{h}"), |b| {
            b.iter(|| black_box(frame(&mut msaa, &empty, &shot.exposure)))
        });
        let gpu = plain.upload(&shot.scene);
        group.bench_function(format!("render_readback_no_msaa_{w}x{h}"), |b| {
            b.iter(|| black_box(frame(&mut plain, &gpu, &shot.exposure)))
        });
        // The sensor model runs on the calling thread only: its CPU time is its cost with
        // little of the inflation that other jobs on the machine add to wall time.
        let gpu = msaa.upload(&shot.scene);
        if w == 1280 {
            look_frame_benches(&mut group, &mut msaa, &gpu, &shot);
        }
        let clean = frame(&mut msaa, &gpu, &shot.exposure);
        sensor_benches(&mut group, &shot, &clean, (w, h));
    }
    group.finish();
}

criterion_group!(benches, render_benches);
criterion_group! {
    name = cpu;
    config = Criterion::default().with_measurement(ProcessCpuTime);
    targets = cpu_benches
}
criterion_main!(benches, cpu);
