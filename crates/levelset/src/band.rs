//! Narrow band: the level set function φ on the sparse block grid
//! ([`BlockGrid`]), plus the list of nodes near its zero set that evolution
//! and reinitialization touch.
//!
//! Only blocks of [`BLOCK`]^D nodes that hold band nodes are allocated;
//! every other block is a tile holding ±`half_width` (sign = side of the
//! surface). So every stencil may read any neighbour, all work is per band
//! node, and memory follows the surface area, not the grid volume.
//!
//! Band nodes are named by *keys*: the block's index into
//! [`BlockGrid::blocks`] shifted above the node's index inside the block.
//! Neighbours inside a block are a key ± a constant; across a block border
//! one look-up in the block table. The evolution's stencils run on dense
//! per-block windows ([`NarrowBand::map_active`]), so they keep the plain
//! slice-and-stride form of a dense grid.

use crate::error::Result;
use rayon::prelude::*;
use std::sync::Arc;
use surfrecon_grid::sparse::{Block, BlockGrid, BLOCK};
use surfrecon_grid::{Field, GridSpec};

/// Nodes this close to the grid border never join the band, so stencils
/// (which reach one node away along up to two axes) need no bounds checks.
pub(crate) const BORDER: usize = 2;

/// Bits of a key below the block index: log2(BLOCK) per axis.
const AXIS_BITS: usize = BLOCK.trailing_zeros() as usize;

/// φ with its active narrow band.
#[derive(Clone, Debug)]
pub struct NarrowBand<const D: usize> {
    /// φ: signed distance inside the band, ±`half_width` elsewhere (tiles
    /// and the allocated blocks' nodes outside the band).
    pub phi: BlockGrid<D>,
    /// Keys of the band nodes (|φ| < `half_width`), ascending: block by
    /// block, in the order of [`BlockGrid::blocks`].
    pub active: Vec<u32>,
    /// Half-width of the band in world units.
    pub half_width: f64,
    /// Per allocated node (key order): stamp used by reinitialization to
    /// mark visited nodes without clearing the array each time.
    pub(crate) marks: Vec<u32>,
    pub(crate) epoch: u32,
    /// Per block with band nodes: its index and its range in `active`.
    pub(crate) runs: Vec<(u32, std::ops::Range<usize>)>,
}

/// A node's neighbour: an allocated node (by key) or a tile's value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Step {
    Node(u32),
    Tile(f64),
}

/// What a per-node computation of [`NarrowBand::map_active`] sees: dense
/// windows of φ (and d) around the node's block, indexed like a dense grid.
pub(crate) struct Stencil<'a, const D: usize> {
    pub phi: &'a [f64],
    /// Empty when no distance was asked for.
    pub d: &'a [f64],
    /// Window index of the node.
    pub at: usize,
    /// Position of the node in the band list (for per-node data kept
    /// beside it).
    pub index: usize,
    pub strides: &'a [usize; D],
    /// Global node index.
    pub node: [usize; D],
    /// Global index of the block's first node (window coordinates 1).
    pub corner: [usize; D],
}

impl<const D: usize> NarrowBand<D> {
    /// Nodes per block.
    pub(crate) const LEN: usize = Block::<D>::LEN;
    const LOCAL_BITS: u32 = (AXIS_BITS * D) as u32;

    /// A band from inside/outside labels (`true` = inside): φ = ∓`half_width`
    /// everywhere, band = nodes next to a label change. Call
    /// [`crate::reinit::reinitialize`] next to turn it into a signed distance.
    pub fn from_inside(spec: GridSpec<D>, inside: &[bool], half_width: f64) -> Result<Self> {
        let values = inside
            .iter()
            .map(|&i| if i { -half_width } else { half_width })
            .collect();
        Self::from_dense(&Field { spec, values }, half_width)
    }

