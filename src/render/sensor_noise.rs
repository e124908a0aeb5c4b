//! The sensor noise's unit normal deviates, fast: a quantile table read with random bits,
//! exact tails.

use std::sync::OnceLock;

use crate::rng::SimRng;

/// Bits of a random word that pick a bin of the normal: 4096 equiprobable bins.
const BIN_BITS: u32 = 12;
/// Bits of a random word that pick one of a bin's evenly spaced values.
const PLACE_BITS: u32 = 4;
/// Bits per deviate: four deviates per 64-bit random word.
const DRAW_BITS: u32 = BIN_BITS + PLACE_BITS;
/// Bins of the normal's quantile table.
const BINS: usize = 1 << BIN_BITS;
/// Bins at each end whose deviates are drawn exactly from the tail beyond them (|z| > 2.66):
/// there the density changes too fast across a bin to be taken as flat.
const TAIL_BINS: usize = 16;
/// Table entries: each bin's values.
const ENTRIES: usize = BINS << PLACE_BITS;
/// The first entry past the lower tail bins, and the number of entries between the tails.
const INNER_START: usize = TAIL_BINS << PLACE_BITS;
const INNER_ENTRIES: usize = ENTRIES - 2 * INNER_START;

/// Unit normal deviates, fast: 16 random bits pick an entry of a table that holds, for each of
/// 4096 equiprobable bins of the normal, 16 values evenly spaced across the bin (at the middles
/// of its sixteenths): one table read per deviate, four deviates per random word, no
/// transcendental function. The outer 16 bins at each end (probability 0.8 %) draw exactly from
/// the tail beyond them (Marsaglia's tail method), so no value is out of reach. Flat within a
/// bin is the only approximation: the density changes by at most 6 % across an inner bin, and
/// the variance comes out within 1e-5 of one.
pub(super) struct FastNormal {
    rng: SimRng,
    table: &'static [f32; ENTRIES],
}

impl FastNormal {
    /// Deviates from the stream seeded with `seed`.
    pub(super) fn new(seed: u64) -> Self {
        Self {
            rng: SimRng::new(seed),
            table: unit_table(),
        }
    }

    /// Fills `out` with unit deviates, four from each random word.
    ///
    /// The four table reads of a word are unconditional (a tail entry reads a placeholder);
    /// only a word with a tail entry among its four (3 % of words, found from the word's bits
    /// at once) then draws its tails, in the same order as one deviate at a time would.
    #[inline(always)]
    pub(super) fn fill(&mut self, out: &mut [f32]) {
        const PER_WORD: usize = (64 / DRAW_BITS) as usize;
        let (table, rng) = (self.table, &mut self.rng);
        let mut chunks = out.chunks_exact_mut(PER_WORD);
        for chunk in &mut chunks {
            let word = rng.next_u64();
            for (i, value) in chunk.iter_mut().enumerate() {
                *value = table[(word >> (i as u32 * DRAW_BITS)) as usize & (ENTRIES - 1)];
            }
            if has_tail_entry(word) {
                for (i, value) in chunk.iter_mut().enumerate() {
                    let entry = (word >> (i as u32 * DRAW_BITS)) as usize & (ENTRIES - 1);
                    *value = deviate(table, rng, entry);
                }
            }
        }
        for value in chunks.into_remainder() {
            let entry = rng.next_u64() as usize & (ENTRIES - 1);
            *value = deviate(table, rng, entry);
        }
    }
}

/// Whether any of the four 16-bit entries of `word` falls in a tail bin, whose high byte is 0
/// (the lower tail: entries below 16 x 16) or 255 (the upper). All four at once on the word's
/// bits: a high byte `h` plus one, with its lowest bit and its carry out masked off, is zero
/// exactly for 0 and 255; then a lane is zero where subtracting one borrows into its top bit.
#[inline(always)]
fn has_tail_entry(word: u64) -> bool {
    const _: () = assert!(DRAW_BITS == 16 && INNER_START == 1 << 8);
    const ONES: u64 = 0x0001_0001_0001_0001;
    const TOPS: u64 = 0x8000_8000_8000_8000;
    const HIGH_BYTES: u64 = 0x00ff_00ff_00ff_00ff;
    const EVEN_BYTES: u64 = 0x00fe_00fe_00fe_00fe;
    let t = (((word >> 8) & HIGH_BYTES) + ONES) & EVEN_BYTES;
    t.wrapping_sub(ONES) & !t & TOPS != 0
}

/// The deviate that table entry `entry` picks; a tail entry draws from `rng`.
#[inline(always)]
fn deviate(table: &[f32; ENTRIES], rng: &mut SimRng, entry: usize) -> f32 {
    if entry.wrapping_sub(INNER_START) < INNER_ENTRIES {
        table[entry & (ENTRIES - 1)]
    } else {
        let tail = normal_tail(rng, tail_edge()) as f32;
        if entry < INNER_START { -tail } else { tail }
    }
}

