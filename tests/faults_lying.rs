//! A tube fallen on its side, found in rendered frames alone: cameras drawn over the whole
//! envelope (tilt, direction, distance, roll, field of view, resolution) and tubes drawn over
//! the family (bore, outer to bore ratio, length), lying at any yaw near the pick station. The
//! finder places most of them (its middle, its axis, its size among the catalogue's), and
//! takes no standing tube (its bore shows) for a lying one.

mod common;

use std::path::Path;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};
use twincell::cell::{Cell, CellModel};
use twincell::render::family::TUBE_FAMILY;
use twincell::render::{CameraRig, ObjectKind, Renderer, RendererOptions, Scene, Shot};
use twincell::rng::SimRng;
use twincell::scenario::{CAMERA_ENVELOPE, CameraSection, Scenario};
use twincell::sim::{BoreForm, PartInstance};
use twincell::station::{LyingPartFinder, TubeSize};

/// Shots drawn.
const SHOTS: u64 = 24;

/// A scenario with a camera `distance_m` from the pick station, its axis `tilt_deg` from
/// vertical towards `azimuth_deg`, and no bottle.
fn with_camera(rng: &mut SimRng) -> Scenario {
    let path = common::scenario_path("paper_50.toml");
    let text = common::read(&path);
    let envelope = CAMERA_ENVELOPE;
    let station = CameraSection::pick_station(&common::paper_50().conveyor);
    let tilt = rng.range(0.0, envelope.max_tilt_deg).to_radians();
    let azimuth = rng.range(0.0, std::f64::consts::TAU);
    let distance = rng.range(envelope.distance_m[0], envelope.distance_m[1]);
    let eye = [
        station[0] + distance * tilt.sin() * azimuth.cos(),
        station[1] + distance * tilt.sin() * azimuth.sin(),
        station[2] + distance * tilt.cos(),
    ];
    let fov = rng.range(
        envelope.horizontal_fov_deg[0],
        envelope.horizontal_fov_deg[1],
    );
    let roll = rng.range(envelope.roll_deg[0], envelope.roll_deg[1]);
    let width = rng.range(640.0, 1280.0).round() as u32;
    let height = width * 3 / 4;
    let keys = format!(
        "[camera]\nposition_m = [{:?}, {:?}, {:?}]\n\
         look_at_m = [{:?}, {:?}, {:?}]\nroll_deg = {roll:?}\nhorizontal_fov_deg = {fov:?}\n\
         resolution_px = [{width}, {height}]\n",
        eye[0], eye[1], eye[2], station[0], station[1], station[2]
    );
    match Scenario::from_toml(&format!("{text}\n{keys}"), Path::new("lying.toml")) {
        Ok(mut s) => {
            s.bottle.enabled = false;
            s
        }
        Err(e) => panic!("scenario: {e}"),
    }
}

/// A tube of the family, drawn log-uniformly in bore, with its outer diameter and length.
fn family_tube(rng: &mut SimRng) -> PartInstance {
    let family = TUBE_FAMILY;
    let bore_m = (rng.range(family.bore_mm[0].ln(), family.bore_mm[1].ln())).exp() / 1e3;
    let outer_m = bore_m * rng.range(family.outer_to_bore[0], family.outer_to_bore[1]);
    let height_m = rng.range(family.height_mm[0], family.height_mm[1]) / 1e3;
    PartInstance {
        type_index: 0,
        type_name: "drawn".into(),
        outer_radius_m: outer_m / 2.0,
        height_m,
        mass_kg: 0.5,
        bore: BoreForm::Ellipse {
            a_m: bore_m / 2.0,
            b_m: bore_m / 2.0,
            angle_rad: 0.0,
        },
    }
}

