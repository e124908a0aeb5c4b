//! The smallest bore the station's finder looks for, from the catalogue as the scenario's camera
//! images it at the pick station.
//!
//! The finder's default floor (10 frame pixels of radius, `BoreDetectorParams::default`) suits
//! the paper's camera, where the smallest bore asked for images at about 12. A user's camera
//! (farther, wider, coarser) or a user's small tube can image a bore below it, and then no bore
//! is ever found and every such part is unidentified. So the floor comes down to a share of the
//! smallest bore the catalogue holds, as imaged at the station (the minor axis of its ellipse in
//! a tilted view), never below a few sensor pixels. A camera that coarse measures worse: its band
//! is what `twincell calibrate` reports for it.

use std::f64::consts::TAU;

use nalgebra::{Point3, Vector3};

use crate::camera::CameraCalibration;
use crate::perception::BoreDetectorParams;
use crate::scenario::{CameraSection, Scenario};

/// Share of the smallest bore's imaged radius that the floor comes down to: a bore fitted a
/// little small (blur, the chamfer's shade) still passes.
const FLOOR_SHARE: f64 = 0.7;
/// The lowest floor, sensor pixels of radius: below it a bore's rim has too few edge points for
/// the fit and the roundness.
const LEAST_RADIUS_PX: f64 = 4.0;
/// Points around a bore's rim projected to find the imaged ellipse's minor semi-axis.
const RIM_POINTS: usize = 36;

/// The finder's parameters for `scenario`'s camera `calibration`, whose sensor reads areas of
/// interest at `roi_scale` pixels a frame pixel: the defaults at that scale, with the smallest
/// radius brought down where the catalogue's smallest bore images below it at the pick station.
pub fn station_bore_params(
    scenario: &Scenario,
    calibration: &CameraCalibration,
    roi_scale: u32,
) -> BoreDetectorParams {
    let scale = f64::from(roi_scale);
    let mut params = BoreDetectorParams::default().at_scale(scale);
    let station = CameraSection::pick_station(&scenario.conveyor);
    let smallest_px = scenario
        .part_types
        .iter()
        .filter_map(|t| {
            let face = Point3::new(station[0], station[1], station[2] + t.height_mm / 1000.0);
            imaged_radius_px(calibration, &face, t.bore_diameter_mm / 2000.0)
        })
        .fold(f64::INFINITY, f64::min)
        * scale;
    if smallest_px.is_finite() {
        let floor = (FLOOR_SHARE * smallest_px).max(LEAST_RADIUS_PX);
        params.min_radius_px = params.min_radius_px.min(floor);
    }
    params
}

