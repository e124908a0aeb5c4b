//! The scenario's part types and bins as typed ids with SI sizes, built once from a validated
//! scenario: every stage after loading refers to a type or a bin by its id, never by its name.

use super::{PartType, Scenario};

/// Density of steel, kg/m^3: a part type's material unless it says otherwise.
pub const STEEL_DENSITY_KG_M3: f64 = 7850.0;

/// A part type: its place in the scenario's `part_types`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct PartTypeId(pub usize);

/// A bin: its place in the scenario's `bins`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct BinId(pub usize);

/// A part type in SI units.
#[derive(Debug, Clone, PartialEq)]
pub struct PartKind {
    /// The type's name, for records and reports.
    pub name: String,
    /// Nominal bore diameter, m.
    pub bore_diameter_m: f64,
    /// Outer diameter, m.
    pub outer_diameter_m: f64,
    /// Height, m.
    pub height_m: f64,
    /// Density, kg/m^3.
    pub density_kg_m3: f64,
    /// Grip force per jaw, N: the type's own, else the gripper's default.
    pub grip_force_n: f64,
    /// The bin the type goes to when accepted, if any.
    pub accept_bin: Option<BinId>,
}

impl PartKind {
    /// Outer radius, m.
    pub fn outer_radius_m(&self) -> f64 {
        self.outer_diameter_m / 2.0
    }

    /// Nominal bore radius, m.
    pub fn bore_radius_m(&self) -> f64 {
        self.bore_diameter_m / 2.0
    }

    /// The mass of the type's nominal tube (its bore at the nominal diameter), kg.
    pub fn mass_kg(&self) -> f64 {
        let area =
            std::f64::consts::PI * (self.outer_radius_m().powi(2) - self.bore_radius_m().powi(2));
        area * self.height_m * self.density_kg_m3
    }
}

/// The part types and bins of a scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct Catalogue {
    parts: Vec<PartKind>,
    bin_names: Vec<String>,
    reject: Option<BinId>,
    waste: Option<BinId>,
    collector: Option<BinId>,
}

impl Catalogue {
    /// The catalogue of a validated `scenario`.
    pub fn of(scenario: &Scenario) -> Self {
        let accept_bin = |part: &PartType| {
            scenario
                .bins
                .iter()
                .position(|b| !b.reject && b.accepts.contains(&part.name))
                .map(BinId)
        };
        let parts = scenario
            .part_types
            .iter()
            .map(|part| PartKind {
                name: part.name.clone(),
                bore_diameter_m: part.bore_diameter_mm / 1000.0,
                outer_diameter_m: part.outer_diameter_mm / 1000.0,
                height_m: part.height_mm / 1000.0,
                density_kg_m3: part.density_kg_m3,
                grip_force_n: part.grip_force_n.unwrap_or(scenario.gripper.grip_force_n),
                accept_bin: accept_bin(part),
            })
            .collect();
        Self {
            parts,
            bin_names: scenario.bins.iter().map(|b| b.name.clone()).collect(),
            reject: scenario.bins.iter().position(|b| b.reject).map(BinId),
            waste: scenario.bins.iter().position(|b| b.waste).map(BinId),
            collector: scenario.bins.iter().position(|b| b.collector).map(BinId),
        }
    }

    /// The part type `id`.
    pub fn part(&self, id: PartTypeId) -> &PartKind {
        &self.parts[id.0]
    }

    /// How many part types the catalogue holds.
    pub fn part_count(&self) -> usize {
        self.parts.len()
    }

    /// Every part type with its id.
    pub fn parts(&self) -> impl Iterator<Item = (PartTypeId, &PartKind)> {
        self.parts
            .iter()
            .enumerate()
            .map(|(i, p)| (PartTypeId(i), p))
    }

    /// The name of bin `id`.
    pub fn bin_name(&self, id: BinId) -> &str {
        &self.bin_names[id.0]
    }

    /// The bin that takes removed foreign objects (`waste = true`), if the scenario has one.
    pub fn waste_bin(&self) -> Option<BinId> {
        self.waste
    }

    /// The collector at the belt's end (`collector = true`), if the scenario has one.
    pub fn collector_bin(&self) -> Option<BinId> {
        self.collector
    }

    /// The bin a part of type `id` goes to when accepted or rejected, if the scenario has one.
    pub fn bin_for(&self, id: PartTypeId, accept: bool) -> Option<BinId> {
        if accept {
            self.part(id).accept_bin
        } else {
            self.reject
        }
    }
}