/// Renders the cell of `scenario` with its part replaced by `tube` at `world_from_part`.
fn render(
    scenario: &Scenario,
    renderer: &mut Renderer,
    tube: &PartInstance,
    world_from_part: Isometry3<f64>,
    rng: &mut SimRng,
) -> (CameraRig, image::RgbImage) {
    let Ok(rig) = CameraRig::from_scenario(scenario) else {
        panic!("camera");
    };
    let model = CellModel::with_urdf(scenario.clone(), None).expect("cell model");
    let cell = Cell::build(&model, rng).expect("cell");
    let mut scene = Scene::from_cell(&cell, scenario);
    let body = scene
        .objects
        .iter()
        .find(|o| matches!(o.kind, ObjectKind::Part(_)))
        .and_then(|o| o.body)
        .expect("a part");
    // The drawn cameras stand anywhere around the station; the arm at home, which the cell's
    // own camera sees past, would stand in front of some of them.
    scene
        .objects
        .retain(|o| !matches!(o.kind, ObjectKind::Part(_)) && !o.name.ends_with("_Link"));
    scene.push_part(body, world_from_part, tube);
    let shot = Shot::of_scene(scenario, &rig, &scenario.sensor, scene, rng);
    match shot.render(renderer) {
        Ok(image) => (rig, image),
        Err(e) => panic!("render: {e}"),
    }
}

#[test]
fn lying_tubes_are_found_over_the_camera_envelope_and_the_tube_family() {
    let mut renderer = match Renderer::new(RendererOptions {
        msaa_samples: 4,
        supersample: 1,
    }) {
        Ok(r) => r,
        Err(e) => panic!("no renderer: {e}"),
    };
    let mut rng = SimRng::new(2828);
    let (mut found, mut tried, mut worst) = (0, 0, (0.0f64, 0.0f64, 0.0f64));
    let mut misses = Vec::new();
    for shot in 0..SHOTS {
        let scenario = with_camera(&mut rng);
        let tube = family_tube(&mut rng);
        let belt = &scenario.conveyor;
        let belt_top_z = belt.belt_center_m[2];
        // Lying near the station, wholly on the belt.
        let half = tube.height_m.max(2.0 * tube.outer_radius_m) / 2.0;
        let reach_y = (belt.width_m / 2.0 - half - 0.01).max(0.0);
        let centre = Point3::new(
            belt.photo_eye_x_m + rng.range(-0.08, 0.08),
            belt.belt_center_m[1] + rng.range(-reach_y, reach_y),
            belt_top_z + tube.outer_radius_m,
        );
        let yaw = rng.range(0.0, std::f64::consts::PI);
        let lying = Isometry3::from_parts(
            Translation3::from(centre.coords),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw)
                * UnitQuaternion::from_euler_angles(0.0, std::f64::consts::FRAC_PI_2, 0.0),
        );
        let (rig, image) = render(&scenario, &mut renderer, &tube, lying, &mut rng);
        // Its diameter must span the smallest face the family's detector is drawn for.
        let seen_px = rig.calibration.fx_px * 2.0 * tube.outer_radius_m
            / (rig.calibration.world_from_camera.translation.vector - centre.coords).norm();
        if seen_px < 20.0 {
            continue;
        }
        tried += 1;
        // The catalogue: the drawn tube among others of the family.
        let mut sizes: Vec<TubeSize> = (0..4)
            .map(|_| {
                let other = family_tube(&mut rng);
                TubeSize {
                    diameter_m: 2.0 * other.outer_radius_m,
                    length_m: other.height_m,
                }
            })
            .collect();
        let true_size = TubeSize {
            diameter_m: 2.0 * tube.outer_radius_m,
            length_m: tube.height_m,
        };
        sizes.insert(shot as usize % 5, true_size);
        let (x, y) = (belt.belt_center_m[0], belt.belt_center_m[1]);
        let belt_xy = [
            [x - belt.length_m / 2.0, x + belt.length_m / 2.0],
            [y - belt.width_m / 2.0, y + belt.width_m / 2.0],
        ];
        let finder = LyingPartFinder::new(rig.calibration, belt_top_z, belt_xy, sizes);
        let station = Point3::new(belt.photo_eye_x_m, belt.belt_center_m[1], belt_top_z);
        let Some(part) = finder.find(&image, &station, 0.3) else {
            misses.push(format!(
                "shot {shot}: {true_size:?} at yaw {:.0} deg not found",
                yaw.to_degrees()
            ));
            continue;
        };
        let offset_mm = (part.centre_in_world - centre).xy().norm() * 1e3;
        let diameter_err = (part.diameter_m - true_size.diameter_m).abs() / true_size.diameter_m;
        let length_err = (part.length_m - true_size.length_m).abs() / true_size.length_m;
        let yaw_err_deg = {
            let d = (part.yaw_rad - yaw).rem_euclid(std::f64::consts::PI);
            d.min(std::f64::consts::PI - d).to_degrees()
        };
        let ok_place = offset_mm < 0.25 * true_size.diameter_m.max(true_size.length_m) * 1e3;
        let ok_size = diameter_err < 0.2 && length_err < 0.2;
        // A tube about as long as it is wide shows no axis from above.
        let elongated = true_size.length_m > 1.3 * true_size.diameter_m
            || true_size.diameter_m > 1.3 * true_size.length_m;
        let ok_yaw = !elongated || yaw_err_deg < 10.0;
        if ok_place && ok_size && ok_yaw {
            found += 1;
            worst = (
                worst.0.max(offset_mm),
                worst.1.max(diameter_err.max(length_err)),
                worst.2.max(if elongated { yaw_err_deg } else { 0.0 }),
            );
        } else {
            misses.push(format!(
                "shot {shot}: {true_size:?} yaw {:.0}: off {offset_mm:.1} mm, diameter {:.1} %, \
                 length {:.1} %, axis {yaw_err_deg:.1} deg",
                yaw.to_degrees(),
                diameter_err * 100.0,
                length_err * 100.0
            ));
        }
    }
    println!(
        "{found} of {tried} lying tubes found; worst: {:.1} mm, size {:.1} %, axis {:.1} deg",
        worst.0,
        worst.1 * 100.0,
        worst.2
    );
    assert!(tried >= SHOTS as usize / 2, "only {tried} shots in view");
    // Measured: 14 of 21 (docs/faults.md); the misses are short wide discs and thin tubes
    // seen from the envelope's edge, whose shadowed side falls into the belt's darkness.
    assert!(
        found * 10 >= tried * 6,
        "{found} of {tried} found:\n{}",
        misses.join("\n")
    );
}

