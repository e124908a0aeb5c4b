//! Sub-pixel edge location along rays from a coarse centre.
//!
//! Integer contour pixels sit up to a pixel off the true edge, which adds 1-2 px of false
//! out-of-roundness. Here each ray from the coarse centre is sampled with bilinear interpolation
//! across the coarse edge; the bore level (inside) and rim level (outside) are measured on the
//! same ray, and the edge is where the profile crosses their half level, interpolated linearly
//! between samples. For an anti-aliased (area-sampled) step edge the half-level crossing is the
//! edge itself; measuring the two levels per ray makes it immune to illumination gradients.

use image::GrayImage;

/// How rays sample the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayParams {
    /// Half length of the searched stretch around the coarse radius.
    pub search_half_px: f64,
    /// Sample spacing of the search for the half-level crossing.
    pub search_step_px: f64,
    /// Sample spacing of the area integral.
    pub step_px: f64,
    /// Distance from the coarse edge to the near end of the level windows.
    pub level_near_px: f64,
    /// Distance from the coarse edge to the far end of the level windows.
    pub level_far_px: f64,
    /// Smallest rim-minus-bore difference, grey levels, for a ray to count.
    pub min_contrast: f64,
    /// Half width of the window the edge's area estimate integrates over.
    pub integral_half_px: f64,
}

impl Default for RayParams {
    fn default() -> Self {
        Self {
            search_half_px: 3.5,
            search_step_px: 0.5,
            step_px: 0.5,
            level_near_px: 3.0,
            level_far_px: 6.0,
            min_contrast: 20.0,
            integral_half_px: 2.0,
        }
    }
}

/// One refined edge point and the levels either side of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgePoint {
    /// Edge position `[x, y]`, pixels.
    pub point_px: [f64; 2],
    /// Direction of the ray.
    pub angle_rad: f64,
    /// Distance from the ray's origin to the edge.
    pub radius_px: f64,
    /// Mean level just inside (bore side).
    pub inner_level: f64,
    /// Mean level just outside (rim side).
    pub outer_level: f64,
}

