//! Insertion order: biased randomized insertion order (BRIO) with each round
//! sorted along a Hilbert curve.
//!
//! Random rounds keep the expected cost of incremental insertion optimal
//! (no adversarial order builds huge cavities); sorting within a round makes
//! consecutive points close, so the walk from the last created tetrahedron
//! is short and the memory it touches is warm.

use glam::DVec3;
use rand::seq::SliceRandom;
use rand::SeedableRng;

/// Bits per axis of the Hilbert keys: 3 × 10 = 30-bit keys, a billion
/// cells, far finer than needed to order millions of points, and cheap.
const HILBERT_BITS: u32 = 10;

/// Each round holds this many times the points of all earlier rounds,
/// less one (the last holds 7/8 of the points), the ratio of CGAL's
/// multiscale sort. Each round's pass along the curve meets the earlier
/// rounds' tetrahedra cold in cache; with doubling rounds (12 for a
/// million points, 4 now) that cost a fifth more L1 misses, and about 5 %
/// more build time.
const ROUND_RATIO: usize = 8;

/// Rounds smaller than this are merged into the first one.
const FIRST_ROUND_MIN: usize = 256;

/// Indices of `points` in BRIO order: shuffled (fixed seed, so a run is
/// reproducible), split into rounds growing by [`ROUND_RATIO`] (the last
/// round holds 7/8 of the points), each round sorted along the Hilbert
/// curve through the points' bounding box.
pub fn brio_order(points: &[DVec3]) -> Vec<u32> {
    let mut order: Vec<u32> = (0..points.len() as u32).collect();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(0x5eed_de1a_0a11);
    order.shuffle(&mut rng);
    // Key in the high half, index in the low half: sorting plain integers
    // is much faster than sorting indices by a looked-up key.
    let keys = hilbert_keys(points);
    let mut packed: Vec<u64> = order
        .iter()
        .map(|&i| (keys[i as usize] << 32) | i as u64)
        .collect();
    let mut buffer = vec![0u64; packed.len()];
    let mut end = packed.len();
    while end > 0 {
        let start = if end / ROUND_RATIO < FIRST_ROUND_MIN {
            0
        } else {
            end / ROUND_RATIO
        };
        radix_sort_keys(&mut packed[start..end], &mut buffer[start..end]);
        end = start;
    }
    packed.iter().map(|&k| k as u32).collect()
}

/// Sort `values` (a key below 2^30 in bits 32.., distinct values) into
/// the order `sort_unstable` gives, several times faster on a million: an
/// LSD radix sort on the key (three passes of 10 bits), then the rare runs
/// of equal keys by the whole value. `buffer` is scratch of the same length.
fn radix_sort_keys(values: &mut [u64], buffer: &mut [u64]) {
    const BITS: u32 = 10;
    const BUCKETS: usize = 1 << BITS;
    let digit = |v: u64, pass: u32| ((v >> (32 + pass * BITS)) as usize) & (BUCKETS - 1);
    let (mut from, mut to) = (values, buffer);
    for pass in 0..3 {
        let mut start = [0usize; BUCKETS];
        for &v in from.iter() {
            start[digit(v, pass)] += 1;
        }
        let mut sum = 0;
        for s in &mut start {
            let count = *s;
            *s = sum;
            sum += count;
        }
        for &v in from.iter() {
            let d = digit(v, pass);
            to[start[d]] = v;
            start[d] += 1;
        }
        std::mem::swap(&mut from, &mut to);
    }
    // Three passes: the sorted values are in the buffer.
    to.copy_from_slice(from);
    // Equal keys (duplicate points, or points in one grid cell) in index
    // order, as a sort of the whole values would put them: that fixes
    // which duplicate is kept and the perturbation order.
    for run in values_with_equal_keys(to) {
        run.sort_unstable();
    }
}

/// The runs of two or more consecutive values with the same key.
fn values_with_equal_keys(values: &mut [u64]) -> impl Iterator<Item = &mut [u64]> {
    values
        .chunk_by_mut(|a, b| a >> 32 == b >> 32)
        .filter(|run| run.len() > 1)
}

/// Hilbert key of every point, on a 2^10 grid over the bounding box.
pub fn hilbert_keys(points: &[DVec3]) -> Vec<u64> {
    let (lo, hi) = points.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    );
    let cells = (1u64 << HILBERT_BITS) as f64;
    // One scale for all axes keeps the curve's cells cubic.
    let extent = (hi - lo).max_element();
    let scale = if extent > 0.0 {
        (cells - 1.0) / extent
    } else {
        0.0
    };
    let cell = |p: DVec3| {
        let q = ((p - lo) * scale).clamp(DVec3::ZERO, DVec3::splat(cells - 1.0));
        [q.x as u32, q.y as u32, q.z as u32]
    };
    let mut keys = Vec::with_capacity(points.len());
    let mut chunks = points.chunks_exact(LANES);
    for chunk in &mut chunks {
        let mut x = [[0u32; LANES]; 3];
        for (lane, &p) in chunk.iter().enumerate() {
            let c = cell(p);
            for axis in 0..3 {
                x[axis][lane] = c[axis];
            }
        }
        keys.extend(hilbert_index_lanes(x, HILBERT_BITS));
    }
    keys.extend(
        chunks
            .remainder()
            .iter()
            .map(|&p| hilbert_index(cell(p), HILBERT_BITS)),
    );
    keys
}

/// Points whose Hilbert keys are computed together: the computation is a
/// long dependent chain per point, so independent lanes keep the
/// processor busy (and vectorize).
const LANES: usize = 8;

