//! Sparse block grid for narrow bands: values are stored only in fixed-size
//! blocks of `8^D` nodes near the surface (in the spirit of OpenVDB's leaf
//! nodes); every other block is a *tile* holding the background value,
//! positive (outside) or negative (inside).
//!
//! Blocks are found through a dense table with one `u32` per block (8 MB
//! for a 1024³ grid), so access costs an index computation, no hashing.
//! A 1024³ narrow band of a few cells around a surface allocates a few
//! tens of thousands of blocks: a few hundred MB instead of 8 GB.
//!
//! For narrow-band algorithms: iterate [`BlockGrid::blocks`] (or mutate
//! them in parallel with [`BlockGrid::blocks_mut`]), map between global and
//! block-local indices with [`Block::node`] / [`BlockGrid::locate`], and read
//! neighbours across block borders with [`BlockGrid::neighbour`].

use crate::marching::tables::{cube_table, EDGE_CORNERS, MAX_LOOP_CENTRES};
use crate::marching::{cell_case, edge_vertex, loop_centre, Samples3};
use crate::{Field, GridError, GridSpec};
use rayon::prelude::*;
use surfrecon_geom::{DVec3, TriMesh};

/// Nodes per block along each axis.
pub const BLOCK: usize = 8;
const BLOCK_SHIFT: u32 = 3;

/// Table entry of a block that is a tile with the positive background.
const TILE_OUTSIDE: u32 = u32::MAX;
/// Table entry of a block that is a tile with the negated background.
const TILE_INSIDE: u32 = u32::MAX - 1;

/// One allocated block: `BLOCK^D` values, axis 0 fastest. Nodes of blocks
/// on the far side of the grid that fall outside it hold padding.
#[derive(Clone, Debug, PartialEq)]
pub struct Block<const D: usize> {
    /// Block coordinates (global node index = `coord * BLOCK + local`).
    pub coord: [usize; D],
    pub values: Vec<f64>,
}

impl<const D: usize> Block<D> {
    /// Number of nodes in a block.
    pub const LEN: usize = BLOCK.pow(D as u32);

    /// Global node index of local linear index `local`.
    #[inline]
    pub fn node(&self, local: usize) -> [usize; D] {
        std::array::from_fn(|a| {
            (self.coord[a] << BLOCK_SHIFT) + ((local >> (BLOCK_SHIFT as usize * a)) & (BLOCK - 1))
        })
    }
}

/// Local linear index inside a block of a global node index.
#[inline]
fn local_index<const D: usize>(idx: [usize; D]) -> usize {
    (0..D).fold(0, |l, a| {
        l | ((idx[a] & (BLOCK - 1)) << (BLOCK_SHIFT as usize * a))
    })
}

/// A grid whose values live in `8^D` blocks allocated on demand.
#[derive(Clone, Debug, PartialEq)]
pub struct BlockGrid<const D: usize> {
    spec: GridSpec<D>,
    background: f64,
    block_dims: [usize; D],
    /// Per block: index into `blocks`, or a tile marker.
    table: Vec<u32>,
    blocks: Vec<Block<D>>,
}

impl<const D: usize> BlockGrid<D> {
    /// An empty grid (all tiles outside) over `spec`. `background` is the
    /// value of outside tiles; inside tiles hold `-background`.
    pub fn new(spec: GridSpec<D>, background: f64) -> Result<Self, GridError> {
        if spec.dims.contains(&0) || !background.is_finite() {
            return Err(GridError::Invalid(format!(
                "block grid needs nonzero dims and a finite background (got {:?}, {background})",
                spec.dims
            )));
        }
        let block_dims = spec.dims.map(|n| n.div_ceil(BLOCK));
        let count = block_dims.iter().try_fold(1usize, |c, &n| c.checked_mul(n));
        match count {
            Some(c) if c < TILE_INSIDE as usize => Ok(BlockGrid {
                spec,
                background,
                block_dims,
                table: vec![TILE_OUTSIDE; c],
                blocks: Vec::new(),
            }),
            _ => Err(GridError::Invalid(format!(
                "too many blocks for grid {:?}",
                spec.dims
            ))),
        }
    }

    pub fn spec(&self) -> &GridSpec<D> {
        &self.spec
    }

    /// Move the grid by `by` (the same values at translated nodes).
    pub fn translate(&mut self, by: [f64; D]) {
        for (o, b) in self.spec.origin.iter_mut().zip(by) {
            *o += b;
        }
    }

    /// Value of outside tiles (inside tiles hold its negation).
    pub fn background(&self) -> f64 {
        self.background
    }

    /// Number of blocks along each axis.
    pub fn block_dims(&self) -> [usize; D] {
        self.block_dims
    }

    /// The allocated blocks, in allocation order.
    pub fn blocks(&self) -> &[Block<D>] {
        &self.blocks
    }

    /// The allocated blocks, mutable (e.g. `par_iter_mut` for a band update).
    pub fn blocks_mut(&mut self) -> &mut [Block<D>] {
        &mut self.blocks
    }

    /// Bytes held by values and the block table.
    pub fn memory_bytes(&self) -> usize {
        self.blocks.len() * (Block::<D>::LEN * 8 + std::mem::size_of::<Block<D>>())
            + self.table.len() * 4
    }

    /// Linear index of block coordinates.
    #[inline]
    fn block_linear(&self, coord: [usize; D]) -> usize {
        (0..D)
            .rev()
            .fold(0, |l, a| l * self.block_dims[a] + coord[a])
    }

