//! Naming a tube's type by measuring it, as dimensional sorting cells do: the image of one end
//! face is measured on the end-face plane of every candidate type (at that type's height, since
//! the camera's scale depends on it), and the type whose nominal bore and outer diameters both
//! lie within its tolerance of those readings is the part's type. None fitting, or several,
//! leaves the part unidentified: the sorter then rejects it rather than guess.

use crate::camera::CameraCalibration;
use crate::perception::Bore;
use crate::perception::circle_fit::fit_geometric;

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

/// Reads `bore` (found in `calibration`'s image) on `calibration`'s end-face plane: the
/// diameter of the circle fitted to its edge points back-projected there, and the outer
/// diameter as the rim's measured outer-to-bore ratio times it (both circles lie on that plane,
/// so the image ratio carries over). `None` when an edge point's ray misses the plane or the
/// fit fails.
pub fn read_on_plane(bore: &Bore, calibration: &CameraCalibration) -> Option<SizeReading> {
    let points = bore
        .edge_points_px
        .iter()
        .map(|p| calibration.pixel_to_plane(p[0], p[1]).map(|q| [q.x, q.y]))
        .collect::<Result<Vec<_>, _>>()
        .ok()?;
    let diameter = 2.0 * fit_geometric(&points).ok()?.radius;
    Some(SizeReading {
        bore_m: diameter,
        outer_m: (bore.outer_ratio.is_finite() && bore.outer_ratio > 1.0)
            .then_some(bore.outer_ratio * diameter),
    })
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
