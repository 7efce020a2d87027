//! Narrow band: the level set function φ stored on the whole grid, plus the
//! list of nodes near its zero set that evolution and reinitialization touch.
//!
//! Nodes outside the band hold ±`half_width` (sign = side of the surface), so
//! every stencil may read any neighbour while all work stays proportional to
//! the band size, i.e. to the surface area.

use surfrecon_grid::sparse::BLOCK;
use surfrecon_grid::{Field, GridSpec};

/// Nodes this close to the grid border never join the band, so stencils
/// (which reach two nodes away for mixed derivatives) need no bounds checks.
pub(crate) const BORDER: usize = 2;

/// φ with its active narrow band.
#[derive(Clone, Debug)]
pub struct NarrowBand<const D: usize> {
    /// φ on every node: signed distance inside the band, ±`half_width` outside.
    pub phi: Field<D>,
    /// Linear indices of the band nodes (|φ| < `half_width`), ascending.
    pub active: Vec<u32>,
    /// Half-width of the band in world units.
    pub half_width: f64,
    /// Per-node stamp used by reinitialization to mark visited nodes
    /// without clearing a whole-grid array each time.
    pub(crate) marks: Vec<u32>,
    pub(crate) epoch: u32,
}

impl<const D: usize> NarrowBand<D> {
    /// A band from inside/outside labels (`true` = inside): φ = ∓`half_width`
    /// everywhere, band = nodes next to a label change. Call
    /// [`crate::reinit::reinitialize`] next to turn it into a signed distance.
    pub fn from_inside(spec: GridSpec<D>, inside: &[bool], half_width: f64) -> Self {
        let values = inside
            .iter()
            .map(|&i| if i { -half_width } else { half_width })
            .collect();
        let phi = Field { spec, values };
        let active = sign_change_nodes(&phi);
        NarrowBand {
            marks: vec![0; spec.node_count()],
            epoch: 0,
            phi,
            active,
            half_width,
        }
    }

    /// A band around the zero set of an arbitrary field (values beyond
    /// `half_width` are clamped); reinitialize before evolving.
    pub fn from_field(mut phi: Field<D>, half_width: f64) -> Self {
        for v in &mut phi.values {
            *v = v.clamp(-half_width, half_width);
        }
        let spec = phi.spec;
        {
            use rayon::prelude::*;
            phi.values.par_iter_mut().enumerate().for_each(|(l, v)| {
                if !is_inner(&spec, l) {
                    *v = half_width;
                }
            });
        }
        let active = sign_change_nodes(&phi);
        NarrowBand {
            marks: vec![0; spec.node_count()],
            epoch: 0,
            phi,
            active,
            half_width,
        }
    }

    /// Number of band nodes.
    pub fn len(&self) -> usize {
        self.active.len()
    }

    /// True when the band is empty (no surface).
    pub fn is_empty(&self) -> bool {
        self.active.is_empty()
    }

    /// Number of blocks of [`surfrecon_grid::sparse::BLOCK`]^D nodes that
    /// hold band nodes: what a sparse block grid would allocate for it.
    pub fn block_count(&self) -> usize {
        let spec = self.phi.spec;
        let block_dims = spec.dims.map(|n| n.div_ceil(BLOCK));
        let mut blocks: Vec<usize> = self
            .active
            .iter()
            .map(|&l| {
                let idx = spec.unlinear(l as usize);
                (0..D)
                    .rev()
                    .fold(0, |b, a| b * block_dims[a] + idx[a] / BLOCK)
            })
            .collect();
        blocks.sort_unstable();
        blocks.dedup();
        blocks.len()
    }
}

/// Inner nodes (at least [`BORDER`] from the grid border) with a neighbour of
/// the other sign, ascending.
pub(crate) fn sign_change_nodes<const D: usize>(phi: &Field<D>) -> Vec<u32> {
    use rayon::prelude::*;
    let spec = phi.spec;
    let strides = spec.strides();
    (0..spec.node_count())
        .into_par_iter()
        .filter(|&l| is_inner(&spec, l) && has_sign_change(&phi.values, l, &strides))
        .map(|l| l as u32)
        .collect()
}

/// Inside means φ ≤ 0 (so a zero value is never ambiguous).
#[inline]
pub(crate) fn inside(v: f64) -> bool {
    v <= 0.0
}

#[inline]
pub(crate) fn has_sign_change<const D: usize>(phi: &[f64], l: usize, strides: &[usize; D]) -> bool {
    let s = inside(phi[l]);
    strides
        .iter()
        .any(|&st| inside(phi[l - st]) != s || inside(phi[l + st]) != s)
}

/// Whether node `l` is far enough from the border for every stencil.
#[inline]
pub(crate) fn is_inner<const D: usize>(spec: &GridSpec<D>, l: usize) -> bool {
    let idx = spec.unlinear(l);
    (0..D).all(|a| idx[a] >= BORDER && idx[a] + BORDER < spec.dims[a])
}

/// Sum of `f` over `items`, in fixed-size chunks summed in order, so the
/// result does not depend on the number of threads.
pub(crate) fn det_sum<T: Sync>(items: &[T], f: impl Fn(&T) -> f64 + Sync) -> f64 {
    use rayon::prelude::*;
    let partial: Vec<f64> = items
        .par_chunks(4096)
        .map(|c| c.iter().map(&f).sum::<f64>())
        .collect();
    partial.iter().sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn band_blocks_follow_the_surface_not_the_grid() {
        // A circle of radius 0.3 in a 161² grid of the unit square.
        let spec = GridSpec::<2> {
            origin: [-0.5, -0.5],
            spacing: 1.0 / 160.0,
            dims: [161, 161],
        };
        let values = (0..spec.node_count())
            .map(|l| {
                let [x, y] = spec.position(spec.unlinear(l));
                x.hypot(y) - 0.3
            })
            .collect();
        let mut band = NarrowBand::from_field(Field { spec, values }, 3.0 * spec.spacing);
        crate::reinit::reinitialize(&mut band);
        let blocks = band.block_count();
        // Circumference 1.9 = 302 cells; a 6-cell wide ring crosses about
        // 302 / 8 · 2 blocks, out of 21² in the grid.
        assert!(band.len() <= blocks * 64);
        assert!((40..=120).contains(&blocks), "{blocks} blocks");
    }
}