    /// Index into [`Self::blocks`] of the block holding node `idx`, if allocated.
    #[inline]
    pub fn block_index(&self, idx: [usize; D]) -> Option<usize> {
        let slot = self.table[self.block_linear(idx.map(|i| i >> BLOCK_SHIFT))];
        (slot < TILE_INSIDE).then_some(slot as usize)
    }

    /// Block index and local index of node `idx`, if its block is allocated.
    #[inline]
    pub fn locate(&self, idx: [usize; D]) -> Option<(usize, usize)> {
        self.block_index(idx).map(|b| (b, local_index(idx)))
    }

    /// Value of the tile at block coordinates `coord` (or `None` if allocated).
    pub fn tile_value(&self, coord: [usize; D]) -> Option<f64> {
        match self.table[self.block_linear(coord)] {
            TILE_OUTSIDE => Some(self.background),
            TILE_INSIDE => Some(-self.background),
            _ => None,
        }
    }

    /// Mark the tile at `coord` inside (`-background`) or outside. No effect
    /// on an allocated block.
    pub fn set_tile_inside(&mut self, coord: [usize; D], inside: bool) {
        let b = self.block_linear(coord);
        if self.table[b] >= TILE_INSIDE {
            self.table[b] = if inside { TILE_INSIDE } else { TILE_OUTSIDE };
        }
    }

    /// Value at node `idx` (must be inside the grid).
    #[inline]
    pub fn get(&self, idx: [usize; D]) -> f64 {
        match self.table[self.block_linear(idx.map(|i| i >> BLOCK_SHIFT))] {
            TILE_OUTSIDE => self.background,
            TILE_INSIDE => -self.background,
            slot => self.blocks[slot as usize].values[local_index(idx)],
        }
    }

    /// Value at the neighbour of `idx` offset by `step` (±1) along `axis`,
    /// or `None` past the grid edge. Works across block borders.
    #[inline]
    pub fn neighbour(&self, idx: [usize; D], axis: usize, step: isize) -> Option<f64> {
        let mut n = idx;
        n[axis] = idx[axis].checked_add_signed(step)?;
        (n[axis] < self.spec.dims[axis]).then(|| self.get(n))
    }

    /// Allocate the block holding node `idx` (filled with its tile value)
    /// and return its index into [`Self::blocks`].
    pub fn allocate(&mut self, idx: [usize; D]) -> usize {
        let coord = idx.map(|i| i >> BLOCK_SHIFT);
        let b = self.block_linear(coord);
        match self.table[b] {
            slot if slot < TILE_INSIDE => slot as usize,
            tile => {
                let fill = if tile == TILE_INSIDE {
                    -self.background
                } else {
                    self.background
                };
                self.blocks.push(Block {
                    coord,
                    values: vec![fill; Block::<D>::LEN],
                });
                self.table[b] = (self.blocks.len() - 1) as u32;
                self.blocks.len() - 1
            }
        }
    }

    /// Set the value at node `idx`, allocating its block if needed.
    pub fn set(&mut self, idx: [usize; D], v: f64) {
        let b = self.allocate(idx);
        self.blocks[b].values[local_index(idx)] = v;
    }

