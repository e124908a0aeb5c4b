//! Contour extraction by border following (Suzuki and Abe), as `findContours` in the paper's
//! toolchain: outer borders and hole borders of 8-connected bright regions, with their nesting.
//!
//! A hole border surrounds a dark region that is fully enclosed by bright pixels: exactly the
//! "dark bore inside a bright rim" shape the bore detector looks for.

use crate::perception::circle_fit::distance;
use crate::perception::contour_scan::quiet_run;
use image::GrayImage;
use std::f64::consts::TAU;

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

/// Neighbour steps in clockwise order (y down): W, NW, N, NE, E, SE, S, SW.
const STEPS: [(isize, isize); 8] = [
    (-1, 0),
    (-1, -1),
    (0, -1),
    (1, -1),
    (1, 0),
    (1, 1),
    (0, 1),
    (-1, 1),
];
/// Index of the east step in [`STEPS`].
const EAST: usize = 4;

/// Pixel states of the working copy.
pub(crate) const BACKGROUND: u8 = 0;
/// Bright, not on a border traced so far.
pub(crate) const UNVISITED: u8 = 1;
/// On a traced border, with a bright east neighbour (Suzuki and Abe's positive label).
pub(crate) const MARKED: u8 = 2;
/// On a traced border whose east neighbour is dark (their negative label): no hole starts here.
pub(crate) const MARKED_EAST: u8 = 3;

/// All borders of the bright (non-zero) regions of a binary image, in raster order of their
/// starting pixels; the image is taken to be surrounded by dark pixels.
///
/// Suzuki and Abe's border following (1985, algorithm 1) on a zero-padded byte copy of the
/// image: pixel states live in one byte and the border numbers of traced pixels in a separate
/// map that is only read where a state says a border passed. Uniform 8-byte runs (all dark, or
/// all unvisited bright between bright neighbours) are skipped a word at a time: on a
/// thresholded frame nearly every word is such a run. Points are listed in tracing order:
/// clockwise for outer borders and counter-clockwise for holes, as seen with y down.
pub fn find_contours(binary: &GrayImage) -> Vec<Contour> {
    let (w, h) = (binary.width() as usize, binary.height() as usize);
    if w == 0 || h == 0 {
        return Vec::new();
    }
    // One column of padding either side, one row above and below (plus 8 spare bytes so the
    // word reads at a row's end stay in bounds).
    let stride = w + 2;
    // Written in order rather than zeroed first and then filled: one pass over the bytes.
    let len = stride * (h + 2) + 8;
    let mut state = Vec::with_capacity(len);
    // The top padding row and the first row's left padding.
    state.resize(stride + 1, BACKGROUND);
    for row in binary.as_raw().chunks_exact(w) {
        state.extend(row.iter().map(|&p| u8::from(p != 0)));
        // This row's right padding and the next row's left padding.
        state.extend_from_slice(&[BACKGROUND; 2]);
    }
    state.resize(len, BACKGROUND);
    LABELS.with_borrow_mut(|label| {
        if label.len() < state.len() {
            label.resize(state.len(), 0);
        }
        follow_all(&mut state, label, stride, w, h)
    })
}

thread_local! {
    /// Border numbers by pixel, kept between calls so a frame does not pay for zeroing 4 bytes
    /// a pixel: a number is only read where this call's pixel state says a border passed, and
    /// such a pixel's number was written by this call.
    static LABELS: std::cell::RefCell<Vec<u32>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// The raster scan of [`find_contours`] over the padded state image.
fn follow_all(
    state: &mut [u8],
    label: &mut [u32],
    stride: usize,
    w: usize,
    h: usize,
) -> Vec<Contour> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the function only requires AVX2, which the CPU was just found to have.
        return unsafe { follow_all_avx2(state, label, stride, w, h) };
    }
    follow_all_kernel(state, label, stride, w, h, false)
}

/// [`follow_all_kernel`] compiled for AVX2, its block skips inlined.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn follow_all_avx2(
    state: &mut [u8],
    label: &mut [u32],
    stride: usize,
    w: usize,
    h: usize,
) -> Vec<Contour> {
    follow_all_kernel(state, label, stride, w, h, true)
}

