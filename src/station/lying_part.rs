//! A tube lying on the belt, found in the camera's frame alone. From above it shows a steel
//! body with a rectangle-like outline and no dark bore inside it (a standing tube shows its
//! bore). Its pixels, laid on the plane through its axis, give the outline's two extents: the
//! catalogue's tube sizes say which is the length, and so the axis. Its outline (the rings at
//! its two ends) is then slid over the belt until its box is centred on the pixels' box, as the
//! bottle fit slides a bottle's.

use image::RgbImage;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector2};

use super::silhouette::{Silhouette, box_residual_px};
use crate::camera::CameraCalibration;

/// A pixel this many times brighter than the belt's median (plus the offset below) is steel.
const STEEL_OVER_BELT: f64 = 1.8;
/// Grey levels added to the threshold, so that a near-black belt's noise stays out.
const STEEL_OFFSET: f64 = 10.0;
/// Blue over red above which a bright pixel is the bottle's tinted plastic, not steel.
const TINT_RATIO: f64 = 1.12;
/// A body with more than this share of its area enclosed dark is a standing tube's end face.
const MAX_HOLE_SHARE: f64 = 0.08;
/// Pixels a body is grown by before its enclosed holes are counted.
const HOLE_CLOSING_PX: u32 = 2;
/// A body with a bore is taken for a standing tube when a standing outline's box fits it
/// within this many times the lying one's residual.
const STANDING_PREFERRED: f64 = 4.0;
/// Fewest pixels of a body worth fitting.
const MIN_BODY_PX: usize = 60;
/// Largest relative error of the pixels' extents against the fitted tube's.
const MAX_SIZE_ERROR: f64 = 0.35;
/// Largest RMS difference of the outline's box and the pixels' box, as a share of the
/// pixels' box diagonal.
const MAX_BOX_RESIDUAL: f64 = 0.08;
/// Yaw steps either side of each extent's direction, and their size, rad.
const YAW_STEPS: i32 = 4;
const YAW_STEP_RAD: f64 = 0.035;
/// Points on each end ring of the outline.
const RING_POINTS: usize = 32;

/// A tube lying on the belt, as the camera saw it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LyingPart {
    /// The middle of its axis, in the world, m.
    pub centre_in_world: Point3<f64>,
    /// The axis' direction on the belt, from the world's x axis, in `[0, pi)`, rad.
    pub yaw_rad: f64,
    /// Length along the axis, m.
    pub length_m: f64,
    /// Outer diameter, m.
    pub diameter_m: f64,
    /// Index of the catalogue tube whose size it matches best.
    pub size_index: usize,
    /// RMS distance between the box its outline projects to and its pixels' box, pixels.
    pub residual_px: f64,
}

impl LyingPart {
    /// Its pose: the middle of the axis, local z along the axis.
    pub fn world_from_part(&self) -> Isometry3<f64> {
        lying_pose(self.centre_in_world, self.yaw_rad)
    }
}

/// The size of a tube the cell handles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TubeSize {
    /// Outer diameter, m.
    pub diameter_m: f64,
    /// Length (a standing tube's height), m.
    pub length_m: f64,
}

/// Finds lying tubes of a catalogue in one calibrated camera's frames.
#[derive(Debug, Clone)]
pub struct LyingPartFinder {
    calibration: CameraCalibration,
    belt_top_z_m: f64,
    /// The belt's top as `[[x_min, x_max], [y_min, y_max]]`, world, m: steel seen beyond it
    /// (the belt's frame, the floor) is not a part on it.
    belt_xy_m: [[f64; 2]; 2],
    sizes: Vec<TubeSize>,
}

impl LyingPartFinder {
    /// A finder for tubes of `sizes` on a belt whose top is at `belt_top_z_m` and spans
    /// `belt_xy_m` (`[[x_min, x_max], [y_min, y_max]]`), seen through `calibration`.
    pub fn new(
        calibration: CameraCalibration,
        belt_top_z_m: f64,
        belt_xy_m: [[f64; 2]; 2],
        sizes: Vec<TubeSize>,
    ) -> Self {
        Self {
            calibration,
            belt_top_z_m,
            belt_xy_m,
            sizes,
        }
    }

