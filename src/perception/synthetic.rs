//! Seeded synthetic end-face images with known truth, for tests, benchmarks and `--compare`.
//!
//! Every edge is anti-aliased by 8x8 supersampling of the pixel's area (pixel `(i, j)` covers
//! `[i - 0.5, i + 0.5] x [j - 0.5, j + 0.5]`, so integer coordinates sit at pixel centres, as in the
//! command-line contract). Reflectance is multiplied by a smooth illumination field (linear gradient
//! and radial vignetting), then Gaussian sensor noise and salt-and-pepper impulses are added.

use crate::rng::SimRng;

pub use crate::perception::rim_stain::RimStain;
pub use crate::perception::scene_draw::{Difficulty, random_scene};
use image::{GrayImage, Luma};
use std::f64::consts::TAU;

/// The true outline of a bore, as a radius about its centre for each direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BoreShape {
    /// A perfect circle.
    Circle {
        /// Radius.
        radius_px: f64,
    },
    /// An ellipse with semi-axes `a_px >= b_px`, major axis at `angle_rad` from +x.
    Ellipse {
        /// Semi-major axis.
        a_px: f64,
        /// Semi-minor axis.
        b_px: f64,
        /// Direction of the major axis.
        angle_rad: f64,
    },
    /// A lobed bore: `r(theta) = mean + amplitude * cos(lobes * theta + phase)`.
    Lobed {
        /// Mean radius.
        mean_radius_px: f64,
        /// Lobe amplitude (half the roundness).
        amplitude_px: f64,
        /// Number of lobes (2 or 3 in practice).
        lobes: u32,
        /// Phase of the lobes.
        phase_rad: f64,
    },
}

impl BoreShape {
    /// Radius of the outline in direction `theta_rad` (from +x towards +y, image axes).
    pub fn radius_at(&self, theta_rad: f64) -> f64 {
        match *self {
            Self::Circle { radius_px } => radius_px,
            Self::Ellipse {
                a_px,
                b_px,
                angle_rad,
            } => {
                let phi = theta_rad - angle_rad;
                a_px * b_px / ((b_px * phi.cos()).powi(2) + (a_px * phi.sin()).powi(2)).sqrt()
            }
            Self::Lobed {
                mean_radius_px,
                amplitude_px,
                lobes,
                phase_rad,
            } => mean_radius_px + amplitude_px * (f64::from(lobes) * theta_rad + phase_rad).cos(),
        }
    }

    /// True roundness `Rmax - Rmin` about the true centre.
    pub fn roundness_px(&self) -> f64 {
        match *self {
            Self::Circle { .. } => 0.0,
            Self::Ellipse { a_px, b_px, .. } => a_px - b_px,
            Self::Lobed { amplitude_px, .. } => 2.0 * amplitude_px.abs(),
        }
    }

    /// Radius of the least-squares circle of the outline sampled uniformly in angle about the
    /// true centre: the mean of `radius_at` (the centre stays put by symmetry for these shapes).
    pub fn mean_radius_px(&self) -> f64 {
        const SAMPLES: usize = 4096;
        (0..SAMPLES)
            .map(|i| self.radius_at(TAU * i as f64 / SAMPLES as f64))
            .sum::<f64>()
            / SAMPLES as f64
    }

    /// Largest radius of the outline.
    pub fn max_radius_px(&self) -> f64 {
        match *self {
            Self::Circle { radius_px } => radius_px,
            Self::Ellipse { a_px, b_px, .. } => a_px.max(b_px),
            Self::Lobed {
                mean_radius_px,
                amplitude_px,
                ..
            } => mean_radius_px + amplitude_px.abs(),
        }
    }
}

/// A tube standing upright, seen end-on: a bright annulus around a dark bore.
#[derive(Debug, Clone, PartialEq)]
pub struct Tube {
    /// Bore centre, pixels.
    pub centre_px: [f64; 2],
    /// Bore outline.
    pub bore: BoreShape,
    /// Outer radius of the end face (the rim's outer edge).
    pub outer_radius_px: f64,
    /// Reflectance of the machined rim, grey levels under unit illumination.
    pub rim_level: f64,
    /// Reflectance seen down the bore.
    pub bore_level: f64,
}

