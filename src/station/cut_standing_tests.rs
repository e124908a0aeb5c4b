//! A bottle the frame's border cuts, read from a painted frame by [`bottle_sightings`]: a
//! standing one is kept clear of standing (the border hides its upper body, and a lying reading
//! would leave most of its height unguarded), and a lying one is still read lying.

use image::{Rgb, RgbImage};
use nalgebra::{Isometry3, Point3, Vector3};

use super::{Evidence, RESIDUAL_SHARE, bottle_sightings};
use crate::camera::CameraCalibration;
use crate::render::material::Material;
use crate::render::mesh::Mesh;
use crate::rng::SimRng;
use crate::scenario::BottleSection;
use crate::station::BeltScene;
use crate::station::bottle_fit::tests::{BELT_TOP_Z, fitter};
use crate::station::bottle_fit::{BottleFitter, BottlePose};
use crate::station::bottle_outline::Cells;
use crate::station::silhouette::CutBox;
use crate::station::silhouette::box_residual_px;

const BELT: [u8; 3] = [40, 40, 45];
const BODY: [u8; 3] = [200, 205, 210];
const CAP: [u8; 3] = [30, 40, 120];

/// A 640 x 480 frame (half the calibration's pixels) of a dark belt with the bottle at `pose`
/// drawn: its mesh's triangles projected through the calibration and filled, the body bright,
/// then the cap dark blue.
fn painted(f: &BottleFitter, pose: &Isometry3<f64>) -> RgbImage {
    let mut image = RgbImage::from_pixel(640, 480, Rgb(BELT));
    let mesh = Mesh::bottle(f.radius_m, f.height_m);
    for cap in [false, true] {
        for t in mesh.vertices.chunks_exact(3) {
            if (t[0].material == Material::BOTTLE_CAP) != cap {
                continue;
            }
            let Some(uv) = t
                .iter()
                .map(|v| {
                    f.calibration
                        .project(&(pose * v.position))
                        .map(|[u, v]| [u / 2.0, v / 2.0])
                })
                .collect::<Option<Vec<[f64; 2]>>>()
            else {
                continue;
            };
            let colour = if cap { CAP } else { BODY };
            fill(&mut image, &uv, Rgb(colour));
        }
    }
    image
}

/// Fills the triangle `uv` (image pixels) in `image`: every pixel whose centre lies inside.
fn fill(image: &mut RgbImage, uv: &[[f64; 2]], colour: Rgb<u8>) {
    let (a, b, c) = (uv[0], uv[1], uv[2]);
    let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    if area == 0.0 {
        return;
    }
    let edge = |p: [f64; 2], q: [f64; 2], x: f64, y: f64| {
        ((q[0] - p[0]) * (y - p[1]) - (q[1] - p[1]) * (x - p[0])) * area.signum()
    };
    let (w, h) = (f64::from(image.width()), f64::from(image.height()));
    let x0 = a[0].min(b[0]).min(c[0]).floor().max(0.0) as u32;
    let x1 = a[0].max(b[0]).max(c[0]).ceil().min(w - 1.0).max(0.0) as u32;
    let y0 = a[1].min(b[1]).min(c[1]).floor().max(0.0) as u32;
    let y1 = a[1].max(b[1]).max(c[1]).ceil().min(h - 1.0).max(0.0) as u32;
    for y in y0..=y1 {
        for x in x0..=x1 {
            let (px, py) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
            if edge(a, b, px, py) >= 0.0 && edge(b, c, px, py) >= 0.0 && edge(c, a, px, py) >= 0.0 {
                image.put_pixel(x, y, colour);
            }
        }
    }
}

/// The horizontal distance between the middles of `pose` and `truth`'s bodies, m.
fn off_m(f: &BottleFitter, pose: &BottlePose, truth: &Isometry3<f64>) -> f64 {
    let middle = |w: &Isometry3<f64>| w * Point3::new(0.0, 0.0, f.height_m / 2.0);
    let d = middle(&pose.world_from_bottle) - middle(truth);
    d.x.hypot(d.y)
}