    /// The lying tube nearest `around_in_world` within `search_radius_m` of it on the belt, if
    /// the frame shows one.
    pub fn find(
        &self,
        image: &RgbImage,
        around_in_world: &Point3<f64>,
        search_radius_m: f64,
    ) -> Option<LyingPart> {
        self.find_all(image, around_in_world, search_radius_m)
            .into_iter()
            .next()
    }

    /// Every lying tube within `search_radius_m` of `around_in_world` on the belt, nearest
    /// first.
    pub fn find_all(
        &self,
        image: &RgbImage,
        around_in_world: &Point3<f64>,
        search_radius_m: f64,
    ) -> Vec<LyingPart> {
        let Some(roi) = self.search_window(image, around_in_world, search_radius_m) else {
            return Vec::new();
        };
        let mut mask = steel_mask(image, roi);
        let [[x_min, x_max], [y_min, y_max]] = self.belt_xy_m;
        let width = roi.2 - roi.0;
        for (i, steel) in mask.iter_mut().enumerate() {
            let (x, y) = (i as u32 % width + roi.0, i as u32 / width + roi.1);
            let on_belt = self
                .calibration
                .pixel_to_height(f64::from(x) + 0.5, f64::from(y) + 0.5, self.belt_top_z_m)
                .is_ok_and(|p| (x_min..=x_max).contains(&p.x) && (y_min..=y_max).contains(&p.y));
            *steel &= on_belt;
        }
        let bodies = components(&mask, roi.2 - roi.0, roi.3 - roi.1);
        let mut found: Vec<LyingPart> = bodies
            .into_iter()
            .filter(|body| body.len() >= MIN_BODY_PX)
            .filter_map(|body| {
                let pixels: Vec<[f64; 2]> = body
                    .iter()
                    .map(|&(x, y)| [f64::from(x + roi.0) + 0.5, f64::from(y + roi.1) + 0.5])
                    .collect();
                let lying = self.fit(&pixels)?;
                // A bore inside the body is a standing tube's end face, unless the body is a
                // lying tube seen along its axis: then a lying outline explains it better.
                let standing = hole_share(&body) > MAX_HOLE_SHARE
                    && self
                        .standing_residual_px(&pixels)
                        .is_some_and(|r| r <= STANDING_PREFERRED * lying.residual_px);
                (!standing).then_some(lying)
            })
            .filter(|part| {
                let d = part.centre_in_world - around_in_world;
                d.x.hypot(d.y) <= search_radius_m
            })
            .collect();
        let distance = |p: &LyingPart| (p.centre_in_world - around_in_world).xy().norm();
        found.sort_by(|a, b| distance(a).total_cmp(&distance(b)));
        found
    }

    /// The image window (`x0, y0, x1, y1`, end exclusive) that the belt's disc of
    /// `radius_m` around `around` projects into.
    fn search_window(
        &self,
        image: &RgbImage,
        around: &Point3<f64>,
        radius_m: f64,
    ) -> Option<(u32, u32, u32, u32)> {
        let mut b = [f64::INFINITY, f64::INFINITY, 0.0f64, 0.0f64];
        for k in 0..32 {
            let angle = std::f64::consts::TAU * f64::from(k) / 32.0;
            for z in [self.belt_top_z_m, self.belt_top_z_m + 0.1] {
                let point = Point3::new(
                    around.x + radius_m * angle.cos(),
                    around.y + radius_m * angle.sin(),
                    z,
                );
                let [u, v] = self.calibration.project(&point)?;
                b = [b[0].min(u), b[1].min(v), b[2].max(u), b[3].max(v)];
            }
        }
        let (w, h) = (f64::from(image.width()), f64::from(image.height()));
        let clamp = |value: f64, most: f64| value.clamp(0.0, most) as u32;
        let window = (
            clamp(b[0].floor(), w),
            clamp(b[1].floor(), h),
            clamp(b[2].ceil(), w),
            clamp(b[3].ceil(), h),
        );
        (window.2 > window.0 && window.3 > window.1).then_some(window)
    }