    /// Every stored node inside the grid as (node index, value), block by
    /// block (padding past the grid's far side left out).
    pub fn iter_nodes(&self) -> impl Iterator<Item = ([usize; D], f64)> + '_ {
        self.blocks.iter().flat_map(move |b| {
            (0..Block::<D>::LEN)
                .map(move |l| (b.node(l), b.values[l]))
                .filter(move |(idx, _)| self.in_grid(*idx))
        })
    }

    /// Whether node `idx` lies in the grid (blocks pad past its far side).
    #[inline]
    pub fn in_grid(&self, idx: [usize; D]) -> bool {
        (0..D).all(|a| idx[a] < self.spec.dims[a])
    }

    /// A grid holding `nodes` (index, value). Other nodes of the blocks
    /// they fall in get `±background` with the sign of the nearest given
    /// node (breadth first), and tiles take the sign of the band next to
    /// them (see [`Self::fill_tile_signs`]): a band a few nodes thick around
    /// a surface yields a consistent inside and outside.
    pub fn from_nodes(
        spec: GridSpec<D>,
        background: f64,
        nodes: impl IntoIterator<Item = ([usize; D], f64)>,
    ) -> Result<Self, GridError> {
        let mut g = Self::new(spec, background)?;
        let mut given = Vec::new();
        for (idx, v) in nodes {
            if !g.in_grid(idx) || v.is_nan() {
                return Err(GridError::Invalid(format!(
                    "node {idx:?} (value {v}) outside grid {:?} or not a number",
                    spec.dims
                )));
            }
            let b = g.allocate_filled(idx, f64::NAN);
            g.blocks[b].values[local_index(idx)] = v;
            given.push(idx);
        }
        g.fill_unset_nodes(given);
        g.fill_tile_signs();
        Ok(g)
    }

    /// Like [`Self::allocate`], but a new block is filled with `fill`.
    fn allocate_filled(&mut self, idx: [usize; D], fill: f64) -> usize {
        let b = self.block_linear(idx.map(|i| i >> BLOCK_SHIFT));
        if self.table[b] >= TILE_INSIDE {
            self.table[b] = TILE_OUTSIDE;
            let slot = self.allocate(idx);
            self.blocks[slot].values.fill(fill);
            slot
        } else {
            self.table[b] as usize
        }
    }

    /// Replace the NaN placeholders of allocated blocks by `±background`,
    /// the sign spreading breadth first from the `given` nodes.
    fn fill_unset_nodes(&mut self, given: Vec<[usize; D]>) {
        let mut queue: std::collections::VecDeque<[usize; D]> = given.into();
        while let Some(idx) = queue.pop_front() {
            let fill = if self.get(idx) < 0.0 {
                -self.background
            } else {
                self.background
            };
            for a in 0..D {
                for step in [-1isize, 1] {
                    let mut n = idx;
                    match idx[a].checked_add_signed(step) {
                        Some(x) if x < self.spec.dims[a] => n[a] = x,
                        _ => continue,
                    }
                    if let Some((b, l)) = self.locate(n) {
                        if self.blocks[b].values[l].is_nan() {
                            self.blocks[b].values[l] = fill;
                            queue.push_back(n);
                        }
                    }
                }
            }
        }
        // Padding past the grid edge (and unreachable nodes) get the background.
        for blk in &mut self.blocks {
            for v in blk.values.iter_mut().filter(|v| v.is_nan()) {
                *v = self.background;
            }
        }
    }

    /// The narrow band of a dense field: every block with a node of
    /// `|value| < band` is stored (with all its values); other blocks become
    /// tiles of `±band` with the sign of their first node. Parallel over
    /// blocks.
    pub fn from_dense_band(field: &Field<D>, band: f64) -> Result<Self, GridError> {
        let mut g = Self::new(field.spec, band)?;
        if field.values.len() != field.spec.node_count() {
            return Err(GridError::Invalid(
                "field has the wrong number of values".into(),
            ));
        }
        let coords: Vec<[usize; D]> = (0..g.table.len()).map(|b| g.block_coord(b)).collect();
        // Per block: (in the band?, first node negative?).
        let kinds: Vec<(bool, bool)> = coords
            .par_iter()
            .map(|&c| {
                let mut in_band = false;
                g.for_block_nodes(c, |_, idx| in_band |= field.get(idx).abs() < band);
                (in_band, field.get(c.map(|x| x * BLOCK)) < 0.0)
            })
            .collect();
        let g_ref = &g;
        let blocks: Vec<Block<D>> = coords
            .par_iter()
            .zip(&kinds)
            .filter(|(_, k)| k.0)
            .map(|(&coord, &(_, inside))| {
                let fill = if inside { -band } else { band };
                let mut values = vec![fill; Block::<D>::LEN];
                g_ref.for_block_nodes(coord, |local, idx| values[local] = field.get(idx));
                Block { coord, values }
            })
            .collect();
        for (b, &(in_band, inside)) in kinds.iter().enumerate() {
            if !in_band && inside {
                g.table[b] = TILE_INSIDE;
            }
        }
        for blk in blocks {
            let b = g.block_linear(blk.coord);
            g.table[b] = g.blocks.len() as u32;
            g.blocks.push(blk);
        }
        Ok(g)
    }

    /// Block coordinates of block linear index `b`.
    fn block_coord(&self, mut b: usize) -> [usize; D] {
        std::array::from_fn(|a| {
            let c = b % self.block_dims[a];
            b /= self.block_dims[a];
            c
        })
    }

    /// Call `visit(local, node)` for the nodes of block `coord` inside the grid.
    fn for_block_nodes(&self, coord: [usize; D], mut visit: impl FnMut(usize, [usize; D])) {
        for local in 0..Block::<D>::LEN {
            let idx: [usize; D] = std::array::from_fn(|a| {
                coord[a] * BLOCK + ((local >> (BLOCK_SHIFT as usize * a)) & (BLOCK - 1))
            });
            if self.in_grid(idx) {
                visit(local, idx);
            }
        }
    }

    /// The dense field (tiles expanded to their values).
    pub fn to_dense(&self) -> Field<D> {
        let spec = self.spec;
        let values = (0..spec.node_count())
            .into_par_iter()
            .map(|l| self.get(spec.unlinear(l)))
            .collect();
        Field { spec, values }
    }

    /// Give every tile the sign of the band it touches: tiles next to an
    /// allocated block take the sign of that block's nodes on the shared
    /// face, then signs spread through connected tiles (breadth first);
    /// tiles reached by nothing stay as they are.
    pub fn fill_tile_signs(&mut self) {
        let mut queue = std::collections::VecDeque::new();
        let mut decided = vec![false; self.table.len()];
        for blk in &self.blocks {
            decided[self.block_linear(blk.coord)] = true;
            for (nb, inside) in self.face_signs(blk) {
                let b = self.block_linear(nb);
                if !decided[b] {
                    decided[b] = true;
                    self.table[b] = if inside { TILE_INSIDE } else { TILE_OUTSIDE };
                    queue.push_back(nb);
                }
            }
        }
        while let Some(c) = queue.pop_front() {
            let tile = self.table[self.block_linear(c)];
            let neighbours: Vec<_> = self.block_neighbours(c).collect();
            for nb in neighbours {
                let b = self.block_linear(nb);
                if !decided[b] {
                    decided[b] = true;
                    self.table[b] = tile;
                    queue.push_back(nb);
                }
            }
        }
    }

    /// Face-neighbour block coordinates of `c` within the grid.
    fn block_neighbours(&self, c: [usize; D]) -> impl Iterator<Item = [usize; D]> + '_ {
        (0..D).flat_map(move |a| {
            [-1isize, 1].into_iter().filter_map(move |s| {
                let mut n = c;
                n[a] = c[a].checked_add_signed(s)?;
                (n[a] < self.block_dims[a]).then_some(n)
            })
        })
    }

    /// For each tile neighbour of an allocated block: whether the block's
    /// nodes facing it are (mostly) negative.
    fn face_signs(&self, blk: &Block<D>) -> Vec<([usize; D], bool)> {
        let mut out = Vec::new();
        for nb in self.block_neighbours(blk.coord) {
            if self.tile_value(nb).is_none() {
                continue;
            }
            let axis = (0..D).find(|&a| nb[a] != blk.coord[a]).unwrap_or(0);
            let face = if nb[axis] > blk.coord[axis] {
                BLOCK - 1
            } else {
                0
            };
            let (mut neg, mut total) = (0usize, 0usize);
            for local in 0..Block::<D>::LEN {
                let idx = blk.node(local);
                if (local >> (BLOCK_SHIFT as usize * axis)) & (BLOCK - 1) == face
                    && self.in_grid(idx)
                {
                    total += 1;
                    neg += (blk.values[local] < 0.0) as usize;
                }
            }
            if total > 0 {
                out.push((nb, 2 * neg > total));
            }
        }
        out
    }
}

