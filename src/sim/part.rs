//! Axle parts and their true bore geometry.

use serde::{Deserialize, Serialize};

use crate::rng::SimRng;
use crate::scenario::{Catalogue, PartTypeId};

/// The true shape of a bore's edge: `r(theta)` about the bore's centre.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "form", rename_all = "snake_case")]
pub enum BoreForm {
    /// An ellipse with semi-axes `a >= b`, its major axis at `angle_rad` from the part's x axis.
    Ellipse {
        /// Semi-major axis, m.
        a_m: f64,
        /// Semi-minor axis, m.
        b_m: f64,
        /// Orientation of the major axis, rad.
        angle_rad: f64,
    },
    /// `r = mean + amplitude cos(lobes (theta - phase))`: a 2- or 3-lobed bore.
    Lobed {
        /// Mean radius, m.
        mean_radius_m: f64,
        /// Lobe amplitude, m.
        amplitude_m: f64,
        /// Number of lobes.
        lobes: u32,
        /// Phase, rad.
        phase_rad: f64,
    },
}

impl BoreForm {
    /// Radius of the bore edge at polar angle `theta_rad` about the centre, m.
    pub fn radius_at(&self, theta_rad: f64) -> f64 {
        match *self {
            Self::Ellipse {
                a_m,
                b_m,
                angle_rad,
            } => {
                let (s, c) = (theta_rad - angle_rad).sin_cos();
                a_m * b_m / ((b_m * c).powi(2) + (a_m * s).powi(2)).sqrt()
            }
            Self::Lobed {
                mean_radius_m,
                amplitude_m,
                lobes,
                phase_rad,
            } => mean_radius_m + amplitude_m * (f64::from(lobes) * (theta_rad - phase_rad)).cos(),
        }
    }

    /// Roundness error Rmax - Rmin about the true centre, m.
    pub fn roundness_m(&self) -> f64 {
        match *self {
            Self::Ellipse { a_m, b_m, .. } => a_m - b_m,
            Self::Lobed { amplitude_m, .. } => 2.0 * amplitude_m,
        }
    }

    /// Mean diameter of the edge over the angle, m (sampled; exact for lobed forms).
    pub fn mean_diameter_m(&self) -> f64 {
        let n = 720;
        let sum: f64 = (0..n)
            .map(|i| self.radius_at(std::f64::consts::TAU * f64::from(i) / f64::from(n)))
            .sum();
        2.0 * sum / f64::from(n)
    }
}

/// One part drawn for a trial: its type and true bore.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PartInstance {
    /// Index into the scenario's part table.
    pub type_index: usize,
    /// Type name.
    pub type_name: String,
    /// Outer radius, m.
    pub outer_radius_m: f64,
    /// Height, m.
    pub height_m: f64,
    /// Mass, kg (the tube's, bore removed).
    pub mass_kg: f64,
    /// The true bore edge.
    pub bore: BoreForm,
}

impl PartInstance {
    /// Draws a part of `catalogue`: uniform type, uniform true roundness in
    /// [0, `max_roundness_mm`], a random form.
    pub fn draw(catalogue: &Catalogue, max_roundness_mm: f64, rng: &mut SimRng) -> Self {
        let type_index = rng.below(catalogue.part_count() as u64) as usize;
        let part = catalogue.part(PartTypeId(type_index));
        let roundness_m = rng.range(0.0, max_roundness_mm) / 1000.0;
        let nominal_radius_m = part.bore_radius_m();
        let bore = match rng.below(3) {
            0 => BoreForm::Ellipse {
                a_m: nominal_radius_m + roundness_m / 2.0,
                b_m: nominal_radius_m - roundness_m / 2.0,
                angle_rad: rng.range(0.0, std::f64::consts::PI),
            },
            form => BoreForm::Lobed {
                mean_radius_m: nominal_radius_m,
                amplitude_m: roundness_m / 2.0,
                lobes: form as u32 + 1,
                phase_rad: rng.range(0.0, std::f64::consts::TAU),
            },
        };
        Self {
            type_index,
            type_name: part.name.clone(),
            outer_radius_m: part.outer_radius_m(),
            height_m: part.height_m,
            mass_kg: part.mass_kg(),
            bore,
        }
    }

    /// Mean bore radius, m (for the tube's inertia).
    pub fn bore_radius_m(&self) -> f64 {
        self.bore.mean_diameter_m() / 2.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roundness_is_rmax_minus_rmin_of_the_edge() {
        let forms = [
            BoreForm::Ellipse {
                a_m: 0.0152,
                b_m: 0.0148,
                angle_rad: 0.4,
            },
            BoreForm::Lobed {
                mean_radius_m: 0.02,
                amplitude_m: 0.0003,
                lobes: 3,
                phase_rad: 1.0,
            },
        ];
        for form in forms {
            let radii: Vec<f64> = (0..36_000)
                .map(|i| form.radius_at(std::f64::consts::TAU * f64::from(i) / 36_000.0))
                .collect();
            let max = radii.iter().copied().fold(f64::MIN, f64::max);
            let min = radii.iter().copied().fold(f64::MAX, f64::min);
            assert!((max - min - form.roundness_m()).abs() < 1e-9, "{form:?}");
        }
    }
}