/// A plastic-bottle distractor.
#[derive(Debug, Clone, PartialEq)]
pub enum Bottle {
    /// Standing: a translucent body disc with a small cap on top.
    Standing {
        /// Centre, pixels.
        centre_px: [f64; 2],
        /// Body radius.
        body_radius_px: f64,
        /// Cap radius.
        cap_radius_px: f64,
        /// Cap reflectance (dark coloured caps make a dark disc inside a bright-ish ring).
        cap_level: f64,
    },
    /// Lying on its side: a capsule with a cylindrical highlight and a cap at one end.
    Lying {
        /// Centre, pixels.
        centre_px: [f64; 2],
        /// End-to-end length.
        length_px: f64,
        /// Diameter.
        width_px: f64,
        /// Direction of the long axis.
        angle_rad: f64,
        /// Cap reflectance.
        cap_level: f64,
    },
}

/// An oil stain: an irregular blob that darkens whatever lies under it.
#[derive(Debug, Clone, PartialEq)]
pub struct Stain {
    /// Centre, pixels.
    pub centre_px: [f64; 2],
    /// Mean radius.
    pub radius_px: f64,
    /// Harmonics of the outline: (relative amplitude, phase) for orders 2, 3, ...
    pub harmonics: Vec<(f64, f64)>,
    /// Factor applied to the reflectance under the stain (0.55..0.8 typical).
    pub transmission: f64,
    /// Width of the stain's soft rim, pixels: the darkening fades out smoothly (smoothstep)
    /// over this distance inside the outline, as oil thins out at its edge. 0 for a sharp edge.
    pub soft_px: f64,
}

impl Stain {
    fn radius_at(&self, theta_rad: f64) -> f64 {
        let wobble: f64 = self
            .harmonics
            .iter()
            .enumerate()
            .map(|(i, (amp, phase))| amp * ((i as f64 + 2.0) * theta_rad + phase).cos())
            .sum();
        self.radius_px * (1.0 + wobble)
    }
}

/// Illumination field multiplying the reflectance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Illumination {
    /// Relative change across the image width (0.3 = +-15% left to right).
    pub gradient_x: f64,
    /// Relative change across the image height.
    pub gradient_y: f64,
    /// Relative loss at the image corners (radial, quadratic).
    pub vignetting: f64,
}

impl Illumination {
    /// Even light: no gradient, no vignetting.
    pub const EVEN: Self = Self {
        gradient_x: 0.0,
        gradient_y: 0.0,
        vignetting: 0.0,
    };
}

/// Sensor noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// Standard deviation of additive Gaussian noise, grey levels.
    pub sigma: f64,
    /// Share of pixels replaced by 0 or 255.
    pub salt_pepper: f64,
}

impl Noise {
    /// A noiseless sensor.
    pub const NONE: Self = Self {
        sigma: 0.0,
        salt_pepper: 0.0,
    };
}

/// The truth of one bore, in the contract's pixel convention.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TruthCircle {
    /// Centre x.
    pub cx: f64,
    /// Centre y.
    pub cy: f64,
    /// Mean radius.
    pub r: f64,
    /// `Rmax - Rmin` about the true centre.
    pub roundness: f64,
}

/// A synthetic scene: a belt with tubes, bottles and stains under some light and noise.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Image width.
    pub width_px: u32,
    /// Image height.
    pub height_px: u32,
    /// Belt reflectance.
    pub belt_level: f64,
    /// Tubes (the bores to find).
    pub tubes: Vec<Tube>,
    /// Bottles (never to be reported).
    pub bottles: Vec<Bottle>,
    /// Oil stains.
    pub stains: Vec<Stain>,
    /// Oil along arcs of the tubes' end faces.
    pub rim_stains: Vec<RimStain>,
    /// Light.
    pub illumination: Illumination,
    /// Sensor noise.
    pub noise: Noise,
    /// Seed of the noise.
    pub noise_seed: u64,
}