/// Nodes per axis of a block's window: the block and one node beyond it
/// on each side (see [`BlockGrid::gather_window`]).
pub const WINDOW: usize = BLOCK + 2;

/// Narrow-band support: whole-block allocation, release and windows.
impl<const D: usize> BlockGrid<D> {
    /// Number of nodes in a window ([`WINDOW`]^D).
    pub const WINDOW_LEN: usize = WINDOW.pow(D as u32);

    /// Strides of a window (axis 0 fastest).
    pub fn window_strides() -> [usize; D] {
        std::array::from_fn(|a| WINDOW.pow(a as u32))
    }

    /// Window index of local linear index `local` of the centre block.
    #[inline]
    pub fn window_index(local: usize) -> usize {
        (0..D).fold(0, |w, a| {
            let c = (local >> (BLOCK_SHIFT as usize * a)) & (BLOCK - 1);
            w + (c + 1) * WINDOW.pow(a as u32)
        })
    }

    /// Index into [`Self::blocks`] of the block at block coordinates
    /// `coord`, if allocated (`coord` must lie in [`Self::block_dims`]).
    #[inline]
    pub fn slot(&self, coord: [usize; D]) -> Option<usize> {
        let slot = self.table[self.block_linear(coord)];
        (slot < TILE_INSIDE).then_some(slot as usize)
    }

    /// Turn the blocks for which `tile` says `Some(inside)` back into tiles
    /// (inside or outside); the others keep their order. Returns, per old
    /// index into [`Self::blocks`], the new index (`u32::MAX` if released).
    pub fn release_blocks(&mut self, mut tile: impl FnMut(&Block<D>) -> Option<bool>) -> Vec<u32> {
        let mut map = Vec::with_capacity(self.blocks.len());
        let mut kept = 0u32;
        let old = std::mem::take(&mut self.blocks);
        for blk in old {
            let b = self.block_linear(blk.coord);
            match tile(&blk) {
                Some(inside) => {
                    self.table[b] = if inside { TILE_INSIDE } else { TILE_OUTSIDE };
                    map.push(u32::MAX);
                }
                None => {
                    self.table[b] = kept;
                    map.push(kept);
                    kept += 1;
                    self.blocks.push(blk);
                }
            }
        }
        map
    }

    /// Order the blocks by their linear index in the block table (axis 0
    /// fastest), so that a pass over them visits neighbours close in time
    /// and finds their values still in cache. Returns, per old index into
    /// [`Self::blocks`], the new index.
    pub fn sort_blocks(&mut self) -> Vec<u32> {
        let mut order: Vec<(usize, usize)> = self
            .blocks
            .iter()
            .enumerate()
            .map(|(i, b)| (self.block_linear(b.coord), i))
            .collect();
        order.sort_unstable();
        let mut map = vec![0u32; order.len()];
        let mut old: Vec<Option<Block<D>>> = std::mem::take(&mut self.blocks)
            .into_iter()
            .map(Some)
            .collect();
        for (new, &(linear, i)) in order.iter().enumerate() {
            map[i] = new as u32;
            self.table[linear] = new as u32;
            self.blocks.push(old[i].take().expect("each block once"));
        }
        map
    }

    /// Copy the values of block `coord` and of the node layer around it
    /// (from the neighbouring blocks or tiles) into `out`, a window of
    /// [`WINDOW`]^D nodes, axis 0 fastest, so that stencils of the block's
    /// nodes run on a dense array with [`Self::window_strides`]. Nodes past
    /// the grid's block range hold the background.
    pub fn gather_window(&self, coord: [usize; D], out: &mut [f64]) {
        self.gather_window_part(coord, D, out);
    }

