//! Naming a tube's type by measuring it, as dimensional sorting cells do: the image of one end
//! face is measured on the end-face plane of every candidate type (at that type's height, since
//! the camera's scale depends on it), and the type whose nominal bore and outer diameters both
//! lie within its tolerance of those readings is the part's type. None fitting, or several,
//! leaves the part unidentified: the sorter then rejects it rather than guess.

use crate::camera::CameraCalibration;
use crate::perception::Bore;
use crate::perception::circle_fit::fit_geometric_over_angle;
use crate::perception::roundness::median_of;

/// A catalogue type's nominal sizes and the tolerance within which a reading names it, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TypeSize {
    /// Nominal bore diameter.
    pub bore_m: f64,
    /// Nominal outer diameter.
    pub outer_m: f64,
    /// Largest difference between a reading and a nominal diameter that still fits.
    pub tolerance_m: f64,
}

/// One end face measured on one candidate type's end-face plane, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SizeReading {
    /// Bore diameter.
    pub bore_m: f64,
    /// Outer diameter, when the rim's outer edge was found (it is not on a belt as bright as
    /// the rim, or where a neighbour touches all round): the bore alone decides then.
    pub outer_m: Option<f64>,
}

/// The outcome of [`identify`].
#[derive(Debug, Clone, PartialEq)]
pub enum TypeCall {
    /// Exactly this type fits.
    Identified(usize),
    /// No type fits; `nearest` misses by the least (in tolerances), for the grasp's geometry.
    NoFit {
        /// The type with the smallest misfit.
        nearest: usize,
    },
    /// These types all fit (ascending); the first is also the nearest.
    Ambiguous(Vec<usize>),
}

impl TypeCall {
    /// The type whose geometry the cell handles the part with: the identified one, else the
    /// nearest candidate.
    pub fn handling_type(&self) -> usize {
        match self {
            Self::Identified(t) | Self::NoFit { nearest: t } => *t,
            Self::Ambiguous(types) => types[0],
        }
    }
}

/// Reads `bore` (found in `calibration`'s image) on `calibration`'s end-face plane, for a
/// candidate type of outer radius `outer_radius_m`: the bore's diameter is that of the circle
/// fitted to its edge points back-projected there; the outer diameter is read from the rim's
/// outer edge points back-projected there too ([`outer_diameter_on_plane`]). `None` when a bore
/// edge point's ray misses the plane or the fit fails.
pub fn read_on_plane(
    bore: &Bore,
    calibration: &CameraCalibration,
    outer_radius_m: f64,
) -> Option<SizeReading> {
    let on_plane = |points: &[[f64; 2]]| {
        points
            .iter()
            .map(|p| calibration.pixel_to_plane(p[0], p[1]).map(|q| [q.x, q.y]))
            .collect::<Result<Vec<_>, _>>()
            .ok()
    };
    let fit = fit_geometric_over_angle(&on_plane(&bore.edge_points_px)?).ok()?;
    let eye = calibration.origin_in_world();
    let outer_m = on_plane(&bore.outer_edge_points_px).and_then(|points| {
        outer_diameter_on_plane(&points, fit.centre, [eye.x, eye.y], outer_radius_m)
    });
    Some(SizeReading {
        bore_m: 2.0 * fit.radius,
        outer_m,
    })
}

/// Fewest outer edge points [`outer_diameter_on_plane`] reads a diameter from.
pub const MIN_OUTER_POINTS: usize = 5;