    /// The lying tube that explains a body's pixels, if one of the catalogue's sizes fits: each
    /// size, its axis along either extent of the pixels (and a few degrees either side), is
    /// slid over the belt until its outline's box is centred on the pixels' box, and the
    /// hypothesis whose box matches best is kept, as the bottle fit keeps its best pose.
    fn fit(&self, pixels: &[[f64; 2]]) -> Option<LyingPart> {
        let mean_diameter_m =
            self.sizes.iter().map(|s| s.diameter_m).sum::<f64>() / self.sizes.len().max(1) as f64;
        let plane_points = |radius_m: f64| -> Vec<Vector2<f64>> {
            let z = self.belt_top_z_m + radius_m;
            pixels
                .iter()
                .filter_map(|p| self.calibration.pixel_to_height(p[0], p[1], z).ok())
                .map(|p| Vector2::new(p.x, p.y))
                .collect()
        };
        let measured = extents(&plane_points(mean_diameter_m / 2.0))?;
        let major_yaw = measured.major_axis.y.atan2(measured.major_axis.x);
        let pixel_box = pixel_box(pixels);
        let centre_px = [
            (pixel_box[0] + pixel_box[2]) / 2.0,
            (pixel_box[1] + pixel_box[3]) / 2.0,
        ];
        let mut best: Option<LyingPart> = None;
        for (size_index, size) in self.sizes.iter().enumerate() {
            let outline = tube_outline(size.length_m, size.diameter_m / 2.0);
            let mid_z = self.belt_top_z_m + size.diameter_m / 2.0;
            for turn in [0.0, std::f64::consts::FRAC_PI_2] {
                for step in -YAW_STEPS..=YAW_STEPS {
                    let yaw_rad = (major_yaw + turn + f64::from(step) * YAW_STEP_RAD)
                        .rem_euclid(std::f64::consts::PI);
                    let pose_at = |x, y| lying_pose(Point3::new(x, y, mid_z), yaw_rad);
                    let Some(([x, y], b)) =
                        outline.slide_to_centre(&self.calibration, centre_px, mid_z, pose_at)
                    else {
                        continue;
                    };
                    let residual_px = box_residual_px(&b, &pixel_box);
                    if best.is_none_or(|best| residual_px < best.residual_px) {
                        best = Some(LyingPart {
                            centre_in_world: Point3::new(x, y, mid_z),
                            yaw_rad,
                            length_m: size.length_m,
                            diameter_m: size.diameter_m,
                            size_index,
                            residual_px,
                        });
                    }
                }
            }
        }
        // The pixels' own extents, laid on the plane through the fitted axis, must agree with
        // the size chosen: a body of another shape is no tube of the catalogue.
        let best = best?;
        let measured = extents(&plane_points(best.diameter_m / 2.0))?;
        let (long, short) = (
            best.length_m.max(best.diameter_m),
            best.length_m.min(best.diameter_m),
        );
        let error = ((measured.major_m - long) / long)
            .abs()
            .max(((measured.minor_m - short) / short).abs());
        let box_size = (pixel_box[2] - pixel_box[0]).hypot(pixel_box[3] - pixel_box[1]);
        (error <= MAX_SIZE_ERROR && best.residual_px <= MAX_BOX_RESIDUAL * box_size).then_some(best)
    }
}

impl LyingPartFinder {
    /// How well the best standing tube of the catalogue explains the pixels' box: the RMS
    /// difference of its outline's box, pixels.
    fn standing_residual_px(&self, pixels: &[[f64; 2]]) -> Option<f64> {
        let pixel_box = pixel_box(pixels);
        let centre_px = [
            (pixel_box[0] + pixel_box[2]) / 2.0,
            (pixel_box[1] + pixel_box[3]) / 2.0,
        ];
        self.sizes
            .iter()
            .filter_map(|size| {
                let outline = tube_outline(size.length_m, size.diameter_m / 2.0);
                let mid_z = self.belt_top_z_m + size.length_m / 2.0;
                let pose_at = |x, y| Isometry3::translation(x, y, mid_z);
                let (_, b) =
                    outline.slide_to_centre(&self.calibration, centre_px, mid_z, pose_at)?;
                Some(box_residual_px(&b, &pixel_box))
            })
            .min_by(f64::total_cmp)
    }
}

/// The box (`[x0, y0, x1, y1]`, pixels) of pixel centres, to their outer edges.
fn pixel_box(pixels: &[[f64; 2]]) -> [f64; 4] {
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for p in pixels {
        b = [
            b[0].min(p[0] - 0.5),
            b[1].min(p[1] - 0.5),
            b[2].max(p[0] + 0.5),
            b[3].max(p[1] + 0.5),
        ];
    }
    b
}