    /// A band around the zero set of an arbitrary field (values beyond
    /// `half_width` are clamped, nodes at the border set outside);
    /// reinitialize before evolving.
    pub fn from_field(mut phi: Field<D>, half_width: f64) -> Result<Self> {
        let spec = phi.spec;
        phi.values.par_iter_mut().enumerate().for_each(|(l, v)| {
            *v = if is_inner(&spec, spec.unlinear(l)) {
                v.clamp(-half_width, half_width)
            } else {
                half_width
            };
        });
        Self::from_dense(&phi, half_width)
    }

    /// The blocks of `field` with a value inside the band or a sign change,
    /// tiles elsewhere.
    fn from_dense(field: &Field<D>, half_width: f64) -> Result<Self> {
        let mut grid = BlockGrid::from_dense_band(field, half_width)?;
        let spec = field.spec;
        let strides = spec.strides();
        let changes: Vec<usize> = (0..spec.node_count())
            .into_par_iter()
            .filter(|&l| {
                is_inner(&spec, spec.unlinear(l)) && dense_sign_change(&field.values, l, &strides)
            })
            .collect();
        for l in changes {
            let idx = spec.unlinear(l);
            if grid.block_index(idx).is_none() {
                let slot = grid.allocate(idx);
                let blk = &mut grid.blocks_mut()[slot];
                for local in 0..Self::LEN {
                    let n = blk.node(local);
                    if (0..D).all(|a| n[a] < spec.dims[a]) {
                        blk.values[local] = field.get(n);
                    }
                }
            }
        }
        Ok(Self::from_grid(grid, half_width))
    }

    /// A band over a block grid whose tiles hold ±`half_width`: the band
    /// is the inner nodes next to a sign change.
    pub fn from_grid(phi: BlockGrid<D>, half_width: f64) -> Self {
        let mut band = NarrowBand {
            marks: vec![0; phi.blocks().len() * Self::LEN],
            epoch: 0,
            phi,
            active: Vec::new(),
            half_width,
            runs: Vec::new(),
        };
        let spec = *band.phi.spec();
        let keys: Vec<u32> = (0..band.phi.blocks().len() * Self::LEN)
            .into_par_iter()
            .map(|k| k as u32)
            .filter(|&k| {
                let node = band.node(k);
                (0..D).all(|a| node[a] < spec.dims[a])
                    && is_inner(&spec, node)
                    && band.has_sign_change(k)
            })
            .collect();
        band.set_active(keys);
        band
    }

    /// Number of band nodes.
    pub fn len(&self) -> usize {
        self.active.len()
    }

    /// True when the band is empty (no surface).
    pub fn is_empty(&self) -> bool {
        self.active.is_empty()
    }

    /// Number of allocated blocks of [`BLOCK`]^D nodes.
    pub fn block_count(&self) -> usize {
        self.phi.blocks().len()
    }

    /// Bytes held by φ (blocks and table), the marks and the band list.
    pub fn memory_bytes(&self) -> usize {
        self.phi.memory_bytes() + 4 * (self.marks.len() + self.active.len())
    }

    /// The grid of φ.
    pub fn spec(&self) -> &GridSpec<D> {
        self.phi.spec()
    }

    /// Global node index of `key`.
    #[inline]
    pub fn node(&self, key: u32) -> [usize; D] {
        let (slot, local) = split::<D>(key);
        self.phi.blocks()[slot].node(local)
    }

    /// φ at `key`.
    #[inline]
    pub fn value(&self, key: u32) -> f64 {
        let (slot, local) = split::<D>(key);
        self.phi.blocks()[slot].values[local]
    }

    #[inline]
    pub(crate) fn set(&mut self, key: u32, v: f64) {
        let (slot, local) = split::<D>(key);
        self.phi.blocks_mut()[slot].values[local] = v;
    }

