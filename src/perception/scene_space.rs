//! Seeded scenes drawn over the whole space `twincell measure` is asked to cover, not the part
//! catalogue: walls of 1.15 to 3 times the bore diameter, bore radii from 12 px to a third of the
//! image height, one to six tubes touching each other or cut by the image border, dark and
//! mid-grey belts, no noise to heavy noise, oil stains (sharp and soft, on rims, across bore
//! edges and on the belt), specks of dirt, and bottles beside the tubes. Each bore comes with its
//! truth and whether it is whole in the image.

use crate::perception::synthetic::{
    BoreShape, Bottle, Illumination, Noise, Scene, Stain, TruthCircle, Tube,
};
use crate::rng::SimRng;
use std::f64::consts::{PI, TAU};

/// Smallest ratio of the rim's outer diameter to the bore's.
pub const MIN_WALL_RATIO: f64 = 1.15;
/// Largest ratio of the rim's outer diameter to the bore's.
pub const MAX_WALL_RATIO: f64 = 3.0;
/// Thinnest wall drawn, pixels: a thinner rim has no level of its own between the bore's and
/// the belt's edges once sampled, which the edge model needs (see [`crate::perception::subpixel`]).
pub const MIN_WALL_PX: f64 = 3.0;
/// Smallest bore radius drawn, pixels.
pub const MIN_BORE_RADIUS_PX: f64 = 12.0;
/// A whole bore keeps at least this many pixels between its edge and the image border; a cut
/// one reaches at least [`CUT_DEPTH_PX`] past it. Nothing is drawn in between, where "whole" is
/// a matter of definition.
pub const WHOLE_MARGIN_PX: f64 = 8.0;
/// How far past the border a cut bore reaches at least, pixels.
pub const CUT_DEPTH_PX: f64 = 3.0;

/// The truth of one bore of a drawn scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpaceBore {
    /// Centre, mean radius and roundness.
    pub truth: TruthCircle,
    /// Ratio of the rim's outer diameter to the bore's mean diameter.
    pub wall_ratio: f64,
    /// Whether the bore lies wholly inside the image (else the border cuts it).
    pub whole: bool,
}

/// A drawn scene and the truth of its bores, in the order of `scene.tubes`.
#[derive(Debug, Clone, PartialEq)]
pub struct SpaceScene {
    /// The scene.
    pub scene: Scene,
    /// One entry per tube.
    pub bores: Vec<SpaceBore>,
}

/// A disc already placed: centre and radius.
type Disc = ([f64; 2], f64);

/// Draws a scene of `width_px` x `height_px` from `seed`.
pub fn space_scene(seed: u64, width_px: u32, height_px: u32) -> SpaceScene {
    let mut rng = SimRng::new(seed);
    let layout = draw_layout(&mut rng, width_px, height_px);
    let belt_level = draw_belt_level(&mut rng);
    let (sigma, salt_pepper) = match rng.below(4) {
        0 => (0.0, 0.0),
        1 => (rng.range(0.5, 3.0), 0.0),
        2 => (rng.range(3.0, 7.0), rng.range(0.0, 0.01)),
        _ => (rng.range(7.0, 12.0), rng.range(0.01, 0.04)),
    };
    let scene = Scene {
        width_px,
        height_px,
        belt_level,
        tubes: layout.tubes,
        bottles: layout.bottles,
        stains: layout.stains,
        rim_stains: Vec::new(),
        illumination: Illumination {
            gradient_x: rng.range(-0.4, 0.4),
            gradient_y: rng.range(-0.4, 0.4),
            vignetting: rng.range(0.0, 0.3),
        },
        noise: Noise { sigma, salt_pepper },
        noise_seed: rng.next_u64(),
    };
    SpaceScene {
        scene,
        bores: layout.bores,
    }
}

/// The tubes of a drawn scene with their truth, and the bottles and stains beside them.
pub(crate) struct Layout {
    pub(crate) tubes: Vec<Tube>,
    pub(crate) bores: Vec<SpaceBore>,
    pub(crate) bottles: Vec<Bottle>,
    pub(crate) stains: Vec<Stain>,
}