/// Sub-samples per pixel side for anti-aliasing.
const SUPERSAMPLE: usize = 8;
/// Radial distance from any outline within which a pixel is supersampled.
const EDGE_BAND_PX: f64 = 3.0;

impl Scene {
    /// One round tube on an even, noiseless `side` x `side` frame: its bore of radius
    /// `bore_radius_px` centred at `centre_px`, its rim out to `outer_radius_px`.
    pub fn one_tube(
        side: u32,
        centre_px: [f64; 2],
        bore_radius_px: f64,
        outer_radius_px: f64,
    ) -> Self {
        Self {
            width_px: side,
            height_px: side,
            belt_level: 40.0,
            tubes: vec![Tube {
                centre_px,
                bore: BoreShape::Circle {
                    radius_px: bore_radius_px,
                },
                outer_radius_px,
                rim_level: 200.0,
                bore_level: 20.0,
            }],
            bottles: vec![],
            stains: vec![],
            rim_stains: vec![],
            illumination: Illumination::EVEN,
            noise: Noise::NONE,
            noise_seed: 0,
        }
    }

    /// The truth of every bore in the scene.
    pub fn truth(&self) -> Vec<TruthCircle> {
        self.tubes
            .iter()
            .map(|t| TruthCircle {
                cx: t.centre_px[0],
                cy: t.centre_px[1],
                r: t.bore.mean_radius_px(),
                roundness: t.bore.roundness_px(),
            })
            .collect()
    }