    /// The neighbour of `key` one node along `axis` (forward or back).
    /// Past the grid's block range: the background tile.
    #[inline]
    pub(crate) fn step(&self, key: u32, axis: usize, forward: bool) -> Step {
        let shift = AXIS_BITS * axis;
        let c = (key as usize >> shift) & (BLOCK - 1);
        if forward && c < BLOCK - 1 {
            return Step::Node(key + (1 << shift));
        }
        if !forward && c > 0 {
            return Step::Node(key - (1 << shift));
        }
        let (slot, local) = split::<D>(key);
        let mut coord = self.phi.blocks()[slot].coord;
        let next = if forward {
            Some(coord[axis] + 1)
        } else {
            coord[axis].checked_sub(1)
        };
        match next.filter(|&n| n < self.phi.block_dims()[axis]) {
            None => Step::Tile(self.phi.background()),
            Some(n) => {
                coord[axis] = n;
                match self.phi.slot(coord) {
                    // The node on the facing side: local coordinate 0 ↔ 7.
                    Some(s) => Step::Node(join::<D>(s, local ^ ((BLOCK - 1) << shift))),
                    None => Step::Tile(self.phi.tile_value(coord).unwrap_or(0.0)),
                }
            }
        }
    }

    /// The values of `key`'s block, for [`Self::neighbour`].
    #[inline]
    pub(crate) fn block_values(&self, key: u32) -> &[f64] {
        &self.phi.blocks()[split::<D>(key).0].values
    }

    /// The face neighbour of `key` along `axis` as (key if allocated, φ):
    /// inside the node's block (`values`, see [`Self::block_values`])
    /// without any look-up. Plain loops over axes and directions calling
    /// this compile to straight code; arrays built by closures did not.
    #[inline(always)]
    pub(crate) fn neighbour(
        &self,
        key: u32,
        values: &[f64],
        axis: usize,
        forward: bool,
    ) -> (Option<u32>, f64) {
        let shift = AXIS_BITS * axis;
        let c = (key as usize >> shift) & (BLOCK - 1);
        let within = if forward { c < BLOCK - 1 } else { c > 0 };
        if within {
            let n = if forward {
                key + (1 << shift)
            } else {
                key - (1 << shift)
            };
            return (Some(n), values[n as usize & (Self::LEN - 1)]);
        }
        match self.step(key, axis, forward) {
            Step::Node(n) => (Some(n), self.value(n)),
            Step::Tile(v) => (None, v),
        }
    }

    /// φ at the neighbour of `key` along `axis`.
    #[inline]
    pub(crate) fn value_at(&self, key: u32, axis: usize, forward: bool) -> f64 {
        match self.step(key, axis, forward) {
            Step::Node(n) => self.value(n),
            Step::Tile(v) => v,
        }
    }

    /// Whether a face neighbour of `key` is on the other side.
    pub(crate) fn has_sign_change(&self, key: u32) -> bool {
        let values = self.block_values(key);
        let s = inside(values[key as usize & (Self::LEN - 1)]);
        for a in 0..D {
            for forward in [false, true] {
                if inside(self.neighbour(key, values, a, forward).1) != s {
                    return true;
                }
            }
        }
        false
    }

    /// Allocate the block holding node `idx` (with its tile value) and its
    /// marks; returns the block's index.
    pub(crate) fn allocate(&mut self, idx: [usize; D]) -> usize {
        let slot = self.phi.allocate(idx);
        self.marks.resize(self.phi.blocks().len() * Self::LEN, 0);
        slot
    }

    /// Set the band list (sorted here) and its per-block runs.
    pub(crate) fn set_active(&mut self, mut keys: Vec<u32>) {
        keys.par_sort_unstable();
        self.set_sorted_active(keys);
    }

    /// Set the band list from keys in ascending order, and its runs.
    fn set_sorted_active(&mut self, keys: Vec<u32>) {
        debug_assert!(keys.windows(2).all(|w| w[0] < w[1]), "ascending keys");
        self.runs.clear();
        let mut start = 0;
        while start < keys.len() {
            let slot = keys[start] >> Self::LOCAL_BITS;
            let end = start + keys[start..].partition_point(|&k| k >> Self::LOCAL_BITS == slot);
            self.runs.push((slot, start..end));
            start = end;
        }
        self.active = keys;
    }

