//! Whether the metrology can tell a catalogue's types apart. The camera names a type by
//! measuring the end face on each type's end-face plane (see the perception station); a reading
//! names a type when its bore and outer diameters both lie within the type's tolerance. Two
//! types are confusable when one reading can fit both: a part of one type, measured within its
//! tolerance on its own plane, then also fits the other on the other's plane. The camera's scale
//! on a plane goes as one over its depth along the optical axis, so a taller type's plane reads
//! the same image larger.

use super::Scenario;

/// A type's nominal sizes, its tolerance and the depth of its end-face plane at the station.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SizedType {
    /// Nominal bore diameter, mm.
    pub bore_mm: f64,
    /// Nominal outer diameter, mm.
    pub outer_mm: f64,
    /// Diameter tolerance, mm.
    pub tolerance_mm: f64,
    /// Depth of the end face's centre along the camera's optical axis, m.
    pub depth_m: f64,
}

/// Two types one reading can fit, and by how much they would have to differ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Confusion {
    /// Index of the first type.
    pub first: usize,
    /// Index of the second type (after the first).
    pub second: usize,
    /// The first type's bore and outer diameters as read on the second's plane, less the
    /// second's, mm (absolute).
    pub gaps_mm: [f64; 2],
    /// What one of the gaps must exceed: the two tolerances on the second's plane, mm.
    pub needed_mm: f64,
}

/// Whether `a` and `b` can be confused: `Some` with the gaps and the margin needed.
pub fn confusion(a: &SizedType, b: &SizedType) -> Option<([f64; 2], f64)> {
    let k = b.depth_m / a.depth_m;
    let needed = a.tolerance_mm * k + b.tolerance_mm;
    let gaps = [
        (a.bore_mm * k - b.bore_mm).abs(),
        (a.outer_mm * k - b.outer_mm).abs(),
    ];
    (gaps[0] <= needed && gaps[1] <= needed).then_some((gaps, needed))
}

/// The first pair of `types` one reading can fit, if any.
pub fn first_confusion(types: &[SizedType]) -> Option<Confusion> {
    for (i, a) in types.iter().enumerate() {
        for (j, b) in types.iter().enumerate().skip(i + 1) {
            if let Some((gaps_mm, needed_mm)) = confusion(a, b) {
                return Some(Confusion {
                    first: i,
                    second: j,
                    gaps_mm,
                    needed_mm,
                });
            }
        }
    }
    None
}

impl Scenario {
    /// The scenario's part types as the camera sees them at the pick station.
    pub fn sized_types(&self) -> Vec<SizedType> {
        let (eye, target) = self.camera.eye_and_target(&self.conveyor);
        let axis: Vec<f64> = (0..3).map(|i| target[i] - eye[i]).collect();
        let norm = axis.iter().map(|v| v * v).sum::<f64>().sqrt();
        let [_, y, top] = self.conveyor.belt_center_m;
        let station = [self.conveyor.photo_eye_x_m, y, top];
        self.part_types
            .iter()
            .map(|part| {
                let face = [station[0], station[1], station[2] + part.height_mm / 1e3];
                let depth = (0..3).map(|i| (face[i] - eye[i]) * axis[i]).sum::<f64>() / norm;
                SizedType {
                    bore_mm: part.bore_diameter_mm,
                    outer_mm: part.outer_diameter_mm,
                    tolerance_mm: part.diameter_tolerance_mm(),
                    depth_m: depth,
                }
            })
            .collect()
    }
}

/// Why `scenario`'s catalogue cannot be measured apart, naming both types and the margin
/// needed; `None` when every pair can be told apart. Types must lie in front of the camera.
pub fn confusable_types(scenario: &Scenario) -> Option<String> {
    let c = first_confusion(&scenario.sized_types())?;
    let (a, b) = (
        &scenario.part_types[c.first].name,
        &scenario.part_types[c.second].name,
    );
    Some(format!(
        "types {a:?} and {b:?} cannot be told apart by measurement: on {b:?}'s end-face plane \
         their bores differ by {:.2} mm and their outer diameters by {:.2} mm, and one of them \
         must differ by more than {:.2} mm (the two types' diameter_tolerance_mm as seen there); \
         make the sizes differ more or narrow the tolerances",
        c.gaps_mm[0], c.gaps_mm[1], c.needed_mm
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sized(bore_mm: f64, outer_mm: f64, depth_m: f64) -> SizedType {
        SizedType {
            bore_mm,
            outer_mm,
            tolerance_mm: 1.0,
            depth_m,
        }
    }

    #[test]
    fn one_diameter_apart_by_more_than_both_tolerances_separates_two_types() {
        let a = sized(20.0, 34.0, 0.52);
        assert!(confusion(&a, &sized(20.0, 36.5, 0.52)).is_none());
        assert!(confusion(&a, &sized(21.5, 35.5, 0.52)).is_some());
    }

    #[test]
    fn a_taller_type_reads_the_same_image_larger() {
        // 20 mm at 0.52 m depth images like 19.2 mm at 0.50 m: one tolerance apart.
        let a = sized(20.0, 34.0, 0.52);
        let b = sized(19.2, 32.7, 0.50);
        let Some((gaps, needed)) = confusion(&a, &b) else {
            panic!("a and b read alike");
        };
        assert!(gaps[0] < 0.05 && gaps[1] < 0.05, "{gaps:?}");
        assert!((needed - (0.5 / 0.52 + 1.0)).abs() < 1e-9);
        assert_eq!(confusion(&b, &a).map(|(g, _)| g[0] < 0.1), Some(true));
    }
}