#[test]
fn a_standing_tube_shows_its_bore_and_is_not_taken_for_a_lying_one() {
    let mut renderer = match Renderer::new(RendererOptions {
        msaa_samples: 4,
        supersample: 1,
    }) {
        Ok(r) => r,
        Err(e) => panic!("no renderer: {e}"),
    };
    let mut rng = SimRng::new(2829);
    for _ in 0..8 {
        let scenario = with_camera(&mut rng);
        let model = CellModel::with_urdf(scenario.clone(), None).expect("cell model");
        let belt = &scenario.conveyor;
        let belt_top_z = belt.belt_center_m[2];
        // The scenario's own tube, standing at the station.
        let kind = model
            .catalogue()
            .part(twincell::scenario::PartTypeId(rng.below(6) as usize));
        let tube = PartInstance {
            type_index: 0,
            type_name: kind.name.clone(),
            outer_radius_m: kind.outer_radius_m(),
            height_m: kind.height_m,
            mass_kg: kind.mass_kg(),
            bore: BoreForm::Ellipse {
                a_m: kind.bore_radius_m(),
                b_m: kind.bore_radius_m(),
                angle_rad: 0.0,
            },
        };
        let standing = Isometry3::translation(
            belt.photo_eye_x_m,
            belt.belt_center_m[1],
            belt_top_z + kind.height_m / 2.0,
        );
        let (rig, image) = render(&scenario, &mut renderer, &tube, standing, &mut rng);
        let sizes = model
            .catalogue()
            .parts()
            .map(|(_, k)| TubeSize {
                diameter_m: k.outer_diameter_m,
                length_m: k.height_m,
            })
            .collect();
        let (x, y) = (belt.belt_center_m[0], belt.belt_center_m[1]);
        let belt_xy = [
            [x - belt.length_m / 2.0, x + belt.length_m / 2.0],
            [y - belt.width_m / 2.0, y + belt.width_m / 2.0],
        ];
        let finder = LyingPartFinder::new(rig.calibration, belt_top_z, belt_xy, sizes);
        let station = Point3::new(belt.photo_eye_x_m, belt.belt_center_m[1], belt_top_z);
        let found = finder.find(&image, &station, 0.3);
        assert!(
            found.is_none(),
            "{} standing taken for lying: {found:?}",
            kind.name
        );
    }
}
