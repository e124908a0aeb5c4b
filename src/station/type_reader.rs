//! The camera's way of naming the target part's type (`[perception] type_by`): by measurement,
//! the default (the bore found in the area of interest read on every type's end-face plane and
//! matched against the catalogue's nominal sizes and tolerances), or by the detector's class.

use crate::camera::CameraCalibration;
use crate::perception::Bore;
use crate::perception::identify::{TypeCall, TypeSize, identify, read_on_plane};
use crate::scenario::{Scenario, TypeBy};

/// The catalogue as the measurement sees it.
#[derive(Debug, Clone)]
pub struct TypeReader {
    type_by: TypeBy,
    names: Vec<String>,
    sizes: Vec<TypeSize>,
    heights_m: Vec<f64>,
    /// The type an unmeasured part is handled as: the widest, then tallest (a conservative
    /// obstacle).
    bulkiest: usize,
}

/// What the camera decided about the target's type.
#[derive(Debug, Clone, PartialEq)]
pub struct TypeDecision {
    /// The scenario type whose geometry the cell handles the part with.
    pub type_index: usize,
    /// Why the part is unidentified, when it is (the sorter rejects it).
    pub unidentified: Option<String>,
}

impl TypeReader {
    /// The reader for `scenario`'s catalogue.
    pub fn new(scenario: &Scenario) -> Self {
        let types = &scenario.part_types;
        let bulkiest = (0..types.len())
            .max_by(|&a, &b| {
                let key = |i: usize| (types[i].outer_diameter_mm, types[i].height_mm);
                key(a)
                    .partial_cmp(&key(b))
                    .unwrap_or(std::cmp::Ordering::Equal)
            })
            .unwrap_or(0);
        Self {
            type_by: scenario.perception.type_by,
            names: types.iter().map(|t| t.name.clone()).collect(),
            sizes: types
                .iter()
                .map(|t| TypeSize {
                    bore_m: t.bore_diameter_mm / 1e3,
                    outer_m: t.outer_diameter_mm / 1e3,
                    tolerance_m: t.diameter_tolerance_mm() / 1e3,
                })
                .collect(),
            heights_m: types.iter().map(|t| t.height_mm / 1e3).collect(),
            bulkiest,
        }
    }

    /// How types are named.
    pub fn type_by(&self) -> TypeBy {
        self.type_by
    }

    /// The type a part that was not measured is handled as.
    pub fn bulkiest(&self) -> usize {
        self.bulkiest
    }

    /// Names the type of a part whose end face shows `bore` in the image of `calibration` (its
    /// end-face height is set per type; the belt's top is at `belt_top_z_m`).
    pub fn decide(
        &self,
        bore: &Bore,
        calibration: &CameraCalibration,
        belt_top_z_m: f64,
    ) -> TypeDecision {
        let readings: Option<Vec<_>> = self
            .heights_m
            .iter()
            .zip(&self.sizes)
            .map(|(h, size)| {
                let face = calibration.with_end_face_height(belt_top_z_m + h);
                read_on_plane(bore, &face, size.outer_m / 2.0)
            })
            .collect();
        let Some(readings) = readings else {
            return TypeDecision {
                type_index: self.bulkiest,
                unidentified: Some("the bore could not be read on the end-face planes".into()),
            };
        };
        let call = identify(&self.sizes, &readings);
        let type_index = call.handling_type();
        let read = &readings[type_index];
        let sizes = match read.outer_m {
            Some(outer) => format!(
                "bore {:.2} mm, outer {:.2} mm",
                read.bore_m * 1e3,
                outer * 1e3
            ),
            None => format!("bore {:.2} mm, outer not found", read.bore_m * 1e3),
        };
        let unidentified = match &call {
            TypeCall::Identified(_) => None,
            TypeCall::NoFit { nearest } => Some(format!(
                "no type fits the end face ({sizes} on {}'s plane; nearest {} at {:.1} tolerances)",
                self.names[*nearest],
                self.names[*nearest],
                crate::perception::identify::misfit(&self.sizes[*nearest], read)
            )),
            TypeCall::Ambiguous(types) => Some(format!(
                "types {} all fit the end face ({sizes} on {}'s plane)",
                types
                    .iter()
                    .map(|&t| self.names[t].as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
                self.names[type_index]
            )),
        };
        TypeDecision {
            type_index,
            unidentified,
        }
    }

    /// A part the camera found no bore in: unidentified, handled as the bulkiest type.
    pub fn unmeasured(&self) -> TypeDecision {
        TypeDecision {
            type_index: self.bulkiest,
            unidentified: Some("no bore was measured to name the type by".into()),
        }
    }
}