/// A dark (25-60) or mid-grey (80-115) belt, in even odds.
pub(crate) fn draw_belt_level(rng: &mut SimRng) -> f64 {
    if rng.uniform() < 0.5 {
        rng.range(25.0, 60.0)
    } else {
        rng.range(80.0, 115.0)
    }
}

/// One to six tubes over the whole space, bottles and stains, on a frame of `width_px` x
/// `height_px`.
pub(crate) fn draw_layout(rng: &mut SimRng, width_px: u32, height_px: u32) -> Layout {
    let (w, h) = (f64::from(width_px), f64::from(height_px));
    let max_bore = (h / 3.0).max(MIN_BORE_RADIUS_PX + 1.0);
    let mut discs: Vec<Disc> = Vec::new();
    let mut tubes: Vec<Tube> = Vec::new();
    let mut bores = Vec::new();
    let tube_count = 1 + rng.below(6) as usize;
    for _ in 0..tube_count {
        // Log-uniform: as many small bores as large ones.
        let radius = (rng.range(MIN_BORE_RADIUS_PX.ln(), max_bore.ln())).exp();
        // Walls of at least MIN_WALL_PX: only bores under 20 px lose part of the thinnest walls.
        let ratio = rng.range(
            MIN_WALL_RATIO.max(1.0 + MIN_WALL_PX / radius),
            MAX_WALL_RATIO,
        );
        let shape = draw_shape(rng, radius);
        let outer = ratio * radius;
        let cut = rng.uniform() < 0.15;
        let Some(centre) = place_tube(rng, &shape, outer, cut, &discs, [w, h]) else {
            continue;
        };
        discs.push((centre, outer));
        let tube = Tube {
            centre_px: centre,
            bore: shape,
            outer_radius_px: outer,
            rim_level: rng.range(170.0, 230.0),
            bore_level: rng.range(5.0, 35.0),
        };
        bores.push(SpaceBore {
            truth: TruthCircle {
                cx: centre[0],
                cy: centre[1],
                r: shape.mean_radius_px(),
                roundness: shape.roundness_px(),
            },
            wall_ratio: outer / shape.mean_radius_px(),
            whole: !cut,
        });
        tubes.push(tube);
    }
    let bottles = draw_bottles(rng, &mut discs, [w, h]);
    let stains = draw_stains(rng, &tubes, [w, h]);
    Layout {
        tubes,
        bores,
        bottles,
        stains,
    }
}

/// A circle, an ellipse or a 2-/3-lobed bore of mean radius about `radius`, out of round by up
/// to 6 % of the radius (3 px at most).
fn draw_shape(rng: &mut SimRng, radius: f64) -> BoreShape {
    let out_of_round = rng.range(0.0, (0.06 * radius).min(3.0));
    match rng.below(3) {
        0 => BoreShape::Circle { radius_px: radius },
        1 => BoreShape::Ellipse {
            a_px: radius + out_of_round / 2.0,
            b_px: radius - out_of_round / 2.0,
            angle_rad: rng.range(0.0, PI),
        },
        _ => BoreShape::Lobed {
            mean_radius_px: radius,
            amplitude_px: out_of_round / 2.0,
            lobes: 2 + rng.below(2) as u32,
            phase_rad: rng.range(0.0, TAU),
        },
    }
}

