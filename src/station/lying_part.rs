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
const STEEL_OVER_BELT: f64 = 2.5;
/// Grey levels added to the threshold, so that a near-black belt's noise stays out.
const STEEL_OFFSET: f64 = 12.0;
/// Blue over red above which a bright pixel is the bottle's tinted plastic, not steel.
const TINT_RATIO: f64 = 1.12;
/// A body with more than this share of its area enclosed dark is a standing tube's end face.
const MAX_HOLE_SHARE: f64 = 0.08;
/// Fewest pixels of a body worth fitting.
const MIN_BODY_PX: usize = 60;
/// Largest relative error of length and diameter against the nearest catalogue tube.
const MAX_SIZE_ERROR: f64 = 0.3;
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
        let roi = self.search_window(image, around_in_world, search_radius_m)?;
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
        bodies
            .into_iter()
            .filter(|body| body.len() >= MIN_BODY_PX)
            .filter(|body| hole_share(body) <= MAX_HOLE_SHARE)
            .filter_map(|body| {
                let pixels: Vec<[f64; 2]> = body
                    .iter()
                    .map(|&(x, y)| [f64::from(x + roi.0) + 0.5, f64::from(y + roi.1) + 0.5])
                    .collect();
                self.fit(&pixels)
            })
            .filter(|part| {
                let d = part.centre_in_world - around_in_world;
                d.x.hypot(d.y) <= search_radius_m
            })
            .min_by(|a, b| {
                let da = (a.centre_in_world - around_in_world).xy().norm();
                let db = (b.centre_in_world - around_in_world).xy().norm();
                da.total_cmp(&db)
            })
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

    /// The lying tube that explains a body's pixels, if one of the catalogue's sizes fits.
    fn fit(&self, pixels: &[[f64; 2]]) -> Option<LyingPart> {
        // Lay the pixels on the plane through the axis; its height depends on the diameter,
        // which the first pass measures.
        let mean_diameter_m =
            self.sizes.iter().map(|s| s.diameter_m).sum::<f64>() / self.sizes.len().max(1) as f64;
        let mut radius_m = mean_diameter_m / 2.0;
        let mut shape = None;
        for _ in 0..3 {
            let z = self.belt_top_z_m + radius_m;
            let points: Vec<Vector2<f64>> = pixels
                .iter()
                .filter_map(|p| self.calibration.pixel_to_height(p[0], p[1], z).ok())
                .map(|p| Vector2::new(p.x, p.y))
                .collect();
            let measured = extents(&points)?;
            let (size_index, along_major, error) =
                self.nearest_size(measured.major_m, measured.minor_m)?;
            if error > MAX_SIZE_ERROR {
                return None;
            }
            let diameter_m = if along_major {
                measured.minor_m
            } else {
                measured.major_m
            };
            radius_m = diameter_m / 2.0;
            shape = Some((measured, size_index, along_major));
        }
        let (measured, size_index, along_major) = shape?;
        let (length_m, diameter_m, axis) = if along_major {
            (measured.major_m, measured.minor_m, measured.major_axis)
        } else {
            (
                measured.minor_m,
                measured.major_m,
                Vector2::new(-measured.major_axis.y, measured.major_axis.x),
            )
        };
        let yaw_rad = axis.y.atan2(axis.x).rem_euclid(std::f64::consts::PI);
        // Place the outline where its box is centred on the pixels' box.
        let mut pixel_box = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for p in pixels {
            pixel_box = [
                pixel_box[0].min(p[0] - 0.5),
                pixel_box[1].min(p[1] - 0.5),
                pixel_box[2].max(p[0] + 0.5),
                pixel_box[3].max(p[1] + 0.5),
            ];
        }
        let outline = tube_outline(length_m, diameter_m / 2.0);
        let mid_z = self.belt_top_z_m + diameter_m / 2.0;
        let centre_px = [
            (pixel_box[0] + pixel_box[2]) / 2.0,
            (pixel_box[1] + pixel_box[3]) / 2.0,
        ];
        let pose_at = |x, y| lying_pose(Point3::new(x, y, mid_z), yaw_rad);
        let ([x, y], b) = outline.slide_to_centre(&self.calibration, centre_px, mid_z, pose_at)?;
        Some(LyingPart {
            centre_in_world: Point3::new(x, y, mid_z),
            yaw_rad,
            length_m,
            diameter_m,
            size_index,
            residual_px: box_residual_px(&b, &pixel_box),
        })
    }

    /// The catalogue size nearest an outline `major_m` by `minor_m`: its index, whether the
    /// length lies along the major extent, and the larger relative error of the two.
    fn nearest_size(&self, major_m: f64, minor_m: f64) -> Option<(usize, bool, f64)> {
        self.sizes
            .iter()
            .enumerate()
            .flat_map(|(i, size)| {
                [true, false].map(|along_major| {
                    let (length, diameter) = if along_major {
                        (major_m, minor_m)
                    } else {
                        (minor_m, major_m)
                    };
                    let error = ((length - size.length_m) / size.length_m)
                        .abs()
                        .max(((diameter - size.diameter_m) / size.diameter_m).abs());
                    (i, along_major, error)
                })
            })
            .min_by(|a, b| a.2.total_cmp(&b.2))
    }
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
    let (w, h) = (x1 - x0 + 1, y1 - y0 + 1);
    let mut inside = vec![false; (w * h) as usize];
    for &(x, y) in body {
        inside[((y - y0) * w + (x - x0)) as usize] = true;
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
        let ring: Vec<(u32, u32)> = (0..21u32)
            .flat_map(|y| (0..21u32).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let r2 = (f64::from(x) - 10.0).powi(2) + (f64::from(y) - 10.0).powi(2);
                (25.0..=100.0).contains(&r2)
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
