//! What naming a part's type by measurement adds per part (`cargo bench --bench identify`):
//! the target's bore, already found in its area of interest, read on every catalogue type's
//! end-face plane and matched against the types' sizes. The bore is a synthetic tube's of the
//! size the default camera's area of interest shows a 20 mm bore at (about 55 px), found by the
//! real detector; the catalogues are the paper's 6 types and a user's 8.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use twincell::perception::synthetic::Scene;
use twincell::perception::{Bore, BoreDetector, BoreDetectorParams};
use twincell::render::CameraRig;
use twincell::scenario::Scenario;
use twincell::station::TypeReader;

fn bore() -> Bore {
    let image = Scene::one_tube(260, [130.3, 129.6], 55.0, 93.0).render();
    let detector = BoreDetector::new(BoreDetectorParams::default().at_scale(2.0));
    let bores = detector.detect(&image).expect("detects");
    bores.into_iter().next().expect("one bore")
}

fn identify(c: &mut Criterion) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let bore = bore();
    for file in [
        "scenarios/paper_50.toml",
        "tests/data/own_catalogues/own_8_types.toml",
    ] {
        let scenario = Scenario::load(&root.join(file)).expect("scenario");
        let rig = CameraRig::from_scenario(&scenario).expect("camera");
        let reader = TypeReader::new(&scenario);
        let belt_top = scenario.conveyor.belt_center_m[2];
        let name = format!("identify/{} types", scenario.part_types.len());
        c.bench_function(&name, |b| {
            b.iter(|| black_box(reader.decide(black_box(&bore), &rig.calibration, belt_top)))
        });
    }
}

criterion_group!(benches, identify);
criterion_main!(benches);
