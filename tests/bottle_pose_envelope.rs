//! The bottle's fitted pose under cameras drawn over the whole envelope (issue 24): the optical
//! axis 0-35 degrees off the vertical towards any side, any roll, 0.35-1.2 m from the pick
//! station. The paper's cell (one bottle 0.10-0.16 m from the part), its bottles standing, or
//! half of them lying, is rendered and looked at by the product's pipeline (renderer, shipped
//! detector, bottle fit against the pixels); each bottle wholly in view that the detector boxed
//! is compared with the bottle as placed.
//!
//! The planner keeps clear of every pose a sighting holds, and approaches over the tallest: a
//! standing bottle taken for a lying one (or the reverse) puts a 200 mm obstacle where none is
//! and lets the arm come down onto the real bottle; a pose a few centimetres off lets the
//! fingers touch it. So every pose of the bottle's sighting must stand or lie as the bottle
//! does, its middle within `BOUND_M` of the truth. Main's fit (the box alone deciding, and
//! every pose within 2 px of the best box kept) took a standing bottle for a lying one in about
//! half the looks from 35 degrees, its middle 70-100 mm off.

mod common;

use nalgebra::{Isometry3, Point3, Vector3};
use twincell::cell::CellModel;
use twincell::render::{CameraRig, ObjectKind, Shot};
use twincell::rng::SimRng;
use twincell::scenario::{CameraSection, Scenario};
use twincell::station::{BottleFitter, CameraPerception, TargetRule};

/// Largest distance between a fitted pose's middle and the true bottle's, m (the fingers pass
/// the bottle 20 mm clear when the grasp allows).
const BOUND_M: f64 = 0.02;
/// Largest angle between a lying pose's axis and the true one's, either way along, degrees.
const BOUND_DEG: f64 = 12.0;

/// The paper's cell seen by a camera `distance_m` from the station, its axis `tilt_deg` from the
/// vertical towards `azimuth_deg`, rolled `roll_deg`; `lying` of its bottles lying.
fn cell(tilt_deg: f64, azimuth_deg: f64, distance_m: f64, roll_deg: f64, lying: f64) -> Scenario {
    let mut s = common::paper_50();
    let station = CameraSection::pick_station(&s.conveyor);
    let (t, a) = (tilt_deg.to_radians(), azimuth_deg.to_radians());
    s.camera.position_m = Some([
        station[0] + distance_m * t.sin() * a.cos(),
        station[1] + distance_m * t.sin() * a.sin(),
        station[2] + distance_m * t.cos(),
    ]);
    s.camera.look_at_m = Some(station);
    s.camera.roll_deg = roll_deg;
    s.bottle.lying_fraction = lying;
    s
}

#[derive(Debug, Default)]
struct Tally {
    /// Bottles wholly in view that a detector box holds.
    boxed: usize,
    /// Of those, the ones whose sighting's every pose is within the bounds.
    fitted: usize,
    /// The largest middle error of a pose of a boxed bottle's sighting, mm.
    worst_mm: f64,
}