/// A lying tube's pose with the middle of its axis at `centre`, the axis at `yaw_rad`.
fn lying_pose(centre: Point3<f64>, yaw_rad: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(centre.coords),
        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad)
            * UnitQuaternion::from_euler_angles(0.0, std::f64::consts::FRAC_PI_2, 0.0),
    )
}

/// A tube's outline in its own frame (axis along z, origin at its middle): its two end rings.
fn tube_outline(length_m: f64, radius_m: f64) -> Silhouette {
    Silhouette::of_points((0..RING_POINTS).flat_map(|k| {
        let angle = std::f64::consts::TAU * k as f64 / RING_POINTS as f64;
        let (x, y) = (radius_m * angle.cos(), radius_m * angle.sin());
        [-length_m / 2.0, length_m / 2.0].map(|z| Point3::new(x, y, z))
    }))
}

/// A body's two extents on a plane, from the second moments of its points (those of a filled
/// rectangle: the side is the square root of 12 times the variance along it).
struct Extents {
    major_m: f64,
    minor_m: f64,
    major_axis: Vector2<f64>,
}

fn extents(points: &[Vector2<f64>]) -> Option<Extents> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let mean = points.iter().sum::<Vector2<f64>>() / n;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in points {
        let d = p - mean;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
    }
    let (sxx, sxy, syy) = (sxx / n, sxy / n, syy / n);
    let half_trace = (sxx + syy) / 2.0;
    let spread = (((sxx - syy) / 2.0).powi(2) + sxy * sxy).sqrt();
    let (large, small) = (half_trace + spread, (half_trace - spread).max(0.0));
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    Some(Extents {
        major_m: (12.0 * large).sqrt(),
        minor_m: (12.0 * small).sqrt(),
        major_axis: Vector2::new(angle.cos(), angle.sin()),
    })
}

/// Which pixels of the window `roi` (`x0, y0, x1, y1`) are bright, untinted steel, row by row.
fn steel_mask(image: &RgbImage, roi: (u32, u32, u32, u32)) -> Vec<bool> {
    let (x0, y0, x1, y1) = roi;
    let luminance = |x: u32, y: u32| {
        let p = image.get_pixel(x, y).0;
        (f64::from(p[0]) + f64::from(p[1]) + f64::from(p[2])) / 3.0
    };
    let mut levels: Vec<f64> = (y0..y1)
        .flat_map(|y| (x0..x1).map(move |x| (x, y)))
        .map(|(x, y)| luminance(x, y))
        .collect();
    levels.sort_by(f64::total_cmp);
    let belt = levels.get(levels.len() / 2).copied().unwrap_or(0.0);
    let threshold = belt * STEEL_OVER_BELT + STEEL_OFFSET;
    (y0..y1)
        .flat_map(|y| (x0..x1).map(move |x| (x, y)))
        .map(|(x, y)| {
            let p = image.get_pixel(x, y).0;
            let (r, b) = (f64::from(p[0]), f64::from(p[2]));
            luminance(x, y) > threshold && b <= r * TINT_RATIO + STEEL_OFFSET
        })
        .collect()
}