/// Position of the cell `x` (each coordinate below 2^bits) along the 3D
/// Hilbert curve, following Skilling's transpose formulation ("Programming
/// the Hilbert curve", 2004): undo the curve's rotations and reflections
/// level by level, Gray-decode, then interleave the bits.
pub fn hilbert_index(x: [u32; 3], bits: u32) -> u64 {
    hilbert_index_lanes(x.map(|c| [c]), bits)[0]
}

/// [`hilbert_index`] of `L` cells at once: `x[axis][lane]`.
// Each lane index reads and writes two rows (x[0] and x[i]), which
// iterators over one row cannot express.
#[allow(clippy::needless_range_loop)]
fn hilbert_index_lanes<const L: usize>(mut x: [[u32; L]; 3], bits: u32) -> [u64; L] {
    // Branch-free: the bit tested at each level is as good as random, so
    // both arms are computed and a mask selects one.
    let top = 1u32 << (bits - 1);
    let mut q = top;
    while q > 1 {
        let low = q - 1;
        for i in 0..3 {
            for l in 0..L {
                let set = 0u32.wrapping_sub(u32::from(x[i][l] & q != 0));
                // Bit set: invert the low bits of x[0]; clear: exchange
                // the low bits of x[0] and x[i].
                x[0][l] ^= low & set;
                let t = (x[0][l] ^ x[i][l]) & low & !set;
                x[0][l] ^= t;
                x[i][l] ^= t;
            }
        }
        q >>= 1;
    }
    let mut keys = [0u64; L];
    for l in 0..L {
        x[1][l] ^= x[0][l];
        x[2][l] ^= x[1][l];
        let mut t = 0;
        let mut q = top;
        while q > 1 {
            t ^= (q - 1) & 0u32.wrapping_sub(u32::from(x[2][l] & q != 0));
            q >>= 1;
        }
        let [a, b, c] = [x[0][l] ^ t, x[1][l] ^ t, x[2][l] ^ t];
        // Interleave, most significant level first, x[0] highest in each.
        keys[l] = (spread_bits(a) << 2) | (spread_bits(b) << 1) | spread_bits(c);
    }
    keys
}

/// Bit `b` of `x` (below 2^21) moved to bit `3 b`.
fn spread_bits(x: u32) -> u64 {
    let mut v = u64::from(x) & 0x1f_ffff;
    v = (v | (v << 32)) & 0x1f_0000_0000_ffff;
    v = (v | (v << 16)) & 0x1f_0000_ff00_00ff;
    v = (v | (v << 8)) & 0x100f_00f0_0f00_f00f;
    v = (v | (v << 4)) & 0x10c3_0c30_c30c_30c3;
    v = (v | (v << 2)) & 0x1249_2492_4924_9249;
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The curve visits every cell of an 8³ grid once, moving to a face
    /// neighbour at each step.
    #[test]
    fn hilbert_curve_is_a_continuous_bijection() {
        let bits = 3;
        let n = 1u32 << bits;
        let mut cells = Vec::new();
        for x in 0..n {
            for y in 0..n {
                for z in 0..n {
                    cells.push((hilbert_index([x, y, z], bits), [x, y, z]));
                }
            }
        }
        cells.sort();
        for (i, (key, _)) in cells.iter().enumerate() {
            assert_eq!(*key, i as u64);
        }
        for w in cells.windows(2) {
            let (a, b) = (w[0].1, w[1].1);
            let step: u32 = (0..3).map(|k| a[k].abs_diff(b[k])).sum();
            assert_eq!(step, 1, "{a:?} -> {b:?}");
        }
    }

    /// Lanes give the same keys as one cell at a time.
    #[test]
    fn hilbert_lanes_agree() {
        let cells: Vec<[u32; 3]> = (0..LANES as u32)
            .map(|i| [i * 97 % 1024, i * 389 % 1024, i * 733 % 1024])
            .collect();
        let mut x = [[0u32; LANES]; 3];
        for (l, c) in cells.iter().enumerate() {
            for axis in 0..3 {
                x[axis][l] = c[axis];
            }
        }
        let keys = hilbert_index_lanes(x, 10);
        for (l, &c) in cells.iter().enumerate() {
            assert_eq!(keys[l], hilbert_index(c, 10));
        }
    }

    #[test]
    fn spread_bits_matches_a_loop() {
        for x in [0u32, 1, 2, 3, 0x155, 0x3ff, 0x1f_ffff, 0x12_3456] {
            let mut expected = 0u64;
            for b in 0..21 {
                expected |= u64::from((x >> b) & 1) << (3 * b);
            }
            assert_eq!(spread_bits(x), expected, "{x:#x}");
        }
    }

    #[test]
    fn radix_sort_equals_a_full_sort() {
        let mut state = 7u64;
        let mut values: Vec<u64> = (0..10_000u64)
            .map(|i| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1);
                ((state >> 40) % 5000) << 32 | i
            })
            .collect();
        values.reverse();
        let mut expected = values.clone();
        expected.sort_unstable();
        let mut buffer = vec![0; values.len()];
        radix_sort_keys(&mut values, &mut buffer);
        assert_eq!(values, expected);
    }

    #[test]
    fn brio_order_is_a_permutation() {
        let points: Vec<DVec3> = (0..5000)
            .map(|i| DVec3::new((i % 17) as f64, (i % 31) as f64, (i % 7) as f64))
            .collect();
        let mut order = brio_order(&points);
        order.sort_unstable();
        assert!(order.iter().enumerate().all(|(i, &v)| v == i as u32));
    }
}