/// Looks at `shots` staged pick stations of `scenario` and tallies the boxed bottles' fits.
fn tally(scenario: &Scenario, shots: u64, tally: &mut Tally, label: &str) {
    let model = CellModel::with_urdf(scenario.clone(), None).expect("cell model");
    let rig = CameraRig::from_scenario(scenario).expect("camera");
    let camera = CameraPerception::new(scenario, twincell::detect::DetectorModel::Shipped)
        .expect("camera pipeline");
    let belt_top_z = scenario.conveyor.belt_center_m[2];
    let h = scenario.bottle.height_m;
    let middle = |p: &Isometry3<f64>| p * Point3::new(0.0, 0.0, h / 2.0);
    let axis = |p: &Isometry3<f64>| p.rotation * Vector3::z();
    let station = Point3::from(CameraSection::pick_station(&scenario.conveyor));
    let (w, hh) = (f64::from(rig.width_px), f64::from(rig.height_px));
    let fitter = BottleFitter::new(rig.calibration, &scenario.bottle);
    for index in 0..shots {
        let Ok(shot) = Shot::pick_station(&model, &rig, &scenario.sensor, index) else {
            continue;
        };
        let truth: Vec<Isometry3<f64>> = shot
            .scene
            .objects
            .iter()
            .filter(|o| o.kind == ObjectKind::Bottle)
            .map(|o| o.world_from_object)
            .collect();
        let mut rng = SimRng::new(0xB0B0 + index);
        let sighting = camera
            .look(
                scenario,
                shot.scene,
                &mut rng,
                &station,
                belt_top_z,
                TargetRule::NearestStation,
            )
            .expect("look");
        for pose in &truth {
            let Some(b) = fitter.projected_box(pose) else {
                continue;
            };
            if !(b[0] > 2.0 && b[1] > 2.0 && b[2] < w - 2.0 && b[3] < hh - 2.0) {
                continue;
            }
            let box_of = |k: usize| sighting.detections[k].box_px.map(f64::from);
            let holds = |k: usize| {
                let [x0, y0, x1, y1] = box_of(k);
                let (u, v) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
                twincell::detect::is_foreign_class(&sighting.detections[k].class_name)
                    && (b[0]..=b[2]).contains(&u)
                    && (b[1]..=b[3]).contains(&v)
            };
            let Some(seen) = sighting
                .bottles
                .iter()
                .find(|s| s.detection < sighting.detections.len() && holds(s.detection))
            else {
                continue;
            };
            tally.boxed += 1;
            let lying = axis(pose).z.abs() < 0.7;
            let mut within = !seen.poses.is_empty();
            for p in &seen.poses {
                let off_m = (middle(&p.world_from_bottle) - middle(pose)).norm();
                let off_deg = axis(&p.world_from_bottle)
                    .dot(&axis(pose))
                    .abs()
                    .min(1.0)
                    .acos()
                    .to_degrees();
                tally.worst_mm = tally.worst_mm.max(off_m * 1e3);
                let ok = p.lying == lying && off_m <= BOUND_M && (!lying || off_deg <= BOUND_DEG);
                if !ok {
                    eprintln!(
                        "{label} shot {index}: {} bottle fitted {} {:.0} mm and {off_deg:.0} deg off",
                        if lying { "lying" } else { "standing" },
                        if p.lying { "lying" } else { "standing" },
                        off_m * 1e3
                    );
                }
                within &= ok;
            }
            tally.fitted += usize::from(within);
        }
    }
}

/// Cameras over the envelope, standing bottles and a lying/standing mix: at least 85 % of the
/// boxed bottles are fitted within the bounds in every pose their sighting holds. The outline's
/// fit gives 46 of 51 here; main's (each box's poses by the box alone) gave 39 of 51, most of the
/// misses a standing bottle fitted lying 70-100 mm off from 30-35 degrees.
#[test]
fn bottles_are_fitted_within_bounds_over_the_camera_envelope() {
    let mut rng = SimRng::new(2424);
    let mut all = Tally::default();
    for draw in 0..12 {
        let tilt = match draw {
            0 => 0.0,
            1 | 2 => 35.0,
            _ => rng.range(0.0, 35.0),
        };
        let azimuth = rng.range(0.0, 360.0);
        let distance = rng.range(0.35, 1.2);
        let roll = rng.range(-180.0, 180.0);
        let lying = if draw % 3 == 2 { 0.5 } else { 0.0 };
        let label = format!(
            "tilt {tilt:.0} az {azimuth:.0} at {distance:.2} m roll {roll:.0} lying {lying}"
        );
        let before = (all.boxed, all.fitted);
        tally(
            &cell(tilt, azimuth, distance, roll, lying),
            8,
            &mut all,
            &label,
        );
        eprintln!(
            "{label}: {}/{} boxed bottles fitted within bounds",
            all.fitted - before.1,
            all.boxed - before.0
        );
    }
    eprintln!("{all:?}");
    assert!(all.boxed >= 50, "{all:?}");
    assert!(all.fitted * 20 >= 17 * all.boxed, "{all:?}");
}