    /// Renders the scene into an 8-bit grey image.
    pub fn render(&self) -> GrayImage {
        let (w, h) = (self.width_px, self.height_px);
        let mut rng = SimRng::new(self.noise_seed);
        let mut image = GrayImage::new(w, h);
        let diag = (f64::from(w).powi(2) + f64::from(h).powi(2)).sqrt() / 2.0;
        let (cx, cy) = (f64::from(w) / 2.0, f64::from(h) / 2.0);
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (f64::from(x), f64::from(y));
                let reflectance = if self.near_edge(xf, yf) {
                    let mut sum = 0.0;
                    for sy in 0..SUPERSAMPLE {
                        for sx in 0..SUPERSAMPLE {
                            let ox = (sx as f64 + 0.5) / SUPERSAMPLE as f64 - 0.5;
                            let oy = (sy as f64 + 0.5) / SUPERSAMPLE as f64 - 0.5;
                            sum += self.reflectance(xf + ox, yf + oy);
                        }
                    }
                    sum / (SUPERSAMPLE * SUPERSAMPLE) as f64
                } else {
                    self.reflectance(xf, yf)
                };
                let rho = ((xf - cx).powi(2) + (yf - cy).powi(2)).sqrt() / diag;
                let light = (1.0
                    + self.illumination.gradient_x * ((xf - cx) / f64::from(w))
                    + self.illumination.gradient_y * ((yf - cy) / f64::from(h)))
                    * (1.0 - self.illumination.vignetting * rho * rho);
                let mut value = reflectance * light + self.noise.sigma * rng.normal();
                if self.noise.salt_pepper > 0.0 && rng.uniform() < self.noise.salt_pepper {
                    value = if rng.uniform() < 0.5 { 0.0 } else { 255.0 };
                }
                image.put_pixel(x, y, Luma([value.round().clamp(0.0, 255.0) as u8]));
            }
        }
        image
    }

    /// Whether any outline passes within the supersampling band of `(x, y)`.
    fn near_edge(&self, x: f64, y: f64) -> bool {
        let near_radius = |c: [f64; 2], r: f64| {
            let rho = ((x - c[0]).powi(2) + (y - c[1]).powi(2)).sqrt();
            (rho - r).abs() < EDGE_BAND_PX
        };
        let angle = |c: [f64; 2]| (y - c[1]).atan2(x - c[0]);
        self.tubes.iter().any(|t| {
            near_radius(t.centre_px, t.outer_radius_px)
                || near_radius(t.centre_px, t.bore.radius_at(angle(t.centre_px)))
        }) || self
            .stains
            .iter()
            .any(|s| near_radius(s.centre_px, s.radius_at(angle(s.centre_px))))
            || self.rim_stains.iter().any(|s| {
                self.tubes
                    .get(s.tube)
                    .is_some_and(|t| s.sharp_boundary_near(t, x, y, EDGE_BAND_PX))
            })
            || self.bottles.iter().any(|b| match *b {
                Bottle::Standing {
                    centre_px,
                    body_radius_px,
                    cap_radius_px,
                    ..
                } => {
                    near_radius(centre_px, body_radius_px) || near_radius(centre_px, cap_radius_px)
                }
                Bottle::Lying {
                    centre_px,
                    length_px,
                    width_px,
                    angle_rad,
                    ..
                } => {
                    let d = capsule_distance(x, y, centre_px, length_px, width_px, angle_rad);
                    let cap = lying_cap_distance(x, y, centre_px, length_px, width_px, angle_rad);
                    d.abs() < EDGE_BAND_PX || cap.abs() < EDGE_BAND_PX
                }
            })
    }

    /// Reflectance at a continuous point.
    fn reflectance(&self, x: f64, y: f64) -> f64 {
        let mut value = self.belt_level;
        for bottle in &self.bottles {
            if let Some(v) = bottle_reflectance(bottle, x, y) {
                value = v;
            }
        }
        // The tube whose face (not bore) the point lies on, if any.
        let mut face = None;
        for (i, tube) in self.tubes.iter().enumerate() {
            let (dx, dy) = (x - tube.centre_px[0], y - tube.centre_px[1]);
            let rho = (dx * dx + dy * dy).sqrt();
            if rho < tube.outer_radius_px {
                (value, face) = if rho < tube.bore.radius_at(dy.atan2(dx)) {
                    (tube.bore_level, None)
                } else {
                    (tube.rim_level, Some(i))
                };
            }
        }
        if let Some(i) = face {
            for stain in self.rim_stains.iter().filter(|s| s.tube == i) {
                value *= stain.factor(&self.tubes[i], x, y);
            }
        }
        for stain in &self.stains {
            let (dx, dy) = (x - stain.centre_px[0], y - stain.centre_px[1]);
            let depth = stain.radius_at(dy.atan2(dx)) - (dx * dx + dy * dy).sqrt();
            if depth > 0.0 {
                let cover = if depth >= stain.soft_px {
                    1.0
                } else {
                    let u = depth / stain.soft_px;
                    u * u * (3.0 - 2.0 * u)
                };
                value *= 1.0 + cover * (stain.transmission - 1.0);
            }
        }
        value
    }
}

/// Signed distance from the capsule's surface (negative inside).
fn capsule_distance(x: f64, y: f64, c: [f64; 2], length: f64, width: f64, angle: f64) -> f64 {
    let (u, v) = to_axis_frame(x, y, c, angle);
    let half_core = (length - width).max(0.0) / 2.0;
    let du = (u.abs() - half_core).max(0.0);
    (du * du + v * v).sqrt() - width / 2.0
}

/// Signed distance from the lying bottle's cap boundary (a disc at the +u end).
fn lying_cap_distance(x: f64, y: f64, c: [f64; 2], length: f64, width: f64, angle: f64) -> f64 {
    let (u, v) = to_axis_frame(x, y, c, angle);
    let cap_u = length / 2.0 - width * 0.25;
    ((u - cap_u).powi(2) + v * v).sqrt() - width * 0.25
}

fn to_axis_frame(x: f64, y: f64, c: [f64; 2], angle: f64) -> (f64, f64) {
    let (dx, dy) = (x - c[0], y - c[1]);
    let (s, co) = angle.sin_cos();
    (dx * co + dy * s, -dx * s + dy * co)
}

