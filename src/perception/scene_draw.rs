//! Random scenes of the twin's own kind at three difficulties: one to four tubes with catalogue-
//! like walls, light and noise from none to heavy, stains and bottles (see
//! [`crate::perception::scene_space`] for scenes drawn over the whole space `measure` covers).

use crate::perception::synthetic::{BoreShape, Bottle, Illumination, Noise, Scene, Stain, Tube};
use crate::rng::SimRng;
use std::f64::consts::{PI, TAU};

/// How hard a random scene is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Difficulty {
    /// No noise, even light, no stains or bottles.
    Clean,
    /// Moderate sensor noise, a light gradient, a stain and a bottle.
    Moderate,
    /// Strong noise, heavy salt-and-pepper, vignetting, stains and bottles.
    Heavy,
}

/// Draws a random scene of `difficulty`, all from `seed`.
///
/// Tubes have bore radii of 20-120 px (circles, ellipses, 2- and 3-lobe bores), wall thicknesses
/// of 8-60 px; bottles and stains are placed apart from the tubes' end faces except for stains,
/// which may lie on rims.
pub fn random_scene(seed: u64, width_px: u32, height_px: u32, difficulty: Difficulty) -> Scene {
    let mut rng = SimRng::new(seed);
    let (w, h) = (f64::from(width_px), f64::from(height_px));
    let max_bore_px = (w.min(h) / 2.0 - 30.0).clamp(20.0, 120.0) / 1.5;
    let mut discs: Vec<([f64; 2], f64)> = Vec::new();
    let place = |rng: &mut SimRng, radius: f64, discs: &mut Vec<([f64; 2], f64)>| {
        for _ in 0..200 {
            let c = [
                rng.range(radius + 4.0, w - radius - 4.0),
                rng.range(radius + 4.0, h - radius - 4.0),
            ];
            if discs.iter().all(|(d, r)| {
                ((c[0] - d[0]).powi(2) + (c[1] - d[1]).powi(2)).sqrt() > r + radius + 6.0
            }) {
                discs.push((c, radius));
                return Some(c);
            }
        }
        None
    };
    let tube_count = 1 + (rng.next_u64() % 4) as usize;
    let mut tubes = Vec::new();
    for i in 0..tube_count {
        let mean_radius = rng.range(20.0, 20.0f64.max(max_bore_px));
        let wall = rng.range(
            8.0f64.max(0.2 * mean_radius),
            10.0f64.max(0.5 * mean_radius),
        );
        let bore = match (i + (seed % 3) as usize) % 3 {
            0 => BoreShape::Circle {
                radius_px: mean_radius,
            },
            1 => {
                let diff = rng.range(0.0, 0.1 * mean_radius);
                BoreShape::Ellipse {
                    a_px: mean_radius + diff / 2.0,
                    b_px: mean_radius - diff / 2.0,
                    angle_rad: rng.range(0.0, PI),
                }
            }
            _ => BoreShape::Lobed {
                mean_radius_px: mean_radius,
                amplitude_px: rng.range(0.0, 4.0f64.min(0.08 * mean_radius)),
                lobes: 2 + (rng.next_u64() % 2) as u32,
                phase_rad: rng.range(0.0, TAU),
            },
        };
        let outer = bore.max_radius_px() + wall;
        let Some(c) = place(&mut rng, outer, &mut discs) else {
            continue;
        };
        tubes.push(Tube {
            centre_px: c,
            bore,
            outer_radius_px: outer,
            rim_level: rng.range(170.0, 225.0),
            bore_level: rng.range(10.0, 35.0),
        });
    }
    let mut bottles = Vec::new();
    let mut stains = Vec::new();
    let (illumination, noise) = match difficulty {
        Difficulty::Clean => (Illumination::EVEN, Noise::NONE),
        Difficulty::Moderate => (
            Illumination {
                gradient_x: rng.range(-0.3, 0.3),
                gradient_y: rng.range(-0.3, 0.3),
                vignetting: rng.range(0.0, 0.2),
            },
            Noise {
                sigma: rng.range(2.0, 6.0),
                salt_pepper: rng.range(0.0, 0.005),
            },
        ),
        Difficulty::Heavy => (
            Illumination {
                gradient_x: rng.range(-0.5, 0.5),
                gradient_y: rng.range(-0.5, 0.5),
                vignetting: rng.range(0.2, 0.4),
            },
            Noise {
                sigma: rng.range(6.0, 12.0),
                salt_pepper: rng.range(0.02, 0.06),
            },
        ),
    };
    if difficulty != Difficulty::Clean {
        let bottle_count = if difficulty == Difficulty::Heavy {
            2
        } else {
            1
        };
        for _ in 0..bottle_count {
            let cap_level = if rng.uniform() < 0.5 {
                rng.range(40.0, 90.0)
            } else {
                rng.range(150.0, 230.0)
            };
            if rng.uniform() < 0.5 {
                let body = rng.range(45.0, 80.0);
                if let Some(c) = place(&mut rng, body, &mut discs) {
                    bottles.push(Bottle::Standing {
                        centre_px: c,
                        body_radius_px: body,
                        cap_radius_px: body * rng.range(0.28, 0.38),
                        cap_level,
                    });
                }
            } else {
                let width = rng.range(50.0, 80.0);
                let length = width * rng.range(2.5, 3.5);
                if let Some(c) = place(&mut rng, length / 2.0, &mut discs) {
                    bottles.push(Bottle::Lying {
                        centre_px: c,
                        length_px: length,
                        width_px: width,
                        angle_rad: rng.range(0.0, PI),
                        cap_level,
                    });
                }
            }
        }
        let stain_count = if difficulty == Difficulty::Heavy {
            4
        } else {
            2
        };
        for _ in 0..stain_count {
            let harmonics = (0..3)
                .map(|_| (rng.range(0.0, 0.15), rng.range(0.0, TAU)))
                .collect();
            stains.push(Stain {
                centre_px: [rng.range(0.0, w), rng.range(0.0, h)],
                radius_px: rng.range(6.0, 25.0),
                harmonics,
                transmission: rng.range(0.55, 0.8),
                soft_px: 0.0,
            });
        }
    }
    Scene {
        width_px,
        height_px,
        belt_level: rng.range(35.0, 55.0),
        tubes,
        bottles,
        stains,
        rim_stains: Vec::new(),
        illumination,
        noise,
        noise_seed: rng.next_u64(),
    }
}
