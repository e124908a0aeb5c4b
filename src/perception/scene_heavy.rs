//! Scenes of the whole space ([`crate::perception::scene_space`]: the same tubes, bottles, stains
//! and belts) under heavy noise, one kind at a time or all at once: Gaussian noise up to σ 16
//! grey levels, salt-and-pepper noise up to 3 %, illumination gradients up to 0.5 across the
//! frame, and oil over up to a third of a rim, across the wall or part of it.

use crate::perception::scene_space::{SpaceScene, draw_belt_level, draw_layout};
use crate::perception::synthetic::{Illumination, Noise, RimStain, Scene, Tube};
use crate::rng::SimRng;
use std::f64::consts::TAU;

/// Which heavy noise a scene carries (the rest stays moderate).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseBand {
    /// Gaussian sensor noise, σ 8 to 16 grey levels.
    Gaussian,
    /// Salt-and-pepper noise on 1 to 3 % of the pixels.
    SaltPepper,
    /// Linear light gradients of 0.25 to 0.5 across the width and across the height.
    Gradient,
    /// Oil on a sixth to a third of most rims.
    RimStains,
    /// All four at once.
    Combined,
}

impl NoiseBand {
    /// Every band, in the order of tables.
    pub const ALL: [Self; 5] = [
        Self::Gaussian,
        Self::SaltPepper,
        Self::Gradient,
        Self::RimStains,
        Self::Combined,
    ];

    /// Short name for tables.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Gaussian => "gaussian 8-16",
            Self::SaltPepper => "salt+pepper 1-3%",
            Self::Gradient => "gradient 0.25-0.5",
            Self::RimStains => "rim stains <=1/3",
            Self::Combined => "all four",
        }
    }

    fn gaussian(&self) -> bool {
        matches!(self, Self::Gaussian | Self::Combined)
    }

    fn salt_pepper(&self) -> bool {
        matches!(self, Self::SaltPepper | Self::Combined)
    }

    fn gradient(&self) -> bool {
        matches!(self, Self::Gradient | Self::Combined)
    }

    fn rim_stains(&self) -> bool {
        matches!(self, Self::RimStains | Self::Combined)
    }
}

/// Largest share of a rim's circumference one rim stain covers.
pub const MAX_RIM_STAIN_SHARE: f64 = 1.0 / 3.0;

/// Draws a scene of `width_px` x `height_px` from `seed` with `band`'s heavy noise; outside the
/// band, Gaussian noise of σ 0.5-4, gradients up to 0.3 and no rim stains.
pub fn heavy_scene(seed: u64, width_px: u32, height_px: u32, band: NoiseBand) -> SpaceScene {
    let mut rng = SimRng::new(seed);
    let layout = draw_layout(&mut rng, width_px, height_px);
    let belt_level = draw_belt_level(&mut rng);
    let sigma = if band.gaussian() {
        rng.range(8.0, 16.0)
    } else {
        rng.range(0.5, 4.0)
    };
    let salt_pepper = if band.salt_pepper() {
        rng.range(0.01, 0.03)
    } else {
        0.0
    };
    let gradient = |rng: &mut SimRng| {
        let sign = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
        if band.gradient() {
            sign * rng.range(0.25, 0.5)
        } else {
            sign * rng.range(0.0, 0.3)
        }
    };
    let illumination = Illumination {
        gradient_x: gradient(&mut rng),
        gradient_y: gradient(&mut rng),
        vignetting: rng.range(0.0, 0.3),
    };
    let rim_stains = if band.rim_stains() {
        draw_rim_stains(&mut rng, &layout.tubes)
    } else {
        Vec::new()
    };
    let scene = Scene {
        width_px,
        height_px,
        belt_level,
        tubes: layout.tubes,
        bottles: layout.bottles,
        stains: layout.stains,
        rim_stains,
        illumination,
        noise: Noise { sigma, salt_pepper },
        noise_seed: rng.next_u64(),
    };
    SpaceScene {
        scene,
        bores: layout.bores,
    }
}

/// Oil on three rims in four: over a sixth to a third of the rim, across the whole wall in half
/// the draws and across part of it (from the bore edge, or clear of it) in the others; sharp or
/// soft edged.
fn draw_rim_stains(rng: &mut SimRng, tubes: &[Tube]) -> Vec<RimStain> {
    let mut stains = Vec::new();
    for (i, tube) in tubes.iter().enumerate() {
        if rng.uniform() >= 0.75 {
            continue;
        }
        let wall = tube.outer_radius_px - tube.bore.max_radius_px();
        let span_rad = TAU * rng.range(MAX_RIM_STAIN_SHARE / 2.0, MAX_RIM_STAIN_SHARE);
        let (inner_px, outer_px) = match rng.below(4) {
            // Across the whole wall.
            0 | 1 => (0.0, 2.0 * tube.outer_radius_px),
            // From the bore edge part of the way out.
            2 => (0.0, wall * rng.range(0.3, 0.8)),
            // Clear of the bore edge, out to the face's edge or short of it.
            _ => {
                let inner = wall * rng.range(0.15, 0.5);
                (inner, inner + wall * rng.range(0.25, 0.85))
            }
        };
        let soft_px = if rng.uniform() < 0.5 {
            0.0
        } else {
            rng.range(1.0, 4.0)
        };
        stains.push(RimStain {
            tube: i,
            middle_rad: rng.range(0.0, TAU),
            span_rad,
            inner_px,
            outer_px,
            transmission: rng.range(0.55, 0.8),
            soft_px,
        });
    }
    stains
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_band_draws_its_noise_over_its_whole_range() {
        for band in NoiseBand::ALL {
            let (mut sigmas, mut peppers, mut gradients, mut spans) =
                (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            for seed in 0..200 {
                let drawn = heavy_scene(seed, 640, 480, band);
                let s = &drawn.scene;
                sigmas.push(s.noise.sigma);
                peppers.push(s.noise.salt_pepper);
                gradients.push(s.illumination.gradient_x.abs());
                gradients.push(s.illumination.gradient_y.abs());
                spans.extend(s.rim_stains.iter().map(|r| r.span_rad / TAU));
            }
            let highest = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
            let lowest = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
            if band.gaussian() {
                assert!(
                    lowest(&sigmas) >= 8.0 && highest(&sigmas) > 15.5,
                    "{band:?}"
                );
            } else {
                assert!(highest(&sigmas) <= 4.0, "{band:?}");
            }
            if band.salt_pepper() {
                assert!(highest(&peppers) > 0.029 && lowest(&peppers) >= 0.01);
            } else {
                assert_eq!(highest(&peppers), 0.0);
            }
            if band.gradient() {
                assert!(highest(&gradients) > 0.49 && lowest(&gradients) >= 0.25);
            } else {
                assert!(highest(&gradients) <= 0.3);
            }
            if band.rim_stains() {
                assert!(
                    spans.len() > 200 && highest(&spans) > 0.33,
                    "{}",
                    spans.len()
                );
                assert!(highest(&spans) <= MAX_RIM_STAIN_SHARE);
            } else {
                assert!(spans.is_empty());
            }
        }
    }
}