/// Reflectance of a bottle at a point, `None` outside it.
fn bottle_reflectance(bottle: &Bottle, x: f64, y: f64) -> Option<f64> {
    match *bottle {
        Bottle::Standing {
            centre_px,
            body_radius_px,
            cap_radius_px,
            cap_level,
        } => {
            let (dx, dy) = (x - centre_px[0], y - centre_px[1]);
            let rho = (dx * dx + dy * dy).sqrt();
            if rho >= body_radius_px {
                return None;
            }
            if rho < cap_radius_px {
                return Some(cap_level);
            }
            // Translucent PET: brighter where the wall is seen at a grazing angle, a soft
            // specular highlight off-centre, a darker shoulder ring.
            let t = rho / body_radius_px;
            let highlight = 60.0
                * (-((dx + 0.45 * body_radius_px).powi(2) + (dy + 0.35 * body_radius_px).powi(2))
                    / (0.06 * body_radius_px * body_radius_px))
                    .exp();
            let shoulder = -25.0 * (-((t - 0.55) / 0.08).powi(2)).exp();
            Some(120.0 + 60.0 * t.powi(4) + highlight + shoulder)
        }
        Bottle::Lying {
            centre_px,
            length_px,
            width_px,
            angle_rad,
            cap_level,
        } => {
            if capsule_distance(x, y, centre_px, length_px, width_px, angle_rad) >= 0.0 {
                return None;
            }
            if lying_cap_distance(x, y, centre_px, length_px, width_px, angle_rad) < 0.0 {
                return Some(cap_level);
            }
            let (_, v) = to_axis_frame(x, y, centre_px, angle_rad);
            let s = (2.0 * v / width_px).clamp(-1.0, 1.0);
            // A cylinder: a bright highlight stripe along the axis, brighter limbs, a label band.
            let stripe = 80.0 * (-((s + 0.2) / 0.12).powi(2)).exp();
            Some(115.0 + 55.0 * s.powi(6) + stripe)
        }
    }
}

/// One tube on an even, noiseless 160 x 160 frame: bore radius `r` at `(cx, cy)`, rim 20 px wide.
/// A fixture for the ray and edge tests.
#[cfg(test)]
pub(crate) fn disc_scene(cx: f64, cy: f64, r: f64) -> image::GrayImage {
    Scene::one_tube(160, [cx, cy], r, r + 20.0).render()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_image() {
        let a = random_scene(7, 160, 120, Difficulty::Heavy).render();
        let b = random_scene(7, 160, 120, Difficulty::Heavy).render();
        assert_eq!(a.as_raw(), b.as_raw());
    }

    #[test]
    fn lobed_truth_is_twice_the_amplitude() {
        let shape = BoreShape::Lobed {
            mean_radius_px: 50.0,
            amplitude_px: 2.5,
            lobes: 3,
            phase_rad: 0.3,
        };
        assert!((shape.roundness_px() - 5.0).abs() < 1e-12);
        assert!((shape.mean_radius_px() - 50.0).abs() < 1e-9);
    }

    #[test]
    fn anti_aliased_edge_is_the_covered_area() {
        // A huge circle is locally a straight vertical edge at x = 100.25 near (100, 300).
        let scene = Scene {
            width_px: 200,
            height_px: 600,
            belt_level: 0.0,
            tubes: vec![Tube {
                centre_px: [-9899.75, 300.0],
                bore: BoreShape::Circle {
                    radius_px: 10_000.0,
                },
                outer_radius_px: 20_000.0,
                rim_level: 200.0,
                bore_level: 0.0,
            }],
            bottles: vec![],
            stains: vec![],
            rim_stains: vec![],
            illumination: Illumination::EVEN,
            noise: Noise::NONE,
            noise_seed: 0,
        };
        let image = scene.render();
        // Pixel 100 spans [99.5, 100.5]: bore (0) on [99.5, 100.25], rim (200) on the rest.
        assert_eq!(image.get_pixel(100, 300)[0], 50);
    }
}
