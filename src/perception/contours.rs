//! Contour extraction by border following (Suzuki and Abe), as `findContours` in the paper's
//! toolchain: outer borders and hole borders of 8-connected bright regions, with their nesting.
//!
//! A hole border surrounds a dark region that is fully enclosed by bright pixels: exactly the
//! "dark bore inside a bright rim" shape the bore detector looks for.

use image::GrayImage;

/// Whether a border surrounds a bright region from outside or a dark hole inside one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BorderKind {
    /// Outer border of a bright region.
    Outer,
    /// Border of a dark hole enclosed by a bright region.
    Hole,
}

/// One border: its pixels (bright side) in tracing order.
#[derive(Debug, Clone, PartialEq)]
pub struct Contour {
    /// Border pixels, `[x, y]`.
    pub points_px: Vec<[i32; 2]>,
    /// Outer or hole border.
    pub kind: BorderKind,
    /// Index of the enclosing border in the returned list.
    pub parent: Option<usize>,
}

/// All borders of the bright (non-zero) regions of a binary image.
pub fn find_contours(binary: &GrayImage) -> Vec<Contour> {
    imageproc::contours::find_contours::<i32>(binary)
        .into_iter()
        .map(|c| Contour {
            points_px: c.points.iter().map(|p| [p.x, p.y]).collect(),
            kind: match c.border_type {
                imageproc::contours::BorderType::Outer => BorderKind::Outer,
                imageproc::contours::BorderType::Hole => BorderKind::Hole,
            },
            parent: c.parent,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Luma;

    #[test]
    fn a_ring_has_an_outer_and_a_hole_border() {
        let mut image = GrayImage::new(30, 30);
        for (x, y, p) in image.enumerate_pixels_mut() {
            let d2 = (x as i32 - 15).pow(2) + (y as i32 - 15).pow(2);
            if (25..=100).contains(&d2) {
                *p = Luma([255]);
            }
        }
        let contours = find_contours(&image);
        assert_eq!(contours.len(), 2);
        assert_eq!(contours[0].kind, BorderKind::Outer);
        assert_eq!(contours[1].kind, BorderKind::Hole);
        assert_eq!(contours[1].parent, Some(0));
        // Hole border pixels are bright and touch the hole.
        for [x, y] in &contours[1].points_px {
            let d2 = (x - 15).pow(2) + (y - 15).pow(2);
            assert!((25..=40).contains(&d2), "({x}, {y})");
        }
    }
}