/// The fitter of [`fitter`]'s bottle seen by a camera `tilt_deg` off the vertical, framed.
fn tilted(tilt_deg: f64) -> BottleFitter {
    let station = Point3::new(0.05, -0.45, BELT_TOP_Z);
    let t = tilt_deg.to_radians();
    let eye = station + Vector3::new(0.58 * t.sin(), 0.0, 0.58 * t.cos());
    let pose = CameraCalibration::look_at(&eye, &station, &Vector3::x()).expect("pose");
    let calibration = CameraCalibration::from_fov(1280, 960, 44f64.to_radians(), pose, BELT_TOP_Z);
    let bottle = BottleSection {
        radius_m: fitter().radius_m,
        height_m: fitter().height_m,
        ..BottleSection::default()
    };
    BottleFitter::new(calibration, &bottle).with_frame(1280, 960)
}

/// Bottles drawn across the view's edges (standing, or lying at any yaw), each painted and its
/// box clipped to the frame as the detector's would be, read by [`bottle_sightings`]. Returns,
/// over the drawn cases, how many had a pose of their kind within 20 mm of the truth among the
/// sighting's poses, and how many had such a pose first.
fn read_cut(f: &BottleFitter, lying: bool, seed: u64) -> (usize, usize, usize) {
    let (mut kept, mut first) = (0, 0);
    let drawn = cut_bottles(f, lying, seed, 24);
    for (truth, detection, image) in &drawn {
        let bottle = crate::detect::Detection {
            class_id: 1,
            class_name: "bottle".into(),
            score: 0.9,
            box_px: detection.map(|c| c as f32),
        };
        let belt = BeltScene {
            top_z_m: BELT_TOP_Z,
            band: None,
            tubes: &[],
        };
        let (seen, _) =
            bottle_sightings(f, &[(0, *detection)], &[bottle], image, (1280, 960), &belt);
        let poses: Vec<&BottlePose> = seen.iter().flat_map(|s| &s.poses).collect();
        let right = |p: &BottlePose| p.lying == lying && off_m(f, p, truth) < 0.02;
        kept += usize::from(poses.iter().any(|p| right(p)));
        first += usize::from(poses.first().is_some_and(|p| right(p)));
    }
    (drawn.len(), kept, first)
}

/// Up to `count` bottles (standing, or lying at any yaw) drawn across the view's edges, each
/// with the detector's box (clipped to the frame, its whole sides drawn in) and its frame.
fn cut_bottles(
    f: &BottleFitter,
    lying: bool,
    seed: u64,
    count: usize,
) -> Vec<(Isometry3<f64>, [f64; 4], RgbImage)> {
    let mut rng = SimRng::new(seed);
    let mut drawn = Vec::new();
    for _ in 0..40 * count {
        if drawn.len() == count {
            break;
        }
        let yaw = rng.range(-std::f64::consts::PI, std::f64::consts::PI);
        let (dx, dy) = match rng.uniform() {
            u if u < 0.25 => (rng.range(0.17, 0.3), rng.range(-0.1, 0.1)),
            u if u < 0.5 => (-rng.range(0.17, 0.3), rng.range(-0.1, 0.1)),
            u if u < 0.75 => (rng.range(-0.15, 0.15), rng.range(0.12, 0.24)),
            _ => (rng.range(-0.15, 0.15), -rng.range(0.12, 0.24)),
        };
        let truth = f.pose_at(lying, yaw, 0.05 + dx, -0.45 + dy, BELT_TOP_Z);
        let Some(b) = f.projected_box(&truth) else {
            continue;
        };
        let Some(cut) = CutBox::of(&b, (1280.0, 960.0), 0.0) else {
            continue;
        };
        // The detector's box is drawn in by up to 24 px on each side the border leaves whole
        // (a box on a slant rounds the bottle's edge off).
        let mut detection = cut.clip(&b);
        for (side, c) in detection.iter_mut().enumerate() {
            if !cut.cut[side] {
                *c += rng.range(0.0, 24.0) * if side < 2 { 1.0 } else { -1.0 };
            }
        }
        // A tenth to a third of the bottle's box in the frame (the cases where the box left
        // in view fits a lying bottle as well), and no side under 24 px.
        let share = (detection[2] - detection[0]) * (detection[3] - detection[1])
            / ((b[2] - b[0]) * (b[3] - b[1]));
        if !(0.1..1.0 / 3.0).contains(&share)
            || (detection[2] - detection[0]).min(detection[3] - detection[1]) < 24.0
        {
            continue;
        }
        drawn.push((truth, detection, painted(f, &truth)));
    }
    drawn
}