/// A centre for a tube of outer radius `outer` whose bore is whole (at least
/// [`WHOLE_MARGIN_PX`] inside the image) or cut (reaching at least [`CUT_DEPTH_PX`] past a
/// border, its centre inside the image), clear of the discs placed so far; touching one of them
/// in two draws of five. `None` when 200 tries find no room.
fn place_tube(
    rng: &mut SimRng,
    shape: &BoreShape,
    outer: f64,
    cut: bool,
    discs: &[Disc],
    [w, h]: [f64; 2],
) -> Option<[f64; 2]> {
    let r = shape.max_radius_px();
    let r_min = (0..360)
        .map(|i| shape.radius_at(TAU * f64::from(i) / 360.0))
        .fold(f64::INFINITY, f64::min);
    for _ in 0..200 {
        let c = if !discs.is_empty() && rng.uniform() < 0.4 {
            let (other, other_r) = discs[rng.below(discs.len() as u64) as usize];
            let angle = rng.range(0.0, TAU);
            let d = other_r + outer;
            [other[0] + d * angle.cos(), other[1] + d * angle.sin()]
        } else if cut {
            // Centre a fraction of the radius from a side (or outside it): the bore crosses it.
            let depth = rng.range(-0.5, 0.7) * r_min;
            match rng.below(4) {
                0 => [depth, rng.range(0.0, h)],
                1 => [w - 1.0 - depth, rng.range(0.0, h)],
                2 => [rng.range(0.0, w), depth],
                _ => [rng.range(0.0, w), h - 1.0 - depth],
            }
        } else {
            [rng.range(0.0, w), rng.range(0.0, h)]
        };
        // Distance of the bore's farthest reach past the nearest border (negative inside).
        let reach = [c[0], w - 1.0 - c[0], c[1], h - 1.0 - c[1]]
            .into_iter()
            .map(|d| r - d)
            .fold(f64::NEG_INFINITY, f64::max);
        let fits = if cut {
            // Beyond the smallest radius too, so every outline crosses the border.
            let reach_min = [c[0], w - 1.0 - c[0], c[1], h - 1.0 - c[1]]
                .into_iter()
                .map(|d| r_min - d)
                .fold(f64::NEG_INFINITY, f64::max);
            reach_min >= CUT_DEPTH_PX && (0.0..w).contains(&c[0]) && (0.0..h).contains(&c[1])
        } else {
            reach <= -WHOLE_MARGIN_PX
        };
        let clear = discs
            .iter()
            .all(|(d, dr)| (c[0] - d[0]).hypot(c[1] - d[1]) >= dr + outer - 1e-9);
        if fits && clear {
            return Some(c);
        }
    }
    None
}

/// None to two bottles, standing or lying, clear of the tubes (2 px apart at least).
fn draw_bottles(rng: &mut SimRng, discs: &mut Vec<Disc>, [w, h]: [f64; 2]) -> Vec<Bottle> {
    let mut bottles = Vec::new();
    for _ in 0..rng.below(3) {
        let cap_level = if rng.uniform() < 0.5 {
            rng.range(40.0, 90.0)
        } else {
            rng.range(150.0, 230.0)
        };
        let standing = rng.uniform() < 0.5;
        let (size, width) = if standing {
            let body = rng.range(30.0, 80.0);
            (body, body)
        } else {
            let width = rng.range(40.0, 80.0);
            (width * rng.range(2.5, 3.5) / 2.0, width)
        };
        for _ in 0..100 {
            let c = [rng.range(0.0, w), rng.range(0.0, h)];
            if discs
                .iter()
                .all(|(d, dr)| (c[0] - d[0]).hypot(c[1] - d[1]) > dr + size + 2.0)
            {
                discs.push((c, size));
                bottles.push(if standing {
                    Bottle::Standing {
                        centre_px: c,
                        body_radius_px: size,
                        cap_radius_px: size * rng.range(0.28, 0.38),
                        cap_level,
                    }
                } else {
                    Bottle::Lying {
                        centre_px: c,
                        length_px: 2.0 * size,
                        width_px: width,
                        angle_rad: rng.range(0.0, PI),
                        cap_level,
                    }
                });
                break;
            }
        }
    }
    bottles
}