/// The body of [`follow_all`]; `avx2` only from the AVX2 build.
#[inline(always)]
fn follow_all_kernel(
    state: &mut [u8],
    label: &mut [u32],
    stride: usize,
    w: usize,
    h: usize,
    avx2: bool,
) -> Vec<Contour> {
    let offsets: [isize; 8] = STEPS.map(|(dx, dy)| dx + dy * stride as isize);

    let mut contours: Vec<Contour> = Vec::new();
    for y in 1..=h {
        // The last traced pixel the scan passed on this row; its border number is the last
        // border seen (the frame, number 1, before any). Read only where a border starts: no
        // trace runs between passing that pixel and the next start, so it still holds the
        // number it held when passed.
        let mut last_marked: Option<usize> = None;
        let mut x = 1;
        let row_end = y * stride + w + 1;
        while x <= w {
            let p = y * stride + x;
            let quiet = quiet_run(avx2, state, p, row_end);
            if let Some(marked) = quiet.last_marked {
                last_marked = Some(marked);
            }
            if quiet.pixels > 0 {
                x += quiet.pixels;
                continue;
            }
            let here = state[p];
            if here == BACKGROUND {
                x += 1;
                continue;
            }
            let start = if here == UNVISITED && state[p - 1] == BACKGROUND {
                Some((0, BorderKind::Outer))
            } else if here != MARKED_EAST && state[p + 1] == BACKGROUND {
                if here == MARKED {
                    last_marked = Some(p);
                }
                Some((EAST, BorderKind::Hole))
            } else {
                None
            };
            if let Some((from_dir, kind)) = start {
                let last_border = last_marked.map_or(1, |m| label[m]);
                let number = contours.len() as u32 + 2;
                let parent = if last_border > 1 {
                    let index = (last_border - 2) as usize;
                    let enclosing = &contours[index];
                    if (kind == BorderKind::Outer) != (enclosing.kind == BorderKind::Outer) {
                        Some(index)
                    } else {
                        enclosing.parent
                    }
                } else {
                    None
                };
                let points_px = trace(state, label, &offsets, stride, w, p, from_dir, number);
                contours.push(Contour {
                    points_px,
                    kind,
                    parent,
                });
            }
            if state[p] != UNVISITED {
                last_marked = Some(p);
            }
            x += 1;
        }
    }
    contours
}

/// Follows one border from its starting pixel `start` whose dark neighbour lies in direction
/// `from_dir`, marking its pixels with `number`; returns its pixels in image coordinates.
#[allow(clippy::too_many_arguments)]
fn trace(
    state: &mut [u8],
    label: &mut [u32],
    offsets: &[isize; 8],
    stride: usize,
    width: usize,
    start: usize,
    from_dir: usize,
    number: u32,
) -> Vec<[i32; 2]> {
    // Image coordinates of the current pixel, stepped along with it (a division per pixel to
    // recover them from the index was the tracing's largest cost).
    let (start_x, start_y) = ((start % stride) as i32 - 1, (start / stride) as i32 - 1);
    let step = |p: usize, d: usize| p.wrapping_add_signed(offsets[d]);
    // First bright neighbour clockwise from the dark one.
    let Some(first_dir) = (0..8)
        .map(|k| (from_dir + k) % 8)
        .find(|&d| state[step(start, d)] != BACKGROUND)
    else {
        state[start] = MARKED_EAST;
        label[start] = number;
        return vec![[start_x, start_y]];
    };
    let first = step(start, first_dir);
    let last_column = width as i32 - 1;
    let spare = state.len() - 1;
    let mut points = Vec::new();
    let mut current = start;
    let mut here = [start_x, start_y];
    // Direction from `current` to the previous border pixel.
    let mut back_dir = first_dir;
    loop {
        points.push(here);
        // Counter-clockwise from the one after the previous pixel, to the next bright one: the
        // neighbours as bits (bit `7 - d` for direction `d`), rotated so that bit `i` is
        // direction `back_dir - 1 - i`; the first bright one is then the lowest set bit. One
        // branch-free step where testing neighbour after neighbour mispredicted.
        let mut reversed = 0u8;
        for (d, &offset) in offsets.iter().enumerate() {
            let bright = state[current.wrapping_add_signed(offset)] != BACKGROUND;
            reversed |= u8::from(bright) << (7 - d);
        }
        let searched = reversed.rotate_right((8 - back_dir as u32) % 8);
        // All eight dark (never on a border: the previous pixel is bright) ends the search
        // back at `back_dir`, every direction passed.
        let found = searched.trailing_zeros() as usize;
        let next_dir = (back_dir + 7 - found.min(7)) % 8;
        // The east neighbour was passed, dark, before the next pixel was found.
        let east_dark = (back_dir + 7 - EAST) % 8 < found;
        let next = step(current, next_dir);
        // Marked by selects, not branches (whether the east neighbour is dark changes from
        // pixel to pixel, and mispredicted): a label that must not change is written to a
        // spare byte's slot past the last row, which nothing reads.
        let (mark_east, unvisited) = (
            east_dark || here[0] == last_column,
            state[current] == UNVISITED,
        );
        let old_state = state[current];
        state[current] = if mark_east {
            MARKED_EAST
        } else if unvisited {
            MARKED
        } else {
            old_state
        };
        let labelled = if mark_east || unvisited {
            current
        } else {
            spare
        };
        label[labelled] = number;
        if next == start && current == first {
            return points;
        }
        back_dir = (next_dir + 4) % 8;
        current = next;
        let (dx, dy) = STEPS[next_dir];
        here = [here[0] + dx as i32, here[1] + dy as i32];
    }
}

