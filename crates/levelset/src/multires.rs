//! Multiresolution: solve on coarser grids first, interpolate φ to the next
//! finer grid and continue there with few steps. The coarse grids cost a
//! fraction of the fine one (1/2^dim per level) yet do most of the motion.

use rayon::prelude::*;
use surfrecon_grid::{Field, GridSpec};

/// Grids larger than this (nodes along the longest axis) get a coarse level.
pub const COARSEN_ABOVE: usize = 160;

/// Number of levels for a fine grid: one more per halving needed to bring
/// the longest axis to at most [`COARSEN_ABOVE`] nodes, at most 3.
pub fn auto_levels<const D: usize>(dims: &[usize; D]) -> usize {
    let mut longest = dims.iter().copied().max().unwrap_or(1);
    let mut levels = 1;
    while longest > COARSEN_ABOVE && levels < 3 {
        longest = longest.div_ceil(2);
        levels += 1;
    }
    levels
}

/// The grid with `factor` times the spacing over the same region (same
/// origin, covering at least the fine grid).
pub fn coarsen<const D: usize>(fine: &GridSpec<D>, factor: usize) -> GridSpec<D> {
    GridSpec {
        origin: fine.origin,
        spacing: fine.spacing * factor as f64,
        dims: std::array::from_fn(|a| ((fine.dims[a] - 1).div_ceil(factor) + 1).max(2)),
    }
}

/// Multilinear interpolation of `coarse` at the nodes of `fine` (positions
/// outside the coarse grid take the nearest boundary value).
pub fn upsample<const D: usize>(coarse: &Field<D>, fine: GridSpec<D>) -> Field<D> {
    let values = (0..fine.node_count())
        .into_par_iter()
        .map(|l| interpolate(coarse, fine.position(fine.unlinear(l))))
        .collect();
    Field { spec: fine, values }
}

/// Multilinear interpolation of `field` at world position `p`.
pub fn interpolate<const D: usize>(field: &Field<D>, p: [f64; D]) -> f64 {
    let spec = &field.spec;
    let g = spec.to_grid(p);
    let mut base = [0usize; D];
    let mut t = [0.0; D];
    for a in 0..D {
        let x = g[a].clamp(0.0, (spec.dims[a] - 1) as f64);
        let i = (x.floor() as usize).min(spec.dims[a] - 2);
        base[a] = i;
        t[a] = x - i as f64;
    }
    let strides = spec.strides();
    let l0 = spec.linear(base);
    let mut sum = 0.0;
    for corner in 0..1usize << D {
        let mut w = 1.0;
        let mut l = l0;
        for a in 0..D {
            if corner >> a & 1 == 1 {
                w *= t[a];
                l += strides[a];
            } else {
                w *= 1.0 - t[a];
            }
        }
        sum += w * field.values[l];
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_functions_upsample_exactly() {
        let fine = GridSpec::<3> {
            origin: [0.5, -1.0, 2.0],
            spacing: 0.1,
            dims: [21, 17, 10],
        };
        let coarse = coarsen(&fine, 2);
        assert!(coarse
            .max_corner()
            .iter()
            .zip(fine.max_corner())
            .all(|(c, f)| *c >= f - 1e-12));
        let f = |p: [f64; 3]| 2.0 * p[0] - p[1] + 0.5 * p[2] + 1.0;
        let cf = Field {
            spec: coarse,
            values: (0..coarse.node_count())
                .map(|l| f(coarse.position(coarse.unlinear(l))))
                .collect(),
        };
        let up = upsample(&cf, fine);
        for l in 0..fine.node_count() {
            let want = f(fine.position(fine.unlinear(l)));
            assert!((up.values[l] - want).abs() < 1e-9);
        }
    }

    #[test]
    fn levels_grow_with_grid_size() {
        assert_eq!(auto_levels(&[100, 80, 60]), 1);
        assert_eq!(auto_levels(&[300, 212, 136]), 2);
        assert_eq!(auto_levels(&[1000, 10]), 3);
    }
}