    /// Make the nodes whose mark is `stamp` the band. Blocks without band
    /// nodes whose nodes all lie on one side are released (they become
    /// tiles, so allocation follows the band as it moves), and the blocks
    /// are ordered in space (see [`BlockGrid::sort_blocks`]):
    /// reinitialization appends blocks in the order its layers reach them.
    /// The band list is then read off the marks block by block, so it
    /// comes out sorted.
    pub(crate) fn set_band(&mut self, stamp: u32) {
        let busy: Vec<bool> = self
            .marks
            .par_chunks(Self::LEN)
            .map(|m| m.contains(&stamp))
            .collect();
        let spec = *self.phi.spec();
        let tiles: Vec<Option<bool>> = self
            .phi
            .blocks()
            .par_iter()
            .zip(&busy)
            .map(|(blk, &busy)| if busy { None } else { one_side(blk, &spec) })
            .collect();
        let mut slot = 0;
        let released = self.phi.release_blocks(|_| {
            slot += 1;
            tiles[slot - 1]
        });
        let sorted = self.phi.sort_blocks();
        // Old index → new index through both steps, and back.
        let map: Vec<u32> = released
            .iter()
            .map(|&m| if m == u32::MAX { m } else { sorted[m as usize] })
            .collect();
        if map.iter().enumerate().any(|(i, &m)| m != i as u32) {
            let mut old_of = vec![0usize; self.phi.blocks().len()];
            for (old, &new) in map.iter().enumerate() {
                if new != u32::MAX {
                    old_of[new as usize] = old;
                }
            }
            let mut marks = vec![0; self.phi.blocks().len() * Self::LEN];
            marks
                .par_chunks_mut(Self::LEN)
                .zip(&old_of)
                .for_each(|(m, &o)| {
                    m.copy_from_slice(&self.marks[o * Self::LEN..(o + 1) * Self::LEN])
                });
            self.marks = marks;
        }
        let keys = self
            .marks
            .par_chunks(Self::LEN)
            .enumerate()
            .flat_map_iter(|(slot, m)| {
                (0..Self::LEN)
                    .filter(move |&local| m[local] == stamp)
                    .map(move |local| join::<D>(slot, local))
            })
            .collect();
        self.set_sorted_active(keys);
    }

    /// `f` at every band node, in band order, from dense windows of φ (and
    /// of `d` when given) around each block: parallel over blocks. The
    /// windows hold the block and the neighbours across its faces; φ's also
    /// across its edges when `phi_edges` (for mixed derivatives). Other
    /// window entries are stale and must not be read.
    pub(crate) fn map_active<T: Send + Default + Clone>(
        &self,
        phi_edges: bool,
        d: Option<&BlockGrid<D>>,
        f: impl Fn(&Stencil<D>) -> T + Sync,
    ) -> Vec<T> {
        self.map_active_from(T::default(), phi_edges, d, f)
    }