    /// [`Self::gather_window`] for the parts of the layer around the block
    /// that lie beyond at most `axes` of its faces at once: 1 gives the
    /// faces (what first-derivative stencils read), 2 adds the edges (mixed
    /// second derivatives), D everything. Other parts of `out` are left as
    /// they were. Each part comes from another block, so leaving out those
    /// that are not read saves most of the look-ups and cache misses.
    pub fn gather_window_part(&self, coord: [usize; D], axes: usize, out: &mut [f64]) {
        assert_eq!(out.len(), Self::WINDOW_LEN, "window buffer size");
        let strides = Self::window_strides();
        // One neighbour block (or the centre) per offset in {-1, 0, 1}^D.
        for k in 0..3usize.pow(D as u32) {
            let off: [usize; D] = std::array::from_fn(|a| k / 3usize.pow(a as u32) % 3);
            if off.iter().filter(|&&o| o != 1).count() > axes {
                continue;
            }
            let mut source = Some(coord);
            for a in 0..D {
                match (coord[a] + off[a]).checked_sub(1) {
                    Some(c) if c < self.block_dims[a] => {
                        if let Some(s) = &mut source {
                            s[a] = c;
                        }
                    }
                    _ => source = None,
                }
            }
            // Window range and the source's local start along each axis.
            let (lo, len, src): ([usize; D], [usize; D], [usize; D]) = (
                off.map(|o| [0, 1, BLOCK + 1][o]),
                off.map(|o| [1, BLOCK, 1][o]),
                off.map(|o| [BLOCK - 1, 0, 0][o]),
            );
            let values = source
                .and_then(|c| self.slot(c))
                .map(|s| &self.blocks[s].values);
            let fill = source
                .and_then(|c| self.tile_value(c))
                .unwrap_or(self.background);
            // Rows along axis 0, the other axes counted by an odometer.
            let mut i = [0usize; D];
            'rows: loop {
                let (mut w, mut s) = (lo[0], src[0]);
                for a in 1..D {
                    w += (lo[a] + i[a]) * strides[a];
                    s += (src[a] + i[a]) << (BLOCK_SHIFT as usize * a);
                }
                // Runs are a whole block row or one node: fixed-size
                // copies, which compile to moves rather than library calls.
                match (values, len[0]) {
                    (Some(v), BLOCK) => {
                        let row: &[f64; BLOCK] = v[s..s + BLOCK].try_into().expect("block row");
                        out[w..w + BLOCK].copy_from_slice(row);
                    }
                    (Some(v), _) => out[w] = v[s],
                    (None, BLOCK) => out[w..w + BLOCK].copy_from_slice(&[fill; BLOCK]),
                    (None, _) => out[w] = fill,
                }
                let mut a = 1;
                loop {
                    if a >= D {
                        break 'rows;
                    }
                    i[a] += 1;
                    if i[a] < len[a] {
                        break;
                    }
                    i[a] = 0;
                    a += 1;
                }
            }
        }
    }
}

impl Samples3 for BlockGrid<3> {
    fn spec(&self) -> &GridSpec<3> {
        &self.spec
    }
    #[inline]
    fn at(&self, idx: [usize; 3]) -> f64 {
        self.get(idx)
    }
}

/// Marching cubes over a block grid, visiting only cells next to allocated
/// blocks (and between tiles of opposite sign); gives the same triangles as
/// [`crate::marching::marching_cubes`] on [`BlockGrid::to_dense`], with
/// vertices ordered by grid edge. Parallel over blocks, deterministic.
pub fn marching_cubes_sparse(grid: &BlockGrid<3>, iso: f64) -> TriMesh {
    let visit = blocks_to_visit(grid);
    let parts: Vec<BlockMesh> = visit
        .par_iter()
        .map(|&c| block_mesh(grid, iso, c))
        .collect();
    merge_block_meshes(parts)
}

/// Block coordinates whose cells may cross the surface, in table order.
fn blocks_to_visit(grid: &BlockGrid<3>) -> Vec<[usize; 3]> {
    let bd = grid.block_dims;
    (0..grid.table.len())
        .into_par_iter()
        .filter_map(|l| {
            let c = [l % bd[0], (l / bd[0]) % bd[1], l / (bd[0] * bd[1])];
            let own = grid.tile_value(c);
            let touches = (0..8).any(|k| {
                let n: [usize; 3] = std::array::from_fn(|a| c[a] + ((k >> a) & 1));
                if (0..3).any(|a| n[a] >= bd[a]) {
                    return false;
                }
                let t = grid.tile_value(n);
                t.is_none() || t != own
            });
            touches.then_some(c)
        })
        .collect()
}

/// Triangles of one block's cells with vertices named by global keys:
/// `3 * node + axis` for edge crossings, `3 * nodes + 4 * cell + k` for
/// loop centres (never shared).
struct BlockMesh {
    keys: Vec<u64>,
    vertices: Vec<(DVec3, DVec3)>,
    triangles: Vec<[u32; 3]>,
}

/// Nodes per axis of a block's cells (the block plus one layer beyond).
const SPAN: usize = BLOCK + 1;

/// Values of the nodes of a block's cells (`SPAN³`, x fastest); `None`
/// when all are on one side of `iso`, so the block has no crossing.
fn gather_block(
    grid: &BlockGrid<3>,
    iso: f64,
    lo: [usize; 3],
    nodes: [usize; 3],
) -> Option<Vec<f64>> {
    let mut vals = vec![0.0; SPAN * SPAN * SPAN];
    // The block itself and the (up to 7) blocks whose first node layer
    // closes its cells; copied block by block, no per-node lookup.
    for o in 0..8 {
        copy_block_part(
            grid,
            lo.map(|l| l / BLOCK),
            [o & 1, (o >> 1) & 1, o >> 2],
            nodes,
            &mut vals,
        );
    }
    let mut positive = 0usize;
    for z in 0..nodes[2] {
        for y in 0..nodes[1] {
            let row = SPAN * (y + SPAN * z);
            positive += vals[row..row + nodes[0]]
                .iter()
                .filter(|&&v| v >= iso)
                .count();
        }
    }
    let total = nodes.iter().product::<usize>();
    (positive != 0 && positive != total).then_some(vals)
}

