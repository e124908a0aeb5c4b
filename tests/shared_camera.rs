//! What the camera's workers share gives what each would get alone, bit for bit: a renderer's
//! sibling (one device, one compilation of the shaders) draws on another thread the images the
//! first renderer draws, the process's shared detector is one instance and finds what a detector
//! of its own finds, and the detector reading a look's binned frame finds what it finds in that
//! frame spread to its own pitch. Shots drawn over several seeds, resolutions and sensors (the
//! scenario's and a harsh one); renders on whatever adapter wgpu finds.

mod common;

use std::sync::Arc;

use twincell::cell::CellModel;
use twincell::detect::{Detector, DetectorModel};
use twincell::render::binned::unbin;
use twincell::render::{CameraRig, Shot, reader_bin};
use twincell::scenario::{Scenario, SensorSection};

/// Seeds no other test draws shots from.
const SEEDS: [u64; 3] = [9101, 9102, 9103];

fn scenario_at(seed: u64, resolution_px: [u32; 2]) -> Scenario {
    let mut s = common::paper_50();
    s.seed = seed;
    s.camera.resolution_px = resolution_px;
    s
}

fn harsh() -> SensorSection {
    SensorSection {
        noise_sigma: 6.0,
        salt_pepper_fraction: 0.002,
        illumination_gradient: 0.3,
        vignetting: 0.4,
        max_stains: 4,
        max_dirt: 10,
        light_jitter_deg: 20.0,
        intensity_jitter: 0.3,
        pose_jitter_m: 0.0005,
        pose_jitter_deg: 0.05,
    }
}

/// Pick-station shots of `scenario`, `per_sensor` with its own sensor and as many harsh ones.
fn shots(scenario: &Scenario, per_sensor: u64) -> Vec<Shot> {
    let Ok(rig) = CameraRig::from_scenario(scenario) else {
        panic!("camera");
    };
    let model = CellModel::with_urdf(scenario.clone(), None).expect("cell model");
    let mut out = Vec::new();
    for sensor in [scenario.sensor.clone(), harsh()] {
        for index in 0..per_sensor {
            match Shot::pick_station(&model, &rig, &sensor, index) {
                Ok(s) => out.push(s),
                Err(e) => panic!("shot {index}: {e}"),
            }
        }
    }
    out
}

#[test]
fn a_sibling_renderer_draws_what_its_first_draws_on_another_thread() {
    let scenario = scenario_at(SEEDS[0], [640, 480]);
    let shots = shots(&scenario, 2);
    let mut first = common::renderer(&scenario);
    let mut sibling = first.sibling();
    // The sibling draws first, on its own thread, so the pipelines are built by whichever
    // renderer gets there and then used by the other.
    let by_sibling: Vec<_> = std::thread::scope(|scope| {
        scope
            .spawn(|| {
                shots
                    .iter()
                    .map(|shot| match shot.render(&mut sibling) {
                        Ok(image) => image,
                        Err(e) => panic!("sibling: {e}"),
                    })
                    .collect()
            })
            .join()
            .expect("sibling thread")
    });
    for (shot, theirs) in shots.iter().zip(&by_sibling) {
        let Ok(mine) = shot.render(&mut first) else {
            panic!("first renderer");
        };
        assert_eq!(&mine, theirs);
    }
    // Images that differ between shots: the comparison above is not of blank frames.
    assert_ne!(by_sibling[0], by_sibling[1]);
}

#[test]
fn the_shared_detector_is_one_instance_and_detects_as_its_own_would() {
    let Ok(a) = Detector::shared(&DetectorModel::Shipped) else {
        panic!("shared detector");
    };
    let Ok(b) = Detector::shared(&DetectorModel::Shipped) else {
        panic!("shared detector");
    };
    assert!(Arc::ptr_eq(&a, &b));
    let Ok(mut own) = Detector::load_default() else {
        panic!("detector");
    };
    assert_eq!(a.card(), own.card());
    let scenario = scenario_at(SEEDS[1], [640, 480]);
    let mut renderer = common::renderer(&scenario);
    let mut found = 0;
    for shot in shots(&scenario, 3) {
        let Ok(image) = shot.render(&mut renderer) else {
            panic!("render");
        };
        let (Ok(shared), Ok(alone)) = (b.detect(&image), own.detect(&image)) else {
            panic!("detect");
        };
        assert_eq!(shared, alone);
        found += alone.len();
    }
    assert!(found > 0, "no detections to compare");
}

#[test]
fn a_binned_frame_detects_as_the_frame_at_its_own_pitch() {
    let Ok(mut detector) = Detector::load_default() else {
        panic!("detector");
    };
    let input = (detector.card().input_width, detector.card().input_height);
    for (seed, resolution) in [(SEEDS[2], [1280, 960]), (SEEDS[1], [640, 480])] {
        let scenario = scenario_at(seed, resolution);
        let bin = reader_bin((resolution[0], resolution[1]), input);
        assert!(bin >= 2, "{resolution:?} is read through block means");
        let mut renderer = common::renderer(&scenario);
        let mut found = 0;
        for shot in shots(&scenario, 2) {
            let gpu = renderer.upload(&shot.scene);
            let frame = match shot.render_binned_frame(&mut renderer, &gpu, bin) {
                Ok(f) => f,
                Err(e) => panic!("render: {e}"),
            };
            assert_eq!(frame.bin, bin);
            let spread = unbin(&frame.binned, bin);
            let (Ok(from_binned), Ok(from_frame)) = (
                detector.detect_binned(&frame.binned, bin),
                detector.detect(&spread),
            ) else {
                panic!("detect");
            };
            assert_eq!(from_binned, from_frame, "{resolution:?}");
            found += from_frame.len();
            assert_eq!(frame.into_frame(), spread);
        }
        assert!(found > 0, "{resolution:?}: no detections to compare");
    }
    // A binned image that is not the input's fitted size is refused, not misread.
    let odd = image::RgbImage::new(300, 200);
    assert!(detector.detect_binned(&odd, 4).is_err());
}