/// Oil stains on rims (sharp or soft rimmed, never across the whole wall), across bore edges
/// (soft rimmed, up to a third of the bore radius) and on the belt, and small dark specks of dirt.
fn draw_stains(rng: &mut SimRng, tubes: &[Tube], [w, h]: [f64; 2]) -> Vec<Stain> {
    let mut stains = Vec::new();
    for _ in 0..rng.below(5) {
        let shape = |rng: &mut SimRng| {
            (0..3)
                .map(|_| (rng.range(0.0, 0.15), rng.range(0.0, TAU)))
                .collect::<Vec<_>>()
        };
        let transmission = rng.range(0.55, 0.8);
        let kind = if tubes.is_empty() { 2 } else { rng.below(3) };
        let stain = match kind {
            0 => {
                // On a rim, sharp or soft, anywhere across its width but never across all of it
                // (a stain over the whole wall leaves no rim around the bore to find it by).
                let tube = &tubes[rng.below(tubes.len() as u64) as usize];
                let wall = tube.outer_radius_px - tube.bore.max_radius_px();
                let radius = rng.range(2.0, 20.0).min(0.4 * wall).max(1.0);
                // At least 3 px clear of the bore edge: a sharp stain touching it is the next
                // kind's business.
                let r = tube.bore.max_radius_px()
                    + rng.range(radius + 3.0, (wall - radius).max(radius + 3.0));
                let a = rng.range(0.0, TAU);
                let soft = rng.uniform() < 0.5;
                Stain {
                    centre_px: [
                        tube.centre_px[0] + r * a.cos(),
                        tube.centre_px[1] + r * a.sin(),
                    ],
                    radius_px: radius,
                    harmonics: shape(rng),
                    transmission,
                    soft_px: if soft { 0.6 * radius } else { 0.0 },
                }
            }
            1 => {
                // Oil across the bore edge: thinning out towards its rim (soft), as on the
                // rendered end faces, and at most a third of the bore's radius.
                let tube = &tubes[rng.below(tubes.len() as u64) as usize];
                let r_bore = tube.bore.mean_radius_px();
                let wall = tube.outer_radius_px - tube.bore.max_radius_px();
                let radius = rng
                    .range(3.0, 12.0)
                    .min(r_bore / 3.0)
                    .min(0.8 * wall)
                    .max(1.5);
                let r = r_bore + rng.range(0.0, radius.min(6.0));
                let a = rng.range(0.0, TAU);
                Stain {
                    centre_px: [
                        tube.centre_px[0] + r * a.cos(),
                        tube.centre_px[1] + r * a.sin(),
                    ],
                    radius_px: radius,
                    harmonics: Vec::new(),
                    transmission,
                    soft_px: 0.6 * radius,
                }
            }
            _ => {
                // On the belt, sharp or soft, wherever it falls.
                let radius = rng.range(4.0, 20.0);
                let soft = rng.uniform() < 0.5;
                Stain {
                    centre_px: [rng.range(0.0, w), rng.range(0.0, h)],
                    radius_px: radius,
                    harmonics: shape(rng),
                    transmission,
                    soft_px: if soft { 0.6 * radius } else { 0.0 },
                }
            }
        };
        stains.push(stain);
    }
    for _ in 0..rng.below(6) {
        stains.push(Stain {
            centre_px: [rng.range(0.0, w), rng.range(0.0, h)],
            radius_px: rng.range(0.7, 2.0),
            harmonics: Vec::new(),
            transmission: rng.range(0.3, 0.7),
            soft_px: 0.0,
        });
    }
    stains
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drawn_scenes_cover_the_space_and_keep_their_promises() {
        let (mut ratios, mut radii, mut cut, mut whole, mut touching) =
            (Vec::new(), Vec::new(), 0, 0, 0);
        for seed in 0..300 {
            let drawn = space_scene(seed, 640, 480);
            assert_eq!(drawn.bores.len(), drawn.scene.tubes.len());
            for (bore, tube) in drawn.bores.iter().zip(&drawn.scene.tubes) {
                ratios.push(bore.wall_ratio);
                radii.push(bore.truth.r);
                let r_max = tube.bore.max_radius_px();
                let [x, y] = tube.centre_px;
                let inside = [x, 639.0 - x, y, 479.0 - y]
                    .into_iter()
                    .fold(f64::INFINITY, f64::min);
                if bore.whole {
                    whole += 1;
                    assert!(inside - r_max >= WHOLE_MARGIN_PX, "seed {seed}");
                } else {
                    cut += 1;
                    assert!(inside - r_max <= -CUT_DEPTH_PX, "seed {seed}");
                }
                touching += drawn
                    .scene
                    .tubes
                    .iter()
                    .filter(|o| {
                        let d = (o.centre_px[0] - x).hypot(o.centre_px[1] - y);
                        d > 0.0 && (d - o.outer_radius_px - tube.outer_radius_px).abs() < 1e-6
                    })
                    .count();
            }
        }
        let lowest = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
        let highest = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
        assert!(lowest(&ratios) < 1.2 && highest(&ratios) > 2.9);
        assert!(lowest(&radii) < 14.0 && highest(&radii) > 140.0);
        assert!(
            cut > 20 && whole > 500 && touching > 50,
            "{cut} {whole} {touching}"
        );
    }
}
