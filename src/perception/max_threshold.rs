//! A threshold against the brightest level nearby: bright where a pixel reaches a share of the
//! local maximum. The bore detector's second segmentation
//! ([`crate::perception::bore::BoreDetectorParams::local_max_share`]).
//!
//! Oil on a rim darkens the metal by a factor (0.55 and more of its level), while a bore keeps
//! below 0.3 of its rim's level. Where oil covers the wall across, the adaptive mean threshold
//! reads the stained arc as dark (it lies below its bright surroundings) and the bore's dark
//! region runs through it out onto the belt: no hole, no candidate. A share of the nearby
//! maximum between the two keeps the stained arc bright and the bore dark, under any smooth
//! light, since both scale with it.
//!
//! The maximum is taken over square tiles and then over the tiles around each one, so the
//! window is about `(2 reach + 1) tile` pixels on a side; the level is the same for a whole tile.
//! Where the maximum is itself dark (a wide bore's middle, a dark belt) everything within a
//! bore's least contrast of it stays bright, so noise does not speckle it into holes.

use image::GrayImage;

/// Side of the square tiles the maximum is kept for, pixels.
pub const TILE_PX: usize = 8;

/// Bright (255) where `p > min(floor(share * m), m - floor_px)`, `m` the largest level over the
/// tiles within `reach_tiles` tiles of the pixel's own tile (saturating at 0); dark (0)
/// elsewhere. The second term keeps a flat dark area (the middle of a wide bore, a dark belt)
/// bright as a whole instead of speckled by noise about a low share of a low maximum: a bore is
/// `floor_px` darker than its rim at least.
pub fn local_max_threshold(
    image: &GrayImage,
    reach_tiles: usize,
    share: f64,
    floor_px: u8,
) -> GrayImage {
    let (w, h) = (image.width() as usize, image.height() as usize);
    let mut binary = GrayImage::new(image.width(), image.height());
    if w == 0 || h == 0 {
        return binary;
    }
    let (tw, th) = (w.div_ceil(TILE_PX), h.div_ceil(TILE_PX));
    let pixels: &[u8] = image;
    // Each tile's maximum: the rows of a band of tiles folded into one row (lane by lane, which
    // vectorises), then each tile's stretch of it.
    let mut tiles = vec![0u8; tw * th];
    let mut folded = vec![0u8; w];
    for (band, maxima) in pixels.chunks(w * TILE_PX).zip(tiles.chunks_exact_mut(tw)) {
        folded.fill(0);
        for row in band.chunks_exact(w) {
            for (m, &p) in folded.iter_mut().zip(row) {
                *m = (*m).max(p);
            }
        }
        for (m, chunk) in maxima.iter_mut().zip(folded.chunks(TILE_PX)) {
            *m = chunk.iter().copied().max().unwrap_or(0);
        }
    }
    // The maximum over the neighbouring tiles: along rows, then along columns.
    let mut across = vec![0u8; tw * th];
    for (out, row) in across.chunks_exact_mut(tw).zip(tiles.chunks_exact(tw)) {
        for (x, o) in out.iter_mut().enumerate() {
            let (a, b) = (x.saturating_sub(reach_tiles), (x + reach_tiles).min(tw - 1));
            *o = row[a..=b].iter().copied().max().unwrap_or(0);
        }
    }
    // Each band of tiles' levels spread over a row of pixels, then every row of the band
    // compared with it (lane by lane).
    let mut levels = vec![0u8; w];
    let out: &mut [u8] = &mut binary;
    for (ty, (band_out, band)) in out
        .chunks_mut(w * TILE_PX)
        .zip(pixels.chunks(w * TILE_PX))
        .enumerate()
    {
        let (a, b) = (
            ty.saturating_sub(reach_tiles),
            (ty + reach_tiles).min(th - 1),
        );
        for (tx, stretch) in levels.chunks_mut(TILE_PX).enumerate() {
            let m = (a..=b).map(|t| across[t * tw + tx]).max().unwrap_or(0);
            let by_share = (share * f64::from(m)).floor().clamp(0.0, 255.0) as u8;
            stretch.fill(by_share.min(m.saturating_sub(floor_px)));
        }
        for (row_out, row) in band_out.chunks_exact_mut(w).zip(band.chunks_exact(w)) {
            for ((o, &p), &level) in row_out.iter_mut().zip(row).zip(&levels) {
                *o = u8::from(p > level).wrapping_neg();
            }
        }
    }
    binary
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Luma;

    /// The definition, pixel by pixel.
    fn plain(image: &GrayImage, reach: usize, share: f64, floor: u8) -> GrayImage {
        let (w, h) = image.dimensions();
        GrayImage::from_fn(w, h, |x, y| {
            let (tx, ty) = (x as usize / TILE_PX, y as usize / TILE_PX);
            let mut m = 0u8;
            for yy in 0..h {
                for xx in 0..w {
                    let (ux, uy) = (xx as usize / TILE_PX, yy as usize / TILE_PX);
                    if ux.abs_diff(tx) <= reach && uy.abs_diff(ty) <= reach {
                        m = m.max(image.get_pixel(xx, yy)[0]);
                    }
                }
            }
            let level = ((share * f64::from(m)).floor() as u8).min(m.saturating_sub(floor));
            Luma([if image.get_pixel(x, y)[0] > level {
                255
            } else {
                0
            }])
        })
    }

    #[test]
    fn matches_the_definition_on_ragged_frames() {
        let mut state = 7u64;
        for (w, h) in [(37u32, 29u32), (64, 16), (17, 41), (1, 1), (8, 9)] {
            let image = GrayImage::from_fn(w, h, |_, _| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                Luma([(state >> 56) as u8])
            });
            for (reach, share, floor) in [(0, 0.5, 0), (1, 0.42, 25), (2, 0.3, 200)] {
                assert_eq!(
                    local_max_threshold(&image, reach, share, floor),
                    plain(&image, reach, share, floor),
                    "{w}x{h} reach {reach} share {share} floor {floor}"
                );
            }
        }
    }

    #[test]
    fn a_stained_rim_stays_bright_and_the_bore_dark() {
        // A rim at 200 with an arc at 0.55 of it, around a bore at 40, on a belt at 30.
        let image = GrayImage::from_fn(96, 96, |x, y| {
            let (dx, dy) = (f64::from(x) - 48.0, f64::from(y) - 48.0);
            let r = dx.hypot(dy);
            Luma([if r < 16.0 {
                40
            } else if r < 30.0 {
                if dx > 0.0 { 110 } else { 200 }
            } else {
                30
            }])
        });
        let binary = local_max_threshold(&image, 2, 0.42, 25);
        assert_eq!(binary.get_pixel(48, 48)[0], 0);
        assert_eq!(binary.get_pixel(48 + 22, 48)[0], 255);
        assert_eq!(binary.get_pixel(48 - 22, 48)[0], 255);
        assert_eq!(binary.get_pixel(2, 2)[0], 255, "a flat belt far away");
        // A dark belt far away stays bright, noise or not.
        let dark = GrayImage::from_fn(64, 64, |x, y| Luma([if (x + y) % 3 == 0 { 5 } else { 20 }]));
        assert!(
            local_max_threshold(&dark, 2, 0.42, 25)
                .pixels()
                .all(|p| p[0] == 255)
        );
        assert_eq!(binary.get_pixel(48 + 33, 48)[0], 0, "the belt by the rim");
    }
}