/// The smallest distance, frame pixels, from the image of `centre` to the image of a horizontal
/// circle of `radius_m` about it: the imaged ellipse's minor semi-axis, near enough. `None`
/// where part of the circle lies behind the camera.
pub fn imaged_radius_px(
    calibration: &CameraCalibration,
    centre: &Point3<f64>,
    radius_m: f64,
) -> Option<f64> {
    let c = calibration.project(centre)?;
    (0..RIM_POINTS)
        .map(|k| {
            let angle = TAU * k as f64 / RIM_POINTS as f64;
            let rim = centre + Vector3::new(radius_m * angle.cos(), radius_m * angle.sin(), 0.0);
            let p = calibration.project(&rim)?;
            Some((p[0] - c[0]).hypot(p[1] - c[1]))
        })
        .try_fold(f64::INFINITY, |least, r| Some(least.min(r?)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::CameraRig;
    use crate::rng::SimRng;
    use std::path::Path;

    /// A camera `distance_m` from `target`, `tilt` from straight down towards -y, with the given
    /// horizontal field of view and width (4:3).
    fn camera(
        target: &Point3<f64>,
        distance_m: f64,
        tilt: f64,
        fov_deg: f64,
        width: u32,
    ) -> CameraCalibration {
        let eye = target + Vector3::new(0.0, -tilt.sin(), tilt.cos()) * distance_m;
        let pose = CameraCalibration::look_at(&eye, target, &Vector3::x()).expect("a view");
        CameraCalibration::from_fov(width, width * 3 / 4, fov_deg.to_radians(), pose, target.z)
    }

    #[test]
    fn an_overhead_view_images_a_bore_at_focal_length_over_distance() {
        let mut rng = SimRng::new(5150);
        for _ in 0..50 {
            let target = Point3::new(rng.range(-0.3, 0.3), rng.range(-0.6, -0.3), 0.7);
            let distance = rng.range(0.35, 1.2);
            let fov = rng.range(35.0, 80.0);
            let width = [640, 1024, 1280, 2048][rng.below(4) as usize];
            let calibration = camera(&target, distance, 0.0, fov, width);
            let radius = rng.range(0.004, 0.045);
            let seen = imaged_radius_px(&calibration, &target, radius).expect("in front");
            // The rim is as deep as the centre, so the image radius is f r / d (the nearest
            // of the rim's points to the image of the centre, exactly).
            let expected = calibration.fx_px * radius / distance;
            assert!(
                (seen - expected).abs() < 1e-6 * expected,
                "{seen} vs {expected}"
            );
        }
    }

    #[test]
    fn a_tilted_view_images_the_minor_axis_shortened_by_the_tilt() {
        let mut rng = SimRng::new(2602);
        for _ in 0..50 {
            let target = Point3::new(0.0, -0.45, 0.75);
            let distance = rng.range(0.35, 1.2);
            let tilt = rng.range(5.0_f64, 35.0).to_radians();
            let calibration = camera(&target, distance, tilt, 50.0, 1280);
            let radius = rng.range(0.004, 0.045);
            let seen = imaged_radius_px(&calibration, &target, radius).expect("in front");
            let overhead = calibration.fx_px * radius / distance;
            let foreshortened = overhead * tilt.cos();
            // Perspective moves the ellipse's ends by a few per cent of the radius at most.
            assert!(
                (seen - foreshortened).abs() < 0.05 * overhead,
                "tilt {:.1} deg: {seen} vs {foreshortened}",
                tilt.to_degrees()
            );
        }
    }

    #[test]
    fn the_floor_comes_down_to_the_catalogues_smallest_bore_and_never_rises() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/paper_50.toml");
        let mut scenario = Scenario::load(&path).expect("paper_50");
        let default_floor = BoreDetectorParams::default().at_scale(2.0).min_radius_px;
        let mut rng = SimRng::new(24);
        for _ in 0..60 {
            // A camera of the envelope over the station, and one tube of the family.
            let [x, y, z] = CameraSection::pick_station(&scenario.conveyor);
            let distance = rng.range(0.35, 1.2);
            let tilt = rng.range(0.0_f64, 35.0).to_radians();
            let heading = rng.range(0.0, TAU);
            let eye = [
                x + distance * tilt.sin() * heading.cos(),
                y + distance * tilt.sin() * heading.sin(),
                z + distance * tilt.cos(),
            ];
            scenario.camera.position_m = Some(eye);
            scenario.camera.look_at_m = Some([x, y, z]);
            scenario.camera.horizontal_fov_deg = rng.range(35.0, 80.0);
            let width = [640, 1024, 1280, 2048][rng.below(4) as usize];
            scenario.camera.resolution_px = [width, width * 3 / 4];
            let bore_mm = rng.range(8.0, 90.0);
            scenario.part_types.truncate(1);
            scenario.part_types[0].bore_diameter_mm = bore_mm;
            scenario.part_types[0].outer_diameter_mm = bore_mm * rng.range(1.15, 3.0);
            scenario.part_types[0].height_mm = rng.range(30.0, 120.0);
            let Ok(rig) = CameraRig::from_scenario(&scenario) else {
                continue;
            };
            let params = station_bore_params(&scenario, &rig.calibration, 2);
            assert!(params.min_radius_px <= default_floor);
            assert!(params.min_radius_px >= LEAST_RADIUS_PX.min(default_floor));
            let face = Point3::new(x, y, z + scenario.part_types[0].height_mm / 1000.0);
            let imaged = 2.0 * imaged_radius_px(&rig.calibration, &face, bore_mm / 2000.0).unwrap();
            // The catalogue's bore images above the floor it sets, unless it images below the
            // least floor (a camera too coarse for that tube).
            assert!(
                imaged > params.min_radius_px || params.min_radius_px == LEAST_RADIUS_PX,
                "bore {bore_mm:.1} mm imaged {imaged:.1} px, floor {}",
                params.min_radius_px
            );
        }
    }
}
