//! A lying bottle the frame's border cuts is placed by the sides of its box the border leaves
//! whole ([`BottleFitter::cut_lying_candidates`]).

use nalgebra::{Point3, Vector3};

use super::BottleFitter;
use super::tests::{BELT_TOP_Z, fitter};
use crate::rng::SimRng;
use crate::station::silhouette::CutBox;

/// How far the nearest of `poses` lies from `truth` (a lying bottle): its middle's distance, m,
/// among those whose axis line is within 10 degrees of the truth's.
fn nearest_m(
    f: &BottleFitter,
    truth: &nalgebra::Isometry3<f64>,
    poses: &[super::BottlePose],
) -> f64 {
    let middle = |w: &nalgebra::Isometry3<f64>| w * Point3::new(0.0, 0.0, f.height_m / 2.0);
    let axis = |w: &nalgebra::Isometry3<f64>| w.rotation * Vector3::z();
    poses
        .iter()
        .filter(|p| {
            p.lying && axis(&p.world_from_bottle).dot(&axis(truth)).abs() > 10f64.to_radians().cos()
        })
        .map(|p| (middle(&p.world_from_bottle) - middle(truth)).norm())
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn a_lying_bottle_the_border_cuts_is_placed_by_its_whole_sides() {
    let whole = fitter();
    let framed = fitter().with_frame(1280, 960);
    let station = [0.05, -0.45];
    let mut rng = SimRng::new(2212);
    let (mut cases, mut centred_off) = (0, 0);
    for _ in 0..200 {
        // Lying across the view's edges at any yaw: part of it out of view.
        let yaw = rng.range(-std::f64::consts::PI, std::f64::consts::PI);
        let (dx, dy) = match rng.uniform() {
            u if u < 0.25 => (rng.range(0.2, 0.3), rng.range(-0.1, 0.1)),
            u if u < 0.5 => (-rng.range(0.2, 0.3), rng.range(-0.1, 0.1)),
            u if u < 0.75 => (rng.range(-0.15, 0.15), rng.range(0.16, 0.24)),
            _ => (rng.range(-0.15, 0.15), -rng.range(0.16, 0.24)),
        };
        let truth = whole.pose_at(true, yaw, station[0] + dx, station[1] + dy, BELT_TOP_Z);
        let Some(b) = whole.projected_box(&truth) else {
            continue;
        };
        let Some(cut) = CutBox::of(&b, (1280.0, 960.0), 0.0) else {
            continue;
        };
        let detection = cut.clip(&b);
        // At least a fifth of the bottle's box in the frame, and not a sliver.
        if (detection[2] - detection[0]) * (detection[3] - detection[1])
            < 0.2 * (b[2] - b[0]) * (b[3] - b[1])
            || (detection[2] - detection[0]).min(detection[3] - detection[1]) < 20.0
        {
            continue;
        }
        cases += 1;
        let by_sides = framed.cut_lying_candidates(&detection, BELT_TOP_Z);
        let near = nearest_m(&framed, &truth, &by_sides);
        assert!(
            near < 0.01,
            "yaw {yaw:.2}, ({dx:.3}, {dy:.3}): the nearest lying pose by the whole sides is {:.1} mm off",
            near * 1e3
        );
        assert!(
            whole
                .cut_lying_candidates(&detection, BELT_TOP_Z)
                .is_empty()
        );
        let centred = nearest_m(
            &whole,
            &truth,
            &whole.fit_candidates(&detection, BELT_TOP_Z),
        );
        centred_off += usize::from(centred > 0.01);
    }
    assert!(cases >= 60, "only {cases} cut boxes drawn");
    // Centred on the cut box, most lying hypotheses miss the bottle.
    assert!(
        2 * centred_off > cases,
        "centred hypotheses missed {centred_off} of {cases}"
    );
}
