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

/// Rounds smaller than this are merged into the first one.
const FIRST_ROUND_MIN: usize = 256;

/// Indices of `points` in BRIO order: shuffled (fixed seed, so a run is
/// reproducible), split into rounds of doubling size (the last round holds
/// half of the points), each round sorted along the Hilbert curve through
/// the points' bounding box.
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
    let mut end = packed.len();
    while end > 0 {
        let start = if end / 2 < FIRST_ROUND_MIN {
            0
        } else {
            end / 2
        };
        packed[start..end].sort_unstable();
        end = start;
    }
    packed.iter().map(|&k| k as u32).collect()
}

/// Hilbert key of every point, on a 2^10 grid over the bounding box.
fn hilbert_keys(points: &[DVec3]) -> Vec<u64> {
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
    points
        .iter()
        .map(|&p| {
            let q = ((p - lo) * scale).clamp(DVec3::ZERO, DVec3::splat(cells - 1.0));
            hilbert_index([q.x as u32, q.y as u32, q.z as u32], HILBERT_BITS)
        })
        .collect()
}

/// Position of the cell `x` (each coordinate below 2^bits) along the 3D
/// Hilbert curve, following Skilling's transpose formulation ("Programming
/// the Hilbert curve", 2004): undo the curve's rotations and reflections
/// level by level, Gray-decode, then interleave the bits.
pub fn hilbert_index(mut x: [u32; 3], bits: u32) -> u64 {
    let top = 1u32 << (bits - 1);
    let mut q = top;
    while q > 1 {
        let low = q - 1;
        for i in 0..3 {
            if x[i] & q != 0 {
                x[0] ^= low;
            } else {
                let t = (x[0] ^ x[i]) & low;
                x[0] ^= t;
                x[i] ^= t;
            }
        }
        q >>= 1;
    }
    x[1] ^= x[0];
    x[2] ^= x[1];
    let mut t = 0;
    let mut q = top;
    while q > 1 {
        if x[2] & q != 0 {
            t ^= q - 1;
        }
        q >>= 1;
    }
    for xi in &mut x {
        *xi ^= t;
    }
    let mut key = 0u64;
    for b in (0..bits).rev() {
        for xi in x {
            key = (key << 1) | ((xi >> b) & 1) as u64;
        }
    }
    key
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