#[test]
fn a_standing_bottle_the_border_cuts_is_kept_clear_of_standing() {
    for (tilt_deg, seed) in [(0.0, 3101), (20.0, 3102), (-30.0, 3103)] {
        let f = tilted(tilt_deg);
        let (cases, kept, first) = read_cut(&f, false, seed);
        assert!(cases >= 16, "tilt {tilt_deg}: only {cases} cut boxes drawn");
        // Measured: 24, 24 and 21 of 24 (the misses stand where the frame shows less than a
        // fifth of them).
        assert!(
            kept * 5 >= cases * 4,
            "tilt {tilt_deg}: a standing reading near the truth in {kept} of {cases} ({first} first)"
        );
    }
}

#[test]
fn a_lying_bottle_the_border_cuts_is_still_read_lying() {
    for (tilt_deg, seed) in [(0.0, 3201), (20.0, 3202), (-30.0, 3203)] {
        let f = tilted(tilt_deg);
        let (cases, kept, first) = read_cut(&f, true, seed);
        assert!(cases >= 16, "tilt {tilt_deg}: only {cases} cut boxes drawn");
        assert!(
            first * 10 >= cases * 9,
            "tilt {tilt_deg}: read lying near the truth first in {first} of {cases} ({kept} kept)"
        );
    }
}

/// The mechanism itself: where lying hypotheses explain a cut box and no standing one does,
/// the outline given the box's best standing hypothesis as a hidden one reads a standing
/// bottle standing; without it, only lying.
#[test]
fn the_outline_judges_a_hidden_standing_hypothesis_beside_the_lying_ones() {
    let (mut cases, mut with_hidden, mut without) = (0, 0, 0);
    for (tilt_deg, seed) in [(0.0, 3301), (20.0, 3302), (-30.0, 3303), (35.0, 3304)] {
        let f = tilted(tilt_deg);
        for (truth, detection, image) in cut_bottles(&f, false, seed, 60) {
            let Some(e) = Evidence::new(&image, 0.5, (1280, 960), &[detection]) else {
                continue;
            };
            let diagonal = (detection[2] - detection[0]).hypot(detection[3] - detection[1]);
            let explains = |p: &BottlePose| {
                f.projected_box(&p.world_from_bottle).is_some_and(|b| {
                    box_residual_px(&e.clip(b), &detection) <= RESIDUAL_SHARE * diagonal
                })
            };
            let candidates = f.fit_candidates(&detection, BELT_TOP_Z);
            let mut explaining: Vec<BottlePose> =
                candidates.iter().copied().filter(explains).collect();
            explaining.extend(
                f.cut_lying_candidates(&detection, BELT_TOP_Z)
                    .into_iter()
                    .filter(explains),
            );
            if explaining.is_empty() || explaining.iter().any(|p| !p.lying) {
                continue;
            }
            cases += 1;
            let hidden = candidates.iter().find(|p| !p.lying);
            let cells = Cells::read(&detection, &e, &[], |u, v| f.sees_belt(u, v, BELT_TOP_Z));
            let standing_near = |hidden: Option<&BottlePose>| {
                f.by_outline(&explaining, hidden, &detection, BELT_TOP_Z, &[], &cells)
                    .is_some_and(|(poses, _)| {
                        poses
                            .iter()
                            .any(|p| !p.lying && off_m(&f, p, &truth) < 0.02)
                    })
            };
            with_hidden += usize::from(standing_near(hidden));
            without += usize::from(standing_near(None));
        }
    }
    assert!(
        cases >= 8,
        "only {cases} boxes only lying hypotheses explain"
    );
    assert_eq!(without, 0, "read standing without the hidden hypothesis");
    // Measured: 11 of 14.
    assert!(
        with_hidden * 4 >= cases * 3,
        "read standing near the truth in {with_hidden} of {cases}"
    );
}
