//! Running sums of the adaptive threshold's box filter ([`crate::perception::threshold`]): a
//! row's column sums slid down by one row, and their running (prefix) sums along the row, with
//! AVX2 kernels where the CPU has them (integer sums: the same values, tested).

/// [`running_sums`], with AVX2 when `avx2` (set only by the AVX2 build).
#[inline(always)]
pub(crate) fn row_running_sums(avx2: bool, values: &[u32], out: &mut [u32]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` is only set by the AVX2 build, on a CPU found to have it.
        return unsafe { running_sums_avx2(values, out) };
    }
    let _ = avx2;
    running_sums(values, out)
}

/// Adds the `entering` row to the column sums and takes the `leaving` one off (exact integers:
/// a column's sum holds the leaving row's pixel), then writes their running sums into `out` as
/// [`running_sums`] does; with AVX2 in one pass when `avx2` (set only by the AVX2 build).
#[inline(always)]
pub(crate) fn slide_and_sum(
    avx2: bool,
    column_sums: &mut [u32],
    entering: &[u8],
    leaving: &[u8],
    out: &mut [u32],
) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` is only set by the AVX2 build, on a CPU found to have it.
        return unsafe { slide_and_sum_avx2(column_sums, entering, leaving, out) };
    }
    let _ = avx2;
    slide(column_sums, entering, leaving);
    running_sums(column_sums, out)
}

/// The column sums' update of [`slide_and_sum`].
#[inline]
fn slide(column_sums: &mut [u32], entering: &[u8], leaving: &[u8]) {
    for ((s, &p), &q) in column_sums.iter_mut().zip(entering).zip(leaving) {
        *s = *s + u32::from(p) - u32::from(q);
    }
}

/// [`slide_and_sum`] eight columns at a time: each chunk's sums are updated, stored and scanned
/// as in [`running_sums_avx2`] while in a register. Integer sums: the same values.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn slide_and_sum_avx2(
    column_sums: &mut [u32],
    entering: &[u8],
    leaving: &[u8],
    out: &mut [u32],
) -> u32 {
    use std::arch::x86_64::{
        __m128i, __m256i, _mm_loadl_epi64, _mm256_add_epi32, _mm256_cvtepu8_epi32,
        _mm256_loadu_si256, _mm256_permute2x128_si256, _mm256_permutevar8x32_epi32,
        _mm256_set1_epi32, _mm256_setzero_si256, _mm256_shuffle_epi32, _mm256_slli_si256,
        _mm256_storeu_si256, _mm256_sub_epi32,
    };
    let n = column_sums
        .len()
        .min(entering.len())
        .min(leaving.len())
        .min(out.len());
    let (sums, entering, leaving, out) = (
        &mut column_sums[..n],
        &entering[..n],
        &leaving[..n],
        &mut out[..n],
    );
    let mut carry = _mm256_setzero_si256();
    let mut done = 0;
    while done + 8 <= n {
        let range = done..done + 8;
        // SAFETY: each slice below holds exactly eight elements: 32 bytes of `u32`, 8 of `u8`
        // (a 64-bit load).
        let x = unsafe {
            let s = _mm256_loadu_si256(sums[range.clone()].as_ptr().cast::<__m256i>());
            let p = _mm256_cvtepu8_epi32(_mm_loadl_epi64(
                entering[range.clone()].as_ptr().cast::<__m128i>(),
            ));
            let q = _mm256_cvtepu8_epi32(_mm_loadl_epi64(
                leaving[range.clone()].as_ptr().cast::<__m128i>(),
            ));
            let s = _mm256_sub_epi32(_mm256_add_epi32(s, p), q);
            _mm256_storeu_si256(sums[range.clone()].as_mut_ptr().cast::<__m256i>(), s);
            s
        };
        let mut x = _mm256_add_epi32(x, _mm256_slli_si256::<4>(x));
        x = _mm256_add_epi32(x, _mm256_slli_si256::<8>(x));
        let lane_totals = _mm256_shuffle_epi32::<0xFF>(x);
        x = _mm256_add_epi32(
            x,
            _mm256_permute2x128_si256::<0x08>(lane_totals, lane_totals),
        );
        let running = _mm256_add_epi32(x, carry);
        // SAFETY: `out[range]` holds exactly eight `u32`, an unaligned store's 32 bytes.
        unsafe { _mm256_storeu_si256(out[range].as_mut_ptr().cast::<__m256i>(), running) };
        carry = _mm256_add_epi32(carry, _mm256_permutevar8x32_epi32(x, _mm256_set1_epi32(7)));
        done += 8;
    }
    slide(&mut sums[done..], &entering[done..], &leaving[done..]);
    let mut running = if done > 0 { out[done - 1] } else { 0 };
    for (o, &v) in out[done..].iter_mut().zip(&sums[done..]) {
        running = running.wrapping_add(v);
        *o = running;
    }
    running
}