    /// [`Self::map_active`] for results without a `Default` (arrays of
    /// length `D`): the output starts filled with `placeholder`.
    pub(crate) fn map_active_from<T: Send + Clone>(
        &self,
        placeholder: T,
        phi_edges: bool,
        d: Option<&BlockGrid<D>>,
        f: impl Fn(&Stencil<D>) -> T + Sync,
    ) -> Vec<T> {
        let strides = BlockGrid::<D>::window_strides();
        let len = BlockGrid::<D>::WINDOW_LEN;
        // Each block's results go straight to their place in the output.
        // Filled in parallel: a serial fill of 1.3M entries (40 MB for
        // tuples) cost the calling thread about 30 ms per call.
        let mut out: Vec<T> = rayon::iter::repeat_n(placeholder, self.active.len()).collect();
        let mut parts = Vec::with_capacity(self.runs.len());
        let mut rest = &mut out[..];
        for (_, range) in &self.runs {
            let (part, tail) = rest.split_at_mut(range.len());
            parts.push(part);
            rest = tail;
        }
        // Per thread: one window buffer for φ and one for d.
        let buffers = || (vec![0.0; len], vec![0.0; if d.is_some() { len } else { 0 }]);
        self.runs.par_iter().zip(parts).for_each_init(
            buffers,
            |(phi, dw), ((slot, range), part)| {
                let blk = &self.phi.blocks()[*slot as usize];
                let phi_parts = if phi_edges { 2 } else { 1 };
                self.phi.gather_window_part(blk.coord, phi_parts, phi);
                if let Some(d) = d {
                    d.gather_window_part(blk.coord, 1, dw);
                }
                let mask = Self::LEN - 1;
                let keys = &self.active[range.clone()];
                for (index, (o, &k)) in (range.start..).zip(part.iter_mut().zip(keys)) {
                    let local = k as usize & mask;
                    *o = f(&Stencil {
                        phi,
                        d: dw,
                        at: BlockGrid::<D>::window_index(local),
                        index,
                        strides: &strides,
                        node: blk.node(local),
                        corner: blk.coord.map(|c| c * BLOCK),
                    });
                }
            },
        );
        out
    }

    /// Adds `updates` (one per band node, in band order) to φ, in parallel
    /// over blocks, except at the nodes where `defer(old, new)` holds:
    /// those come back as (key, new value), in band order, for a caller
    /// that must decide them one by one.
    pub(crate) fn add_active(
        &mut self,
        updates: &[f64],
        defer: impl Fn(f64, f64) -> bool + Sync,
    ) -> Vec<(u32, f64)> {
        assert_eq!(updates.len(), self.active.len(), "one update per band node");
        // The runs name distinct blocks in ascending order: one pass over
        // the blocks hands out each run's block once.
        let mut blocks = self.phi.blocks_mut().iter_mut().enumerate();
        let run_blocks: Vec<&mut Block<D>> = self
            .runs
            .iter()
            .map(|(slot, _)| {
                let (_, blk) = blocks
                    .find(|(i, _)| *i == *slot as usize)
                    .expect("runs follow the block order");
                blk
            })
            .collect();
        let (active, mask) = (&self.active, Self::LEN - 1);
        run_blocks
            .into_par_iter()
            .zip(&self.runs)
            .flat_map_iter(|(blk, (_, range))| {
                let mut deferred = Vec::new();
                for (&k, &u) in active[range.clone()].iter().zip(&updates[range.clone()]) {
                    let v = &mut blk.values[k as usize & mask];
                    let new = *v + u;
                    if defer(*v, new) {
                        deferred.push((k, new));
                    } else {
                        *v = new;
                    }
                }
                deferred
            })
            .collect()
    }
}

/// `Some(inside)` if every node of `blk` in the grid lies on that side.
fn one_side<const D: usize>(blk: &Block<D>, spec: &GridSpec<D>) -> Option<bool> {
    let mut sides = (0..Block::<D>::LEN)
        .filter(|&l| {
            let n = blk.node(l);
            (0..D).all(|a| n[a] < spec.dims[a])
        })
        .map(|l| inside(blk.values[l]));
    let first = sides.next()?;
    sides.all(|s| s == first).then_some(first)
}

#[inline]
pub(crate) fn split<const D: usize>(key: u32) -> (usize, usize) {
    let bits = AXIS_BITS * D;
    (key as usize >> bits, key as usize & ((1 << bits) - 1))
}

#[inline]
pub(crate) fn join<const D: usize>(slot: usize, local: usize) -> u32 {
    ((slot << (AXIS_BITS * D)) | local) as u32
}

/// Inside means φ ≤ 0 (so a zero value is never ambiguous).
#[inline]
pub(crate) fn inside(v: f64) -> bool {
    v <= 0.0
}