/// The table of [`FastNormal`]: entry `bin * 16 + k` is the middle of the `k`-th sixteenth of
/// the bin (entries of the tail bins are never read).
fn unit_table() -> &'static [f32; ENTRIES] {
    static TABLE: OnceLock<Box<[f32; ENTRIES]>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let edges = unit_edges();
        let places = 1usize << PLACE_BITS;
        let mut table = Box::new([0.0f32; ENTRIES]);
        for (bin, values) in table.chunks_exact_mut(places).enumerate() {
            if !(TAIL_BINS..BINS - TAIL_BINS).contains(&bin) {
                continue;
            }
            let (low, high) = (edges[bin], edges[bin + 1]);
            for (k, value) in values.iter_mut().enumerate() {
                *value = (low + (k as f64 + 0.5) / places as f64 * (high - low)) as f32;
            }
        }
        table
    })
}

/// The unit normal's quantiles at `i / BINS` for every `i` in `0..=BINS` (the outer ones
/// infinite; the tail bins never read theirs).
fn unit_edges() -> &'static [f64; BINS + 1] {
    static TABLE: OnceLock<[f64; BINS + 1]> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut table = [0.0; BINS + 1];
        for (i, q) in table.iter_mut().enumerate() {
            *q = match i {
                0 => f64::NEG_INFINITY,
                BINS => f64::INFINITY,
                _ => normal_quantile(i as f64 / BINS as f64),
            };
        }
        table
    })
}

/// Where the tail bins begin: the unit normal's quantile at `1 - TAIL_BINS / BINS`.
fn tail_edge() -> f64 {
    static EDGE: OnceLock<f64> = OnceLock::new();
    *EDGE.get_or_init(|| -normal_quantile(TAIL_BINS as f64 / BINS as f64))
}

/// A unit normal deviate conditioned on exceeding `edge` > 0 (Marsaglia's tail method: exact).
fn normal_tail(rng: &mut SimRng, edge: f64) -> f64 {
    loop {
        let a = -(1.0 - rng.uniform()).ln() / edge;
        let b = -(1.0 - rng.uniform()).ln();
        if 2.0 * b > a * a {
            return edge + a;
        }
    }
}

/// The unit normal's quantile function, by Acklam's rational approximation (relative error
/// below 1.2e-9, far finer than any bin), for `p` in (0, 1).
fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    const LOW: f64 = 0.024_25;
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < LOW {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - LOW {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_word_has_a_tail_entry_exactly_when_one_of_its_four_is_in_a_tail_bin() {
        let tail =
            |entry: u64| !(INNER_START as u64..(ENTRIES - INNER_START) as u64).contains(&entry);
        let mut rng = SimRng::new(5);
        // Random words, and words built from entries at and next to the tails' edges.
        let edges = [
            0u64, 1, 255, 256, 257, 0x7fff, 0xfeff, 0xff00, 0xff01, 0xffff,
        ];
        let mut words: Vec<u64> = (0..100_000).map(|_| rng.next_u64()).collect();
        for _ in 0..20_000 {
            let lanes = rng.next_u64();
            words.push((0..4).fold(0, |w, i| {
                let entry = edges[((lanes >> (8 * i)) % edges.len() as u64) as usize];
                w | entry << (16 * i)
            }));
        }
        for word in words {
            let expected = (0..4).any(|i| tail((word >> (16 * i)) & 0xffff));
            assert_eq!(has_tail_entry(word), expected, "{word:016x}");
        }
    }

    #[test]
    fn the_bins_make_a_unit_normal() {
        let edges = unit_edges();
        let edge = tail_edge();
        assert!((normal_quantile(0.975) - 1.959_963_984_540_054).abs() < 1e-8);
        assert!((edge - 2.660_067_468_617_458).abs() < 1e-6, "{edge}");
        // Second moment of the flat bins, plus the exact tails':
        // E[z^2 | z > a] = 1 + a phi(a) / (1 - Phi(a)).
        let n = BINS as f64;
        let inner: f64 = edges[TAIL_BINS..=BINS - TAIL_BINS]
            .windows(2)
            .map(|e| (e[0] * e[0] + e[0] * e[1] + e[1] * e[1]) / 3.0 / n)
            .sum();
        let share = TAIL_BINS as f64 / n;
        let phi = (-0.5 * edge * edge).exp() / std::f64::consts::TAU.sqrt();
        let variance = inner + 2.0 * share * (1.0 + edge * phi / share);
        assert!((variance - 1.0).abs() < 1e-5, "variance {variance}");
    }
}