/// Running (inclusive, wrapping) sums of `values` into `out`, of the same length; returns the
/// total.
#[inline]
fn running_sums(values: &[u32], out: &mut [u32]) -> u32 {
    let mut running = 0u32;
    for (o, &v) in out.iter_mut().zip(values) {
        running = running.wrapping_add(v);
        *o = running;
    }
    running
}

/// [`running_sums`], eight at a time: a log-step scan inside each 128-bit lane, the low lane's
/// total added to the high one, then the sum of all before. Integer sums: the same values.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn running_sums_avx2(values: &[u32], out: &mut [u32]) -> u32 {
    use std::arch::x86_64::{
        __m256i, _mm256_add_epi32, _mm256_loadu_si256, _mm256_permute2x128_si256,
        _mm256_permutevar8x32_epi32, _mm256_set1_epi32, _mm256_setzero_si256, _mm256_shuffle_epi32,
        _mm256_slli_si256, _mm256_storeu_si256,
    };
    let n = values.len().min(out.len());
    let (values, out) = (&values[..n], &mut out[..n]);
    let mut carry = _mm256_setzero_si256();
    let mut chunks = out.chunks_exact_mut(8);
    for (o, v) in (&mut chunks).zip(values.chunks_exact(8)) {
        // SAFETY: `v` holds exactly eight `u32`, an unaligned load's 32 bytes.
        let mut x = unsafe { _mm256_loadu_si256(v.as_ptr().cast::<__m256i>()) };
        x = _mm256_add_epi32(x, _mm256_slli_si256::<4>(x));
        x = _mm256_add_epi32(x, _mm256_slli_si256::<8>(x));
        // Element 3 (the low lane's total) into the high lane, zeros into the low one.
        let lane_totals = _mm256_shuffle_epi32::<0xFF>(x);
        x = _mm256_add_epi32(
            x,
            _mm256_permute2x128_si256::<0x08>(lane_totals, lane_totals),
        );
        let sums = _mm256_add_epi32(x, carry);
        // SAFETY: `o` holds exactly eight `u32`, an unaligned store's 32 bytes.
        unsafe { _mm256_storeu_si256(o.as_mut_ptr().cast::<__m256i>(), sums) };
        // The chunk's own total is broadcast off the carry's chain: one add a chunk on it.
        carry = _mm256_add_epi32(carry, _mm256_permutevar8x32_epi32(x, _mm256_set1_epi32(7)));
    }
    let done = n - chunks.into_remainder().len();
    let mut running = if done > 0 { out[done - 1] } else { 0 };
    for (o, &v) in out[done..].iter_mut().zip(&values[done..]) {
        running = running.wrapping_add(v);
        *o = running;
    }
    running
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn both_builds_of_the_running_sums_agree(
            values in proptest::collection::vec(any::<u32>(), 0..70)
        ) {
            let mut scalar = vec![0u32; values.len()];
            let total = running_sums(&values, &mut scalar);
            prop_assert_eq!(total, scalar.last().copied().unwrap_or(0));
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                let mut wide = vec![0u32; values.len()];
                // SAFETY: the CPU has AVX2 (checked above).
                let wide_total = unsafe { running_sums_avx2(&values, &mut wide) };
                prop_assert_eq!(&wide, &scalar);
                prop_assert_eq!(wide_total, total);
            }
        }

        #[test]
        fn both_builds_of_the_sliding_sums_agree(
            rows in proptest::collection::vec((any::<u8>(), any::<u8>(), 0u32..1_000_000), 0..70)
        ) {
            // Column sums that hold the leaving row's pixel, as in the threshold's window.
            let entering: Vec<u8> = rows.iter().map(|r| r.0).collect();
            let leaving: Vec<u8> = rows.iter().map(|r| r.1).collect();
            let start: Vec<u32> = rows.iter().map(|r| r.2 + u32::from(r.1)).collect();
            let (mut scalar_sums, mut scalar) = (start.clone(), vec![0u32; rows.len()]);
            let total = slide_and_sum(false, &mut scalar_sums, &entering, &leaving, &mut scalar);
            prop_assert_eq!(total, scalar.last().copied().unwrap_or(0));
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                let (mut wide_sums, mut wide) = (start.clone(), vec![0u32; rows.len()]);
                // SAFETY: the CPU has AVX2 (checked above).
                let wide_total =
                    unsafe { slide_and_sum_avx2(&mut wide_sums, &entering, &leaving, &mut wide) };
                prop_assert_eq!(&wide_sums, &scalar_sums);
                prop_assert_eq!(&wide, &scalar);
                prop_assert_eq!(wide_total, total);
            }
        }
    }
}