/// Whether node `l` of a dense field has a face neighbour on the other side.
#[inline]
fn dense_sign_change<const D: usize>(phi: &[f64], l: usize, strides: &[usize; D]) -> bool {
    let s = inside(phi[l]);
    strides
        .iter()
        .any(|&st| inside(phi[l - st]) != s || inside(phi[l + st]) != s)
}

/// Whether node `idx` is far enough from the border for every stencil.
#[inline]
pub(crate) fn is_inner<const D: usize>(spec: &GridSpec<D>, idx: [usize; D]) -> bool {
    (0..D).all(|a| idx[a] >= BORDER && idx[a] + BORDER < spec.dims[a])
}

/// The `Some` results of `f` over `items`, in order, computed in
/// parallel into one vector allocated by the calling thread: `f` runs
/// twice per item (to count, then to fill). Rayon's `filter`/`flatten`
/// collect into per-thread vectors, which glibc keeps in per-thread
/// arenas after they are freed (+140 MB peak at Dragon scale).
pub(crate) fn par_filter_map<I: Sync, T: Clone + Send>(
    items: &[I],
    placeholder: T,
    f: impl Fn(&I) -> Option<T> + Sync,
) -> Vec<T> {
    const CHUNK: usize = 16384;
    let counts: Vec<usize> = items
        .par_chunks(CHUNK)
        .map(|c| c.iter().filter(|i| f(i).is_some()).count())
        .collect();
    let mut out = vec![placeholder; counts.iter().sum()];
    let mut parts = Vec::with_capacity(counts.len());
    let mut rest = &mut out[..];
    for &n in &counts {
        let (part, tail) = rest.split_at_mut(n);
        parts.push(part);
        rest = tail;
    }
    items.par_chunks(CHUNK).zip(parts).for_each(|(c, part)| {
        for (o, v) in part.iter_mut().zip(c.iter().filter_map(&f)) {
            *o = v;
        }
    });
    out
}

/// Sum of `f` over `items`, in fixed-size chunks summed in order, so the
/// result does not depend on the number of threads.
pub(crate) fn det_sum<T: Sync>(items: &[T], f: impl Fn(&T) -> f64 + Sync) -> f64 {
    let partial: Vec<f64> = items
        .par_chunks(4096)
        .map(|c| c.iter().map(&f).sum::<f64>())
        .collect();
    partial.iter().sum()
}

/// Fills the values of one block (block coordinates, values in block
/// order) of a distance that is computed only where the band needs it.
pub type BlockFill<const D: usize> = Box<dyn Fn([usize; D], &mut [f64]) + Send + Sync>;

/// Value of the unsigned distance's tiles: never read by the evolution
/// (every block next to a band block is computed), large so a mistake
/// shows as a wild speed rather than a plausible one.
const FAR: f64 = 1e30;

/// The unsigned distance d on the blocks of a band and their neighbours
/// (every node a band stencil or its closest point reads), computed block
/// by block as the band reaches new blocks ([`BandDistance::cover`]).
pub struct BandDistance<const D: usize> {
    grid: BlockGrid<D>,
    fill: BlockFill<D>,
}

impl<const D: usize> BandDistance<D> {
    /// d computed on demand by `fill`.
    pub fn new(spec: GridSpec<D>, fill: BlockFill<D>) -> Result<Self> {
        Ok(BandDistance {
            grid: BlockGrid::new(spec, FAR)?,
            fill,
        })
    }

    /// d copied on demand from a dense field.
    pub fn dense(field: Arc<Field<D>>) -> Result<Self> {
        let spec = field.spec;
        Self::new(
            spec,
            Box::new(move |coord, values| {
                for (local, v) in values.iter_mut().enumerate() {
                    let n: [usize; D] = std::array::from_fn(|a| {
                        coord[a] * BLOCK + ((local >> (AXIS_BITS * a)) & (BLOCK - 1))
                    });
                    if (0..D).all(|a| n[a] < spec.dims[a]) {
                        *v = field.get(n);
                    }
                }
            }),
        )
    }

    /// The computed blocks.
    pub fn grid(&self) -> &BlockGrid<D> {
        &self.grid
    }