/// Copy into `vals` the nodes that block `coord + off` contributes to the
/// cells of block `coord`: all of its own nodes for `off = 0`, else its
/// first layer along each axis where `off` is 1.
fn copy_block_part(
    grid: &BlockGrid<3>,
    coord: [usize; 3],
    off: [usize; 3],
    nodes: [usize; 3],
    vals: &mut [f64],
) {
    let range: [std::ops::Range<usize>; 3] = std::array::from_fn(|a| {
        if off[a] == 0 {
            0..nodes[a].min(BLOCK)
        } else {
            BLOCK..nodes[a]
        }
    });
    if range.iter().any(|r| r.is_empty()) {
        return;
    }
    let source: [usize; 3] = std::array::from_fn(|a| coord[a] + off[a]);
    let tile = grid.tile_value(source);
    let block = match tile {
        Some(_) => None,
        None => Some(&grid.blocks[grid.table[grid.block_linear(source)] as usize].values),
    };
    for z in range[2].clone() {
        for y in range[1].clone() {
            for x in range[0].clone() {
                vals[x + SPAN * (y + SPAN * z)] = match block {
                    Some(b) => {
                        b[local_index([x - off[0] * BLOCK, y - off[1] * BLOCK, z - off[2] * BLOCK])]
                    }
                    None => tile.unwrap_or(0.0),
                };
            }
        }
    }
}

fn block_mesh(grid: &BlockGrid<3>, iso: f64, coord: [usize; 3]) -> BlockMesh {
    let lo = coord.map(|c| c * BLOCK);
    // Cells of this block: lower corners from lo up to the block end or the
    // last node but one.
    let cells: [usize; 3] = std::array::from_fn(|a| {
        (lo[a] + BLOCK)
            .min(grid.spec.dims[a] - 1)
            .saturating_sub(lo[a])
    });
    let mut out = BlockEmitter {
        grid,
        iso,
        lo,
        ids: Vec::new(),
        mesh: BlockMesh {
            keys: Vec::new(),
            vertices: Vec::new(),
            triangles: Vec::new(),
        },
    };
    if cells.contains(&0) {
        return out.mesh;
    }
    let Some(vals) = gather_block(grid, iso, lo, cells.map(|c| c + 1)) else {
        return out.mesh;
    };
    out.ids = vec![u32::MAX; 3 * SPAN * SPAN * SPAN];
    for z in 0..cells[2] {
        for y in 0..cells[1] {
            for x in 0..cells[0] {
                let at =
                    |c: usize| x + (c & 1) + SPAN * (y + ((c >> 1) & 1) + SPAN * (z + (c >> 2)));
                let v: [f64; 8] = std::array::from_fn(|c| vals[at(c)]);
                out.cell([x, y, z], &v);
            }
        }
    }
    out.mesh
}

/// Builds one block's mesh: vertex ids per local edge (`3 * node + axis`
/// over the `SPAN³` local nodes), created on first use.
struct BlockEmitter<'a> {
    grid: &'a BlockGrid<3>,
    iso: f64,
    lo: [usize; 3],
    ids: Vec<u32>,
    mesh: BlockMesh,
}

impl BlockEmitter<'_> {
    /// Triangles of the cell at local position `p` with corner values `v`.
    fn cell(&mut self, p: [usize; 3], v: &[f64; 8]) {
        let (config, bits) = cell_case(v, self.iso);
        if config == 0 || config == 255 {
            return;
        }
        let edge_ids: [u32; 12] = std::array::from_fn(|e| {
            let [a, b] = EDGE_CORNERS[e];
            if (config >> a) & 1 == (config >> b) & 1 {
                return u32::MAX;
            }
            let a = a as usize;
            self.edge_vertex(
                [p[0] + (a & 1), p[1] + ((a >> 1) & 1), p[2] + (a >> 2)],
                e / 4,
            )
        });
        let table = cube_table();
        let spec = &self.grid.spec;
        let cell = spec.linear(std::array::from_fn(|k| self.lo[k] + p[k])) as u64;
        let mut centre_ids = [u32::MAX; MAX_LOOP_CENTRES];
        for (c, lp) in table.loop_centres(config, bits).iter().enumerate() {
            let centre = loop_centre(
                lp.iter()
                    .map(|&e| self.mesh.vertices[edge_ids[e as usize] as usize]),
            );
            // Centre keys lie past all edge keys and are never shared.
            centre_ids[c] = self.push(3 * spec.node_count() as u64 + 4 * cell + c as u64, centre);
        }
        for tri in table.triangles(config, bits) {
            let ids = tri.map(|e| {
                if e < 12 {
                    edge_ids[e as usize]
                } else {
                    centre_ids[e as usize - 12]
                }
            });
            self.mesh.triangles.push(ids);
        }
    }

    /// Id of the crossing on the edge from local node `n` along `axis`.
    fn edge_vertex(&mut self, n: [usize; 3], axis: usize) -> u32 {
        let slot = 3 * (n[0] + SPAN * (n[1] + SPAN * n[2])) + axis;
        if self.ids[slot] == u32::MAX {
            let node: [usize; 3] = std::array::from_fn(|k| self.lo[k] + n[k]);
            let key = 3 * self.grid.spec.linear(node) as u64 + axis as u64;
            self.ids[slot] = self.push(key, edge_vertex(self.grid, node, axis, self.iso));
        }
        self.ids[slot]
    }

    fn push(&mut self, key: u64, vertex: (DVec3, DVec3)) -> u32 {
        self.mesh.keys.push(key);
        self.mesh.vertices.push(vertex);
        (self.mesh.keys.len() - 1) as u32
    }
}