/// The same borders from imageproc's implementation: the oracle for [`find_contours`]'s tests
/// and the library baseline of the metrology benchmark.
///
/// imageproc does not start an outer border in the image's first column; on images whose first
/// column is dark the two agree exactly.
pub fn find_contours_imageproc(binary: &GrayImage) -> Vec<Contour> {
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

/// Mean coarse radius per angular bin about `centre`; empty bins interpolated circularly.
pub(crate) fn binned_radii(
    points: &[[f64; 2]],
    centre: [f64; 2],
    bins: usize,
    fallback: f64,
) -> Vec<f64> {
    let mut sum = vec![0.0f64; bins];
    let mut count = vec![0u32; bins];
    for q in points {
        let (dx, dy) = (q[0] - centre[0], q[1] - centre[1]);
        let angle = dy.atan2(dx).rem_euclid(TAU);
        // Truncation of the value plus a half: `round` for these non-negative values, without
        // a libm call per border point.
        let bin = ((angle / TAU * bins as f64 + 0.5) as usize) % bins;
        sum[bin] += distance(dx, dy);
        count[bin] += 1;
    }
    let filled: Vec<usize> = (0..bins).filter(|&i| count[i] > 0).collect();
    if filled.is_empty() {
        return vec![fallback; bins];
    }
    let value = |i: usize| sum[i] / f64::from(count[i]);
    let mut radii = vec![0.0; bins];
    for (k, &i) in filled.iter().enumerate() {
        let j = filled[(k + 1) % filled.len()];
        let gap = (j + bins - i) % bins;
        let gap = if gap == 0 { bins } else { gap };
        for step in 0..gap {
            let f = step as f64 / gap as f64;
            radii[(i + step) % bins] = (1.0 - f) * value(i) + f * value(j);
        }
    }
    radii
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Luma;

    /// Random blobs, rings and salt noise with a dark first column (where imageproc differs).
    fn random_binary(seed: u64, width: u32, height: u32) -> GrayImage {
        let mut rng = crate::rng::SimRng::new(seed);
        let mut image = GrayImage::new(width, height);
        for _ in 0..12 {
            let (cx, cy) = (
                rng.range(0.0, f64::from(width)),
                rng.range(0.0, f64::from(height)),
            );
            let (r_in, r_out) = (rng.range(0.0, 15.0), rng.range(3.0, 40.0));
            let ex = rng.range(0.5, 1.5);
            for (x, y, p) in image.enumerate_pixels_mut() {
                let (dx, dy) = ((f64::from(x) - cx) * ex, f64::from(y) - cy);
                let d = dx.hypot(dy);
                if d <= r_out && d >= r_in {
                    *p = Luma([255 - p.0[0]]);
                }
            }
        }
        for _ in 0..(width * height / 40) {
            let x = (rng.next_u64() % u64::from(width)) as u32;
            let y = (rng.next_u64() % u64::from(height)) as u32;
            let old = image.get_pixel(x, y).0[0];
            image.put_pixel(x, y, Luma([255 - old]));
        }
        for y in 0..height {
            image.put_pixel(0, y, Luma([0]));
        }
        image
    }

    #[test]
    fn own_border_following_equals_imageproc() {
        for seed in 0..60 {
            let (w, h) = (40 + (seed as u32 * 7) % 90, 30 + (seed as u32 * 13) % 70);
            let image = random_binary(seed, w, h);
            assert_eq!(
                find_contours(&image),
                find_contours_imageproc(&image),
                "seed {seed} ({w}x{h})"
            );
        }
    }

    #[test]
    fn thin_and_tiny_shapes_match_the_oracle() {
        // Single pixels, one-pixel lines, a full-width bar and bright pixels at the right and
        // bottom edges.
        let mut image = GrayImage::new(24, 12);
        for (x, y) in [(3, 3), (5, 1), (23, 0), (23, 11), (10, 11)] {
            image.put_pixel(x, y, Luma([1]));
        }
        for x in 1..24 {
            image.put_pixel(x, 6, Luma([9]));
        }
        for y in 0..12 {
            image.put_pixel(15, y, Luma([200]));
        }
        assert_eq!(find_contours(&image), find_contours_imageproc(&image));
        assert!(find_contours(&GrayImage::new(0, 0)).is_empty());
    }

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