/// The 4-connected bodies of `mask` (`width` by `height`), as window pixel coordinates.
fn components(mask: &[bool], width: u32, height: u32) -> Vec<Vec<(u32, u32)>> {
    let mut seen = vec![false; mask.len()];
    let mut bodies = Vec::new();
    let index = |x: u32, y: u32| (y * width + x) as usize;
    for start in 0..mask.len() {
        if !mask[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        let mut body = Vec::new();
        let mut stack = vec![(start as u32 % width, start as u32 / width)];
        while let Some((x, y)) = stack.pop() {
            body.push((x, y));
            let neighbours = [
                (x.wrapping_sub(1), y),
                (x + 1, y),
                (x, y.wrapping_sub(1)),
                (x, y + 1),
            ];
            for (nx, ny) in neighbours {
                if nx < width && ny < height && mask[index(nx, ny)] && !seen[index(nx, ny)] {
                    seen[index(nx, ny)] = true;
                    stack.push((nx, ny));
                }
            }
        }
        body.sort_unstable_by_key(|&(x, y)| (y, x));
        bodies.push(body);
    }
    bodies
}

/// The share of a body's area that it encloses without covering (a bore seen from above): the
/// pixels of its box, not in it, that cannot reach the box's edge around it.
fn hole_share(body: &[(u32, u32)]) -> f64 {
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for &(x, y) in body {
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
    }
    // The body grown by a pixel or two, with a free border around it: a ring that noise or a
    // stain broke somewhere still closes around its bore.
    let grow = HOLE_CLOSING_PX;
    let (w, h) = (x1 - x0 + 1 + 2 * (grow + 1), y1 - y0 + 1 + 2 * (grow + 1));
    let mut inside = vec![false; (w * h) as usize];
    for &(x, y) in body {
        let (cx, cy) = (x - x0 + grow + 1, y - y0 + grow + 1);
        for yy in cy - grow..=cy + grow {
            for xx in cx - grow..=cx + grow {
                inside[(yy * w + xx) as usize] = true;
            }
        }
    }
    // Flood the box's free pixels from its border; what stays unreached is enclosed.
    let mut reached = vec![false; inside.len()];
    let mut stack: Vec<(u32, u32)> = Vec::new();
    for x in 0..w {
        stack.extend([(x, 0), (x, h - 1)]);
    }
    for y in 0..h {
        stack.extend([(0, y), (w - 1, y)]);
    }
    while let Some((x, y)) = stack.pop() {
        let i = (y * w + x) as usize;
        if inside[i] || reached[i] {
            continue;
        }
        reached[i] = true;
        if x > 0 {
            stack.push((x - 1, y));
        }
        if x + 1 < w {
            stack.push((x + 1, y));
        }
        if y > 0 {
            stack.push((x, y - 1));
        }
        if y + 1 < h {
            stack.push((x, y + 1));
        }
    }
    let enclosed = inside
        .iter()
        .zip(&reached)
        .filter(|&(&i, &r)| !i && !r)
        .count();
    enclosed as f64 / body.len().max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SimRng;

    #[test]
    fn extents_of_a_filled_rectangle_give_its_sides_and_axis() {
        let mut rng = SimRng::new(28);
        for _ in 0..20 {
            let (length, width) = (rng.range(0.03, 0.12), rng.range(0.01, 0.1));
            let yaw = rng.range(0.0, std::f64::consts::PI);
            let (c, s) = (yaw.cos(), yaw.sin());
            let points: Vec<Vector2<f64>> = (0..4000)
                .map(|_| {
                    let (u, v) = (rng.range(-0.5, 0.5) * length, rng.range(-0.5, 0.5) * width);
                    Vector2::new(c * u - s * v, s * u + c * v)
                })
                .collect();
            let Some(e) = extents(&points) else {
                panic!("no extents");
            };
            let (major, minor) = (length.max(width), length.min(width));
            assert!(
                (e.major_m - major).abs() < 0.03 * major,
                "{} vs {major}",
                e.major_m
            );
            assert!(
                (e.minor_m - minor).abs() < 0.03 * major,
                "{} vs {minor}",
                e.minor_m
            );
            if major > 1.3 * minor {
                let axis = if length > width { [c, s] } else { [-s, c] };
                let along = (e.major_axis.x * axis[0] + e.major_axis.y * axis[1]).abs();
                assert!(along > 0.99, "axis off: {along}");
            }
        }
    }

    #[test]
    fn a_ring_encloses_its_hole_and_a_bar_does_not() {
        let ring: Vec<(u32, u32)> = (0..25u32)
            .flat_map(|y| (0..25u32).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let r2 = (f64::from(x) - 12.0).powi(2) + (f64::from(y) - 12.0).powi(2);
                (64.0..=144.0).contains(&r2)
            })
            .collect();
        assert!(hole_share(&ring) > 0.2);
        let bar: Vec<(u32, u32)> = (0..8u32)
            .flat_map(|y| (0..30u32).map(move |x| (x, y)))
            .collect();
        assert_eq!(hole_share(&bar), 0.0);
        let mask: Vec<bool> = (0..100).map(|i| (i % 10) < 3 || (i % 10) > 6).collect();
        assert_eq!(components(&mask, 10, 10).len(), 2);
    }
}