/// The outer diameter of an end face from its rim's outer edge `points` on the end-face plane,
/// about the bore's centre `centre` there, seen by a camera whose centre lies above `eye` (world
/// x, y), for a tube of outer radius `outer_radius_m`; m.
///
/// Beyond the end face's outer edge, where the camera looks down on the tube's side wall, the
/// image shows the wall, not the belt: the rim's walk may run on down the wall, and the point it
/// stops at, cast onto the end-face plane, lies outside the edge. The wall at a point of
/// direction `n` from the axis is in view when the camera lies beyond the wall's tangent plane
/// there, `(eye - centre) . n > outer_radius_m`. So only the points where it is hidden count, and
/// the diameter is twice their median distance from the bore's centre (the bore and the outer
/// surface are turned on one axis). Under a camera straight above the part every point counts;
/// under one tilted 35° about half. `None` with fewer than [`MIN_OUTER_POINTS`].
pub fn outer_diameter_on_plane(
    points: &[[f64; 2]],
    centre: [f64; 2],
    eye: [f64; 2],
    outer_radius_m: f64,
) -> Option<f64> {
    let to_eye = [eye[0] - centre[0], eye[1] - centre[1]];
    let mut radii: Vec<f64> = points
        .iter()
        .filter_map(|p| {
            let d = [p[0] - centre[0], p[1] - centre[1]];
            let r = d[0].hypot(d[1]);
            let towards_eye = (to_eye[0] * d[0] + to_eye[1] * d[1]) / r;
            (r > 0.0 && towards_eye < outer_radius_m).then_some(r)
        })
        .collect();
    (radii.len() >= MIN_OUTER_POINTS).then(|| 2.0 * median_of(&mut radii))
}

/// How far `reading` lies from `size`, in tolerances: the larger of the bore's and the outer
/// diameter's differences over the tolerance; at most 1 means it fits.
pub fn misfit(size: &TypeSize, reading: &SizeReading) -> f64 {
    let bore = (reading.bore_m - size.bore_m).abs();
    let outer = reading.outer_m.map_or(0.0, |o| (o - size.outer_m).abs());
    bore.max(outer) / size.tolerance_m
}