/// Bilinear sample of `image` at `(x, y)` (pixel centres at integers), clamped to the image.
#[inline]
pub fn sample_bilinear(image: &GrayImage, x: f64, y: f64) -> f64 {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let x = x.clamp(0.0, (w - 1) as f64);
    let y = y.clamp(0.0, (h - 1) as f64);
    // Truncation is floor here (both are clamped to >= 0) and, unlike `floor`, needs no libm call.
    let (x0, y0) = (x as usize, y as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let raw = image.as_raw();
    let p = |xx: usize, yy: usize| f64::from(raw[yy * w + xx]);
    let top = p(x0, y0) + fx * (p(x1, y0) - p(x0, y0));
    let bottom = p(x0, y1) + fx * (p(x1, y1) - p(x0, y1));
    top + fy * (bottom - top)
}

/// Mean of samples along a ray between radii `from` and `to` (inclusive, 0.5 px apart).
pub fn mean_along(image: &GrayImage, centre: [f64; 2], dir: [f64; 2], from: f64, to: f64) -> f64 {
    let count = ((to - from) / 0.5).round().max(0.0) as usize + 1;
    let sum: f64 = (0..count)
        .map(|i| {
            let t = from + 0.5 * i as f64;
            sample_bilinear(image, centre[0] + t * dir[0], centre[1] + t * dir[1])
        })
        .sum();
    sum / count as f64
}

/// Mean levels inside (bore side) and outside (rim side) of the coarse edge on the ray from
/// `centre` with unit direction `dir`.
pub fn ray_levels(
    image: &GrayImage,
    centre: [f64; 2],
    dir: [f64; 2],
    coarse_radius_px: f64,
    params: &RayParams,
) -> (f64, f64) {
    let rho = coarse_radius_px;
    // Keep the inner window inside the bore even for small bores.
    let inner_far = (rho - params.level_far_px).max(0.4 * rho);
    let inner_near = (rho - params.level_near_px).max(inner_far);
    (
        mean_along(image, centre, dir, inner_far, inner_near),
        mean_along(
            image,
            centre,
            dir,
            rho + params.level_near_px,
            rho + params.level_far_px,
        ),
    )
}

/// Locates the dark-to-bright edge on the ray from `centre` at `angle_rad` (unit direction
/// `dir`) near `coarse_radius_px`, given the levels either side. `None` when the contrast is too low or the
/// profile never crosses the half level.
///
/// The half-level crossing picks the edge; its position is then the area (first-moment) estimate
/// `t = b - integral_a^b n(t) dt` of the normalised profile `n = (I - inner) / (outer - inner)`
/// over a window `[a, b]` around the crossing. For an area-sampled step edge and any symmetric blur
/// that integral is exact, where linear interpolation of the crossing is biased by up to 0.09 px.
pub fn locate_edge(
    image: &GrayImage,
    centre: [f64; 2],
    angle_rad: f64,
    dir: [f64; 2],
    coarse_radius_px: f64,
    levels: (f64, f64),
    params: &RayParams,
) -> Option<EdgePoint> {
    let (inner_level, outer_level) = levels;
    if image.width() == 0 || image.height() == 0 || outer_level - inner_level < params.min_contrast
    {
        return None;
    }
    let [c, s] = dir;
    let rho = coarse_radius_px;
    let at = |t: f64| sample_bilinear(image, centre[0] + t * c, centre[1] + t * s);
    let half = 0.5 * (inner_level + outer_level);
    let steps = (2.0 * params.search_half_px / params.search_step_px).round() as usize;
    let t0 = rho - params.search_half_px;
    let mut crossing: Option<f64> = None;
    let mut prev = at(t0);
    for i in 0..steps {
        let next = at(t0 + params.search_step_px * (i + 1) as f64);
        if prev < half && next >= half {
            let t = t0 + params.search_step_px * (i as f64 + (half - prev) / (next - prev));
            if crossing.is_none_or(|b| (t - rho).abs() < (b - rho).abs()) {
                crossing = Some(t);
            }
        }
        prev = next;
    }
    let t_c = crossing?;
    let a = t_c - params.integral_half_px;
    let n = (2.0 * params.integral_half_px / params.step_px).round() as usize;
    let scale = 1.0 / (outer_level - inner_level);
    let mut integral = 0.0;
    for j in 0..=n {
        let weight = if j == 0 || j == n { 0.5 } else { 1.0 };
        integral += weight * (at(a + params.step_px * j as f64) - inner_level) * scale;
    }
    integral *= params.step_px;
    let t = a + params.step_px * n as f64 - integral;
    if (t - t_c).abs() > 1.0 {
        return None;
    }
    Some(EdgePoint {
        point_px: [centre[0] + t * c, centre[1] + t * s],
        angle_rad,
        radius_px: t,
        inner_level,
        outer_level,
    })
}

/// [`ray_levels`] then [`locate_edge`] on one ray.
pub fn refine_ray(
    image: &GrayImage,
    centre: [f64; 2],
    angle_rad: f64,
    coarse_radius_px: f64,
    params: &RayParams,
) -> Option<EdgePoint> {
    let (s, c) = angle_rad.sin_cos();
    let levels = ray_levels(image, centre, [c, s], coarse_radius_px, params);
    locate_edge(
        image,
        centre,
        angle_rad,
        [c, s],
        coarse_radius_px,
        levels,
        params,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::synthetic::{BoreShape, Illumination, Noise, Scene, Tube};

    fn disc_scene(cx: f64, cy: f64, r: f64) -> GrayImage {
        Scene {
            width_px: 160,
            height_px: 160,
            belt_level: 40.0,
            tubes: vec![Tube {
                centre_px: [cx, cy],
                bore: BoreShape::Circle { radius_px: r },
                outer_radius_px: r + 20.0,
                rim_level: 200.0,
                bore_level: 20.0,
            }],
            bottles: vec![],
            stains: vec![],
            illumination: Illumination::EVEN,
            noise: Noise::NONE,
            noise_seed: 0,
        }
        .render()
    }

    #[test]
    fn rays_find_an_anti_aliased_circle_to_a_few_hundredths() {
        let (cx, cy, r) = (80.3, 79.6, 40.27);
        let image = disc_scene(cx, cy, r);
        let (mut worst, mut sum): (f64, f64) = (0.0, 0.0);
        for i in 0..360 {
            let angle = f64::from(i).to_radians();
            // Start off-centre, with a coarse radius a pixel off.
            let centre = [cx + 0.7, cy - 0.4];
            let Some(edge) = refine_ray(&image, centre, angle, r + 1.0, &RayParams::default())
            else {
                panic!("ray {i} found no edge");
            };
            let d = (edge.point_px[0] - cx).hypot(edge.point_px[1] - cy);
            worst = worst.max((d - r).abs());
            sum += d - r;
        }
        // Bilinear sampling of a pixel grid leaves a small error that varies quickly along the
        // edge (the roundness filter removes most of it); the mean error is the radius bias.
        assert!(worst < 0.08, "worst radial error {worst}");
        assert!(
            (sum / 360.0).abs() < 0.02,
            "mean radial error {}",
            sum / 360.0
        );
    }

    #[test]
    fn a_flat_ray_has_no_edge() {
        let image = GrayImage::from_pixel(50, 50, image::Luma([100]));
        assert!(refine_ray(&image, [25.0, 25.0], 0.0, 10.0, &RayParams::default()).is_none());
    }
}