    /// d at node `idx`, if its block has been computed.
    #[inline]
    pub fn get(&self, idx: [usize; D]) -> Option<f64> {
        self.grid
            .locate(idx)
            .map(|(b, l)| self.grid.blocks()[b].values[l])
    }

    /// Compute d on every block of the band's blocks with band nodes and
    /// on their neighbours (all 3^D − 1) that lack it; parallel over the
    /// new blocks.
    pub fn cover(&mut self, band: &NarrowBand<D>) {
        let dims = self.grid.block_dims();
        let first_new = self.grid.blocks().len();
        for (slot, _) in &band.runs {
            let centre = band.phi.blocks()[*slot as usize].coord;
            for k in 0..3usize.pow(D as u32) {
                let mut c = centre;
                let mut valid = true;
                for a in 0..D {
                    match (centre[a] + k / 3usize.pow(a as u32) % 3).checked_sub(1) {
                        Some(x) if x < dims[a] => c[a] = x,
                        _ => valid = false,
                    }
                }
                if valid && self.grid.slot(c).is_none() {
                    self.grid.allocate(c.map(|x| x * BLOCK));
                }
            }
        }
        let fill = &self.fill;
        self.grid.blocks_mut()[first_new..]
            .par_iter_mut()
            .for_each(|b| fill(b.coord, &mut b.values));
    }

    /// Bytes held by the computed blocks and the table.
    pub fn memory_bytes(&self) -> usize {
        self.grid.memory_bytes()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle(n: usize, r: f64) -> Field<2> {
        let spec = GridSpec::<2> {
            origin: [-0.5, -0.5],
            spacing: 1.0 / (n - 1) as f64,
            dims: [n, n],
        };
        let values = (0..spec.node_count())
            .map(|l| {
                let [x, y] = spec.position(spec.unlinear(l));
                x.hypot(y) - r
            })
            .collect();
        Field { spec, values }
    }

    #[test]
    fn band_blocks_follow_the_surface_not_the_grid() {
        // A circle of radius 0.3 in a 161² grid of the unit square.
        let field = circle(161, 0.3);
        let h = field.spec.spacing;
        let mut band = NarrowBand::from_field(field, 3.0 * h).unwrap();
        crate::reinit::reinitialize(&mut band);
        let blocks = band.block_count();
        // Circumference 1.9 = 302 cells; a 6-cell wide ring crosses about
        // 302 / 8 · 2 blocks, out of 21² in the grid.
        assert!(band.len() <= blocks * 64);
        assert!((40..=120).contains(&blocks), "{blocks} blocks");
        // Tiles hold the side: centre inside, corner outside.
        assert_eq!(band.phi.get([80, 80]), -band.half_width);
        assert_eq!(band.phi.get([3, 3]), band.half_width);
    }

    #[test]
    fn neighbour_steps_match_node_coordinates() {
        let field = circle(61, 0.3);
        let h = field.spec.spacing;
        let band = NarrowBand::from_field(field.clone(), 3.0 * h).unwrap();
        assert!(!band.is_empty());
        for &k in &band.active {
            let node = band.node(k);
            assert_eq!(band.value(k), field.get(node).clamp(-3.0 * h, 3.0 * h));
            for a in 0..2 {
                for f in [false, true] {
                    let mut n = node;
                    n[a] = if f { n[a] + 1 } else { n[a] - 1 };
                    match band.step(k, a, f) {
                        Step::Node(m) => assert_eq!(band.node(m), n),
                        Step::Tile(v) => assert_eq!(v, band.phi.get(n)),
                    }
                }
            }
        }
        // The windows see the same values as node access.
        let seen = band.map_active(false, None, |s| {
            (s.node, s.phi[s.at], s.phi[s.at + s.strides[1]])
        });
        for (node, v, up) in seen {
            assert_eq!(v, band.phi.get(node));
            assert_eq!(up, band.phi.get([node[0], node[1] + 1]));
        }
    }
}