/// Names the type of a part from `readings[i]`, its end face measured on type `i`'s plane, for
/// the catalogue `sizes` (same order). `sizes` must not be empty.
pub fn identify(sizes: &[TypeSize], readings: &[SizeReading]) -> TypeCall {
    let misfits: Vec<f64> = sizes
        .iter()
        .zip(readings)
        .map(|(size, reading)| misfit(size, reading))
        .collect();
    let nearest = (0..misfits.len())
        .min_by(|&a, &b| misfits[a].total_cmp(&misfits[b]))
        .unwrap_or(0);
    let mut fitting: Vec<usize> = (0..misfits.len()).filter(|&i| misfits[i] <= 1.0).collect();
    match fitting.len() {
        0 => TypeCall::NoFit { nearest },
        1 => TypeCall::Identified(fitting[0]),
        _ => {
            fitting.sort_by(|&a, &b| misfits[a].total_cmp(&misfits[b]).then(a.cmp(&b)));
            TypeCall::Ambiguous(fitting)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    fn size(bore_mm: f64, outer_mm: f64, tol_mm: f64) -> TypeSize {
        TypeSize {
            bore_m: bore_mm / 1e3,
            outer_m: outer_mm / 1e3,
            tolerance_m: tol_mm / 1e3,
        }
    }

    fn reading(bore_mm: f64, outer_mm: Option<f64>) -> SizeReading {
        SizeReading {
            bore_m: bore_mm / 1e3,
            outer_m: outer_mm.map(|o| o / 1e3),
        }
    }

    #[test]
    fn the_type_within_tolerance_on_both_diameters_is_named() {
        let sizes = [size(20.0, 34.0, 1.0), size(20.0, 40.0, 1.0)];
        let r = [reading(20.4, Some(39.3)), reading(20.4, Some(39.3))];
        assert_eq!(identify(&sizes, &r), TypeCall::Identified(1));
    }

    #[test]
    fn no_fit_and_two_fits_leave_the_part_unidentified() {
        let sizes = [size(20.0, 34.0, 1.0), size(24.0, 38.0, 1.0)];
        let far = [reading(22.0, Some(36.0)), reading(22.0, Some(36.0))];
        assert!(matches!(identify(&sizes, &far), TypeCall::NoFit { .. }));
        let wide = [size(20.0, 34.0, 3.0), size(24.0, 38.0, 3.0)];
        let both = [reading(22.0, Some(36.0)), reading(22.5, Some(36.5))];
        assert_eq!(identify(&wide, &both), TypeCall::Ambiguous(vec![1, 0]));
    }

    /// The outer edge is read to within a pixel over the family's walls (outer/bore 1.15-3) and
    /// bores from 14 px: the ratio is taken to the fitted bore, not the coarse outline.
    #[test]
    fn the_rim_walk_reads_the_outer_edge_over_the_walls_of_the_family() {
        use crate::perception::synthetic::Scene;
        use crate::perception::{BoreDetector, BoreDetectorParams};
        let detector = BoreDetector::new(BoreDetectorParams::default());
        let mut rng = crate::rng::SimRng::new(24);
        let mut worst: f64 = 0.0;
        for _ in 0..40 {
            let r = rng.range(14.0, 60.0);
            let ratio = rng.range(1.15, 3.0);
            let outer = r * ratio;
            let side = (2.0 * outer + 40.0).ceil() as u32;
            let c = f64::from(side) / 2.0 + rng.range(-0.5, 0.5);
            let image = Scene::one_tube(side, [c, c], r, outer).render();
            let bores = detector.detect(&image).unwrap_or_default();
            let [bore] = bores.as_slice() else {
                panic!("r {r:.1} ratio {ratio:.2}: {} bores", bores.len());
            };
            let error = bore.outer_ratio * bore.radius_px - outer;
            worst = worst.max(error.abs());
            assert!(
                error.abs() < 1.0,
                "r {r:.1} ratio {ratio:.2}: off {error:.2} px"
            );
        }
        eprintln!("outer radius within {worst:.2} px");
    }

    /// Points on the arc where the side wall faces the camera lie outside the edge (the walk ran
    /// on down the wall); only the others are read, wherever the camera stands.
    #[test]
    fn the_outer_diameter_is_read_where_the_side_wall_is_hidden() {
        let mut rng = crate::rng::SimRng::new(2424);
        for _ in 0..200 {
            let outer_r = rng.range(0.008, 0.06);
            let centre = [rng.range(-0.2, 0.2), rng.range(-0.6, -0.3)];
            let (azimuth, reach) = (rng.range(0.0, TAU), rng.range(0.0, 0.9));
            let eye = [
                centre[0] + reach * azimuth.cos(),
                centre[1] + reach * azimuth.sin(),
            ];
            let points: Vec<[f64; 2]> = (0..32)
                .map(|i| {
                    let a = TAU * (f64::from(i) + 0.5) / 32.0;
                    let n = [a.cos(), a.sin()];
                    let wall_seen =
                        (eye[0] - centre[0]) * n[0] + (eye[1] - centre[1]) * n[1] > outer_r;
                    let r = if wall_seen { outer_r + 0.004 } else { outer_r };
                    [centre[0] + r * n[0], centre[1] + r * n[1]]
                })
                .collect();
            let Some(d) = outer_diameter_on_plane(&points, centre, eye, outer_r) else {
                panic!("reach {reach:.3} m, outer radius {outer_r:.3} m: no reading");
            };
            assert!(
                (d - 2.0 * outer_r).abs() < 1e-9,
                "read {d}, true {}",
                2.0 * outer_r
            );
        }
        assert!(outer_diameter_on_plane(&[[0.01, 0.0]; 4], [0.0, 0.0], [0.0, 0.0], 0.01).is_none());
    }

    #[test]
    fn without_an_outer_reading_the_bore_alone_decides() {
        let sizes = [size(20.0, 34.0, 1.0), size(20.0, 40.0, 1.0)];
        let r = [reading(20.2, None), reading(20.2, None)];
        assert_eq!(identify(&sizes, &r), TypeCall::Ambiguous(vec![0, 1]));
        let one = [size(20.0, 34.0, 1.0)];
        assert_eq!(
            identify(&one, &[reading(19.5, None)]),
            TypeCall::Identified(0)
        );
    }
}