/// Join block meshes: one vertex per key, vertices sorted by key.
fn merge_block_meshes(parts: Vec<BlockMesh>) -> TriMesh {
    let mut all: Vec<(u64, u32, u32)> = parts
        .iter()
        .enumerate()
        .flat_map(|(p, m)| {
            m.keys
                .iter()
                .enumerate()
                .map(move |(l, &k)| (k, p as u32, l as u32))
        })
        .collect();
    all.par_sort_unstable();
    let mut offsets = vec![0usize; parts.len() + 1];
    for (p, m) in parts.iter().enumerate() {
        offsets[p + 1] = offsets[p] + m.keys.len();
    }
    let mut global = vec![0u32; offsets[parts.len()]];
    let (mut vertices, mut normals) = (Vec::new(), Vec::new());
    let mut last = None;
    for &(key, p, l) in &all {
        if last != Some(key) {
            let (pos, n) = parts[p as usize].vertices[l as usize];
            vertices.push(pos);
            normals.push(n);
            last = Some(key);
        }
        global[offsets[p as usize] + l as usize] = (vertices.len() - 1) as u32;
    }
    let triangles = parts
        .iter()
        .enumerate()
        .flat_map(|(p, m)| {
            let base = offsets[p];
            let global = &global;
            m.triangles
                .iter()
                .map(move |t| t.map(|v| global[base + v as usize]))
        })
        .collect();
    TriMesh {
        vertices,
        triangles,
        normals: Some(normals),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::marching::marching_cubes;
    use crate::marching::tests::{closed_manifold, cube_spec, sample3};
    use crate::Field2;

    /// Triangles as position triples, rotated to start at the smallest
    /// corner (orientation kept), sorted: equal for equal meshes whatever
    /// the vertex numbering.
    fn canonical(mesh: &TriMesh) -> Vec<[[u64; 3]; 3]> {
        let mut tris: Vec<[[u64; 3]; 3]> = mesh
            .triangles
            .iter()
            .map(|t| {
                let p = t.map(|i| mesh.vertices[i as usize].to_array().map(f64::to_bits));
                let m = (0..3).min_by_key(|&k| p[k]).unwrap();
                [p[m], p[(m + 1) % 3], p[(m + 2) % 3]]
            })
            .collect();
        tris.sort_unstable();
        tris
    }

    fn torus(p: DVec3) -> f64 {
        let q = (p.x * p.x + p.y * p.y).sqrt() - 0.5;
        (q * q + p.z * p.z).sqrt() - 0.2
    }

    #[test]
    fn get_set_and_neighbours_match_a_dense_field() {
        let spec = GridSpec::<2> {
            origin: [0.0; 2],
            spacing: 1.0,
            dims: [21, 13],
        };
        let mut dense = Field2::filled(spec, 5.0);
        let mut sparse = BlockGrid::new(spec, 5.0).unwrap();
        for (n, idx) in [[0, 0], [7, 7], [8, 7], [20, 12], [15, 3], [8, 8]]
            .into_iter()
            .enumerate()
        {
            dense.set(idx, n as f64);
            sparse.set(idx, n as f64);
        }
        assert_eq!(sparse.blocks().len(), 4);
        assert_eq!(sparse.to_dense(), dense);
        assert_eq!(sparse.neighbour([7, 7], 0, 1), Some(2.0));
        assert_eq!(sparse.neighbour([8, 8], 1, -1), Some(2.0));
        assert_eq!(sparse.neighbour([0, 0], 0, -1), None);
        assert_eq!(sparse.neighbour([20, 12], 1, 1), None);
        let (b, l) = sparse.locate([15, 3]).unwrap();
        assert_eq!(sparse.blocks()[b].node(l), [15, 3]);
        assert!(sparse.locate([3, 11]).is_none());
    }

    #[test]
    fn dense_band_round_trip_keeps_band_and_signs() {
        let spec = cube_spec(40, -1.0, 1.0);
        let field = sample3(spec, torus);
        let band = 3.0 * spec.spacing;
        let sparse = BlockGrid::from_dense_band(&field, band).unwrap();
        let back = sparse.to_dense();
        for (a, b) in field.values.iter().zip(&back.values) {
            if a.abs() < band {
                assert_eq!(a, b);
            } else {
                assert_eq!(a.signum(), b.signum());
            }
        }
        assert!(sparse.blocks().len() < sparse.table.len());
        // Signs of the tiles are also recovered from the band alone.
        let nodes: Vec<_> = sparse.iter_nodes().collect();
        let stored: std::collections::HashSet<[usize; 3]> = nodes.iter().map(|n| n.0).collect();
        assert_eq!(stored.len(), nodes.len(), "a node listed twice");
        for (l, &v) in field.values.iter().enumerate() {
            assert!(v.abs() >= band || stored.contains(&spec.unlinear(l)));
        }
        let rebuilt = BlockGrid::from_nodes(spec, band, nodes).unwrap();
        assert_eq!(rebuilt.to_dense(), back);
    }

    #[test]
    fn sparse_marching_cubes_equals_dense() {
        let spec = cube_spec(45, -1.0, 1.0);
        let field = sample3(spec, torus);
        let sparse = BlockGrid::from_dense_band(&field, 2.0 * spec.spacing).unwrap();
        let dense_mesh = marching_cubes(&sparse.to_dense(), 0.0);
        let sparse_mesh = marching_cubes_sparse(&sparse, 0.0);
        assert_eq!(canonical(&sparse_mesh), canonical(&dense_mesh));
        assert_eq!(sparse_mesh.vertices.len(), dense_mesh.vertices.len());
        let topo = closed_manifold(&sparse_mesh);
        assert_eq!((topo.euler, topo.components), (0, 1));
        // Same in a grid whose size is not a multiple of the block size,
        // at a non-zero iso.
        let spec = cube_spec(29, -1.0, 1.0);
        let sparse = BlockGrid::from_dense_band(&sample3(spec, torus), 0.3).unwrap();
        let iso = 0.05;
        assert_eq!(
            canonical(&marching_cubes_sparse(&sparse, iso)),
            canonical(&marching_cubes(&sparse.to_dense(), iso))
        );
    }

    #[test]
    fn narrow_band_uses_a_fraction_of_dense_memory() {
        let spec = cube_spec(200, -1.0, 1.0);
        let r = 0.8;
        let h = spec.spacing;
        // Only nodes within 3h of the sphere, computed directly.
        let nodes = (0..spec.node_count()).filter_map(|l| {
            let idx = spec.unlinear(l);
            let d = DVec3::from_array(spec.position(idx)).length() - r;
            (d.abs() < 3.0 * h).then_some((idx, d))
        });
        let grid = BlockGrid::from_nodes(spec, 3.0 * h, nodes).unwrap();
        let dense_bytes = spec.node_count() * 8;
        assert!(
            grid.memory_bytes() * 4 < dense_bytes,
            "{} vs {}",
            grid.memory_bytes(),
            dense_bytes
        );
        assert!(grid.get([100, 100, 100]) < 0.0, "centre tile is inside");
        assert!(grid.get([0, 0, 0]) > 0.0);
        let topo = closed_manifold(&marching_cubes_sparse(&grid, 0.0));
        assert_eq!((topo.euler, topo.components), (2, 1));
    }

    #[test]
    fn windows_and_released_blocks_match_node_access() {
        let spec = cube_spec(29, -1.0, 1.0);
        let mut grid = BlockGrid::from_dense_band(&sample3(spec, torus), 0.2).unwrap();
        let before = grid.to_dense();
        let check = |grid: &BlockGrid<3>| {
            let strides = BlockGrid::<3>::window_strides();
            let mut window = vec![0.0; BlockGrid::<3>::WINDOW_LEN];
            for blk in grid.blocks() {
                grid.gather_window(blk.coord, &mut window);
                for (w, &value) in window.iter().enumerate() {
                    let wc: [usize; 3] = std::array::from_fn(|a| w / strides[a] % WINDOW);
                    let node: [usize; 3] = std::array::from_fn(|a| blk.coord[a] * BLOCK + wc[a]);
                    // Window coordinate c is node coord*BLOCK + c - 1.
                    if node.contains(&0) {
                        continue;
                    }
                    let node = node.map(|n| n - 1);
                    if grid.in_grid(node) {
                        assert_eq!(value, grid.get(node), "{node:?}");
                    }
                }
                for local in [0, 7, 63, 511] {
                    let w = BlockGrid::<3>::window_index(local);
                    assert_eq!(window[w], blk.values[local]);
                }
                // Faces only: the same values there, edges left alone.
                let mut faces = vec![f64::NAN; window.len()];
                grid.gather_window_part(blk.coord, 1, &mut faces);
                for (w, (&f, &full)) in faces.iter().zip(&window).enumerate() {
                    let layers = (0..3)
                        .filter(|&a| [0, WINDOW - 1].contains(&(w / strides[a] % WINDOW)))
                        .count();
                    if layers <= 1 {
                        assert_eq!(f, full);
                    } else {
                        assert!(f.is_nan());
                    }
                }
            }
        };
        check(&grid);
        let count = grid.blocks().len();
        // Release every other block as an inside tile.
        let mut n = 0;
        let map = grid.release_blocks(|_| {
            n += 1;
            (n % 2 == 0).then_some(true)
        });
        assert_eq!(grid.blocks().len(), count.div_ceil(2));
        assert_eq!(map.iter().filter(|&&m| m == u32::MAX).count(), count / 2);
        check(&grid);
        for blk in grid.blocks() {
            let slot = grid.slot(blk.coord).unwrap();
            assert_eq!(grid.blocks()[slot].coord, blk.coord);
            for l in 0..Block::<3>::LEN {
                let node = blk.node(l);
                if grid.in_grid(node) {
                    assert_eq!(blk.values[l], before.get(node));
                }
            }
        }
    }

    #[test]
    fn bad_inputs_are_errors() {
        let spec = GridSpec::<2> {
            origin: [0.0; 2],
            spacing: 1.0,
            dims: [4, 4],
        };
        assert!(BlockGrid::new(spec, f64::NAN).is_err());
        assert!(BlockGrid::from_nodes(spec, 1.0, [([4, 0], 0.0)]).is_err());
    }
}
