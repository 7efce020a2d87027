//! A fast hasher for the hash maps and sets of grid nodes and point
//! coordinates that the serial steps build (hundreds of thousands of keys
//! each): std's SipHash cost more than the rest of those steps. Only
//! lookups are made in them, never iteration, so the hasher cannot change
//! a result.

use std::collections::{HashMap, HashSet};
use std::hash::{BuildHasherDefault, Hasher};

/// A `HashMap` with [`MixHasher`].
pub(crate) type FastMap<K, V> = HashMap<K, V, BuildHasherDefault<MixHasher>>;
/// A `HashSet` with [`MixHasher`].
pub(crate) type FastSet<K> = HashSet<K, BuildHasherDefault<MixHasher>>;

/// Multiply-rotate over 64-bit words, then the SplitMix64 finaliser so
/// that every bit of the keys reaches the bits the table uses.
#[derive(Clone, Copy, Default)]
pub(crate) struct MixHasher(u64);

impl Hasher for MixHasher {
    fn finish(&self) -> u64 {
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(word));
        }
    }

    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(5) ^ x).wrapping_mul(0x517c_c1b7_2722_0a95);
    }

    fn write_usize(&mut self, x: usize) {
        self.write_u64(x as u64);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maps_find_every_key_and_nothing_else() {
        let keys: Vec<[i64; 3]> = (0..20_000i64).map(|i| [i % 37, i / 37, -i]).collect();
        let set: FastSet<[i64; 3]> = keys.iter().copied().collect();
        assert_eq!(set.len(), keys.len());
        assert!(keys.iter().all(|k| set.contains(k)));
        assert!(!set.contains(&[0, 0, 1]));
        let map: FastMap<usize, usize> = (0..50_000).map(|i| (i * 4096, i)).collect();
        assert!((0..50_000).all(|i| map.get(&(i * 4096)) == Some(&i)));
        assert_eq!(map.get(&1), None);
    }

    #[test]
    fn nearby_keys_spread_over_the_low_bits() {
        // Grid node indices differ in a few low or high bits; the table
        // takes its bucket from the low bits of the hash.
        let hash = |k: usize| {
            let mut h = MixHasher::default();
            h.write_usize(k);
            h.finish()
        };
        for stride in [1usize, 512, 1 << 20] {
            let buckets: FastSet<u64> = (0..1024).map(|i| hash(i * stride) & 1023).collect();
            assert!(
                buckets.len() > 550,
                "stride {stride}: {} buckets",
                buckets.len()
            );
        }
    }
}
