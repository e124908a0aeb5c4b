//! The raster scan of border following ([`crate::perception::contours`]): the stretches of a
//! row where no border starts, skipped a block at a time (32 pixels with AVX2, 8 in a word
//! otherwise), noting the last traced pixel in them, whose border number is the last border
//! seen.

use crate::perception::contours::{MARKED, UNVISITED};

/// A stretch of a row the raster scan passes without starting a border.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct QuietRun {
    /// Its length, pixels.
    pub(crate) pixels: usize,
    /// The last traced pixel in it.
    pub(crate) last_marked: Option<usize>,
}

/// The pixels from `p` on (before `end`, which must be a padding byte or before one) where no
/// border starts, counted a block at a time: the scan skips them, noting the last traced one. A
/// border starts at an unvisited bright pixel with a dark left neighbour (outer), or at an
/// unvisited or traced pixel whose east neighbour is dark and was not found so by a trace
/// (hole). May stop short of the first start (the scan then steps through the rest one by one,
/// to the same effect).
#[inline(always)]
pub(crate) fn quiet_run(avx2: bool, state: &[u8], p: usize, end: usize) -> QuietRun {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` is true only where the CPU was found to have AVX2.
        return unsafe { quiet_run_avx2(state, p, end) };
    }
    let _ = avx2;
    quiet_run_words(state, p, end)
}

/// The last traced pixel of a block from `from` before its first start (`starts` and `marked`:
/// one bit per pixel, at most 32), or `last` when it has none; and where the first start is.
#[inline(always)]
fn block_end(from: usize, starts: u64, marked: u64, last: Option<usize>) -> (Option<usize>, u32) {
    let length = (starts | (1 << 32)).trailing_zeros();
    let before = marked & ((1u64 << length) - 1);
    let last = if before != 0 {
        Some(from + 63 - before.leading_zeros() as usize)
    } else {
        last
    };
    (last, length)
}

/// [`quiet_run`] eight pixels a word: the states are 0 to 3, so a byte's two low bits say all.
#[inline]
fn quiet_run_words(state: &[u8], p: usize, end: usize) -> QuietRun {
    const ONES: u64 = 0x0101_0101_0101_0101;
    let word = |a: usize| {
        state
            .get(a..a + 8)
            .and_then(|b| b.first_chunk::<8>())
            .map(|b| u64::from_le_bytes(*b))
    };
    // One bit per byte (its lowest) to one bit per pixel.
    let pack = |v: u64| (0..8).fold(0u64, |bits, k| bits | (((v >> (8 * k)) & 1) << k));
    // The block's address does not wait on the block before (only the exit does), so the
    // loads run ahead.
    let (mut q, mut last_marked) = (p, None);
    while q + 8 <= end {
        let (Some(left), Some(here), Some(right)) = (word(q.wrapping_sub(1)), word(q), word(q + 1))
        else {
            break;
        };
        let dark = |v: u64| !(v | (v >> 1)) & ONES;
        let (low, high) = (here & ONES, (here >> 1) & ONES);
        let outer = low & !high & dark(left);
        let hole = (low ^ high) & dark(right);
        let starts = pack(outer | hole);
        let (last, length) = block_end(q, starts, pack(high), last_marked);
        last_marked = last;
        if starts != 0 {
            return QuietRun {
                pixels: q + length as usize - p,
                last_marked,
            };
        }
        q += 8;
    }
    QuietRun {
        pixels: q - p,
        last_marked,
    }
}

/// [`quiet_run`] 32 pixels at a time with AVX2, then word by word.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn quiet_run_avx2(state: &[u8], p: usize, end: usize) -> QuietRun {
    use std::arch::x86_64::*;
    let (one, two, zero) = (
        _mm256_set1_epi8(UNVISITED as i8),
        _mm256_set1_epi8(MARKED as i8),
        _mm256_setzero_si256(),
    );
    let (mut q, mut last_marked) = (p, None);
    while q + 32 <= end {
        let (Some(left), Some(here), Some(right)) = (
            state.get(q.wrapping_sub(1)..q + 31),
            state.get(q..q + 32),
            state.get(q + 1..q + 33),
        ) else {
            break;
        };
        // SAFETY: each slice holds exactly 32 bytes.
        let (left, here, right) = unsafe {
            (
                _mm256_loadu_si256(left.as_ptr().cast()),
                _mm256_loadu_si256(here.as_ptr().cast()),
                _mm256_loadu_si256(right.as_ptr().cast()),
            )
        };
        let unvisited = _mm256_cmpeq_epi8(here, one);
        let open_east = _mm256_or_si256(unvisited, _mm256_cmpeq_epi8(here, two));
        let outer = _mm256_and_si256(unvisited, _mm256_cmpeq_epi8(left, zero));
        let hole = _mm256_and_si256(open_east, _mm256_cmpeq_epi8(right, zero));
        let bits = |v: __m256i| u64::from(_mm256_movemask_epi8(v) as u32);
        let starts = bits(_mm256_or_si256(outer, hole));
        let (last, length) = block_end(q, starts, bits(_mm256_cmpgt_epi8(here, one)), last_marked);
        last_marked = last;
        if starts != 0 {
            return QuietRun {
                pixels: q + length as usize - p,
                last_marked,
            };
        }
        q += 32;
    }
    let rest = quiet_run_words(state, q, end);
    QuietRun {
        pixels: q - p + rest.pixels,
        last_marked: rest.last_marked.or(last_marked),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::contours::BACKGROUND;

    /// Whether a border starts at a pixel (see [`quiet_run`]).
    fn starts(left: u8, here: u8, right: u8) -> bool {
        (here == UNVISITED && left == BACKGROUND)
            || ((here == UNVISITED || here == MARKED) && right == BACKGROUND)
    }

    #[test]
    fn quiet_runs_stop_at_the_first_start_and_note_the_last_traced_pixel_in_both_builds() {
        let mut rng = crate::rng::SimRng::new(5);
        for trial in 0..5000 {
            let len = 2 + (rng.next_u64() % 150) as usize;
            // Mostly long runs of one state, sometimes any state.
            let mut state = vec![0u8; len + 1];
            let mut level = 0u8;
            for s in &mut state {
                if rng.uniform() < 0.08 {
                    level = (rng.next_u64() % 4) as u8;
                }
                *s = if rng.uniform() < 0.05 {
                    (rng.next_u64() % 4) as u8
                } else {
                    level
                };
            }
            let end = len;
            let p = 1 + (rng.next_u64() % (len as u64 - 1)) as usize;
            let first = (p..end)
                .find(|&q| starts(state[q - 1], state[q], state[q + 1]))
                .unwrap_or(end);
            for avx2 in [false, true] {
                #[cfg(target_arch = "x86_64")]
                if avx2 && !std::arch::is_x86_feature_detected!("avx2") {
                    continue;
                }
                #[cfg(not(target_arch = "x86_64"))]
                if avx2 {
                    continue;
                }
                let quiet = quiet_run(avx2, &state, p, end);
                let stop = p + quiet.pixels;
                assert!(stop <= first, "trial {trial}, avx2 {avx2}");
                // Only a tail shorter than a word is left to the pixel-by-pixel scan.
                assert!(stop == first || end - stop < 8, "trial {trial}");
                let last_marked = (p..stop).rev().find(|&q| state[q] >= MARKED);
                assert_eq!(quiet.last_marked, last_marked, "trial {trial}, avx2 {avx2}");
            }
        }
    }
}
