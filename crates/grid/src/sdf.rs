//! Signed distance of a closed triangle mesh (negative inside).
//!
//! Magnitude: the unsigned distance to the triangles from
//! [`crate::distance`] (exact near the surface; closest-triangle
//! propagation elsewhere), over the whole grid or only in a narrow band.
//!
//! Sign: regions, then winding numbers. Two neighbouring nodes `a`, `b`
//! with `d(a) + d(b) > h` cannot have the surface between them (a crossing
//! point would be within `d(a)` of `a` and `d(b)` of `b`); the test keeps
//! a margin for rounding, since a face square to the edge gives
//! `d(a) + d(b) = h` exactly, up to rounding either way. The nodes split
//! into connected regions over such "free" edges; in a closed mesh each
//! region lies on one side. Each region is signed by the generalized
//! winding number (inside where it exceeds 1/2), evaluated with a
//! hierarchical approximation (a bounding-volume tree whose far clusters
//! act as dipoles) at a few sample nodes spread over the region. When the
//! samples disagree (a hole wider than a cell lets a region run inside and
//! out), every node of that region gets its own winding number. The
//! winding number degrades gracefully with cracks, holes and
//! self-intersections, so such defects never flip whole regions. For a
//! closed, consistently oriented mesh the nodes without a region verdict
//! (mostly those next to the surface, cut off from all neighbours) take
//! the exact winding number from the surface's signed crossings along
//! their grid row instead (`rows`): one pass per row, where a winding
//! number at a node beside the surface sums hundreds of solid angles.

use crate::distance::{rescale, unsigned_distance_with, DataSet, DistanceOptions};
use crate::{Field3, GridError, GridSpec};
use rayon::prelude::*;
use std::collections::HashMap;
use surfrecon_geom::{DVec3, TriMesh};

mod rows;

/// Regions at most this large get a winding number at every node.
const SMALL_REGION: usize = 64;
/// Sample nodes per large region.
const REGION_SAMPLES: usize = 24;
/// A tree cluster farther than this many cluster radii counts as a dipole.
const FAR_RATIO: f64 = 2.0;
/// Triangles per leaf of the winding-number tree.
const LEAF_SIZE: usize = 8;

/// Signed distance of `mesh` at the nodes of `spec`, negative inside.
///
/// `band: None` gives the full (dense) field. `band: Some(w)` computes
/// distances only within `w` of the surface and stores `±w` beyond (sign
/// still correct everywhere); `w` must be at least one grid spacing.
/// Refuses empty meshes, bad vertex indices, non-finite coordinates and
/// grids that do not fit in memory. Does not require the mesh to be closed;
/// for open meshes the sign follows the winding number (see module docs).
pub fn signed_distance(
    mesh: &TriMesh,
    spec: &GridSpec<3>,
    band: Option<f64>,
) -> Result<Field3, GridError> {
    if mesh.triangles.is_empty() {
        return Err(GridError::InvalidInput("the mesh has no triangles".into()));
    }
    let data = DataSet::<3>::from_mesh(mesh)?;
    if spec.node_count() >= u32::MAX as usize {
        return Err(GridError::InvalidInput(format!(
            "grid {} has too many nodes to sign (at most {} are supported)",
            spec.dims_string(),
            u32::MAX - 1
        )));
    }
    // The sign stage after the distance (which checks its own need), when
    // every node is a run and a region of its own: distances; run starts,
    // regions, grouping, region offsets and sizes; the nodes without a
    // region verdict, those a lattice may decide (8 bytes each), their sides
    // and winding flags.
    spec.check_memory(8 + 5 * 4 + 4 + 8 + 2 + 1)?;
    let options = match band {
        None => DistanceOptions::default(),
        Some(w) if w.is_finite() && w >= spec.spacing => DistanceOptions {
            band_cells: w / spec.spacing,
            propagate: false,
        },
        Some(w) => {
            return Err(GridError::InvalidInput(format!(
                "band must be at least one grid spacing ({}), got {w}",
                spec.spacing
            )))
        }
    };
    let closed = rows::closed_and_oriented(&mesh.triangles);
    // Huge or tiny coordinates: the winding numbers' products would leave
    // the f64 range, so the whole field is computed on a copy scaled by a
    // power of two (exact) and scaled back.
    if let Some(s) = rescale::unit_scale(&data, spec) {
        let mut field = signed_field(
            &data.scaled(s),
            &spec.scaled(s),
            &options,
            band.map(|w| w * s),
            closed,
        )?;
        field.spec = *spec;
        field.values.par_iter_mut().for_each(|v| *v /= s);
        return Ok(field);
    }
    signed_field(&data, spec, &options, band, closed)
}

/// Unsigned distances (clamped to the band), then the sign; `closed`:
/// the triangles form a closed, consistently oriented surface.
fn signed_field(
    data: &DataSet<3>,
    spec: &GridSpec<3>,
    options: &DistanceOptions,
    band: Option<f64>,
    closed: bool,
) -> Result<Field3, GridError> {
    let mut field = unsigned_distance_with(data, spec, options)?.field;
    if let Some(w) = band {
        field.values.par_iter_mut().for_each(|v| *v = v.min(w));
    }
    let tree = WindingTree::new(&data.triangles);
    let triangles = closed.then_some(data.triangles.as_slice());
    negate_inside(&mut field, &tree, triangles);
    Ok(field)
}

/// Refuse a mesh that is not closed: every edge must be shared by exactly
/// two triangles. The message counts boundary and over-shared edges.
pub fn check_closed(mesh: &TriMesh) -> Result<(), GridError> {
    if mesh.triangles.is_empty() {
        return Err(GridError::InvalidInput("the mesh has no triangles".into()));
    }
    let mut uses: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *uses.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let boundary = uses.values().filter(|&&n| n == 1).count();
    let over = uses.values().filter(|&&n| n > 2).count();
    if boundary == 0 && over == 0 {
        return Ok(());
    }
    Err(GridError::InvalidInput(format!(
        "the mesh is not closed: {boundary} boundary edges (used by one triangle) and \
         {over} edges used by more than two triangles; a signed distance needs a watertight mesh"
    )))
}

/// Negate the values of the nodes of `field` that lie inside (see the
/// module docs for the method). `closed`: the triangles of a closed,
/// consistently oriented surface, whose crossings along the grid rows
/// give exact winding numbers.
fn negate_inside(field: &mut Field3, tree: &WindingTree, closed: Option<&[[[f64; 3]; 3]]>) {
    let regions = Regions::new(field);
    let verdicts = regions.verdicts(field, tree);
    // Regions without a verdict (the nodes next to the surface, cut off
    // from their neighbours, most of all): a winding number per node,
    // interpolated where that is safe, or counted along rows.
    let undecided = regions.nodes_where(|region| verdicts[region].is_none());
    let per_node = match closed {
        Some(triangles) => rows::row_sides(&field.spec, triangles, &undecided),
        None => winding_sides(field, tree, &undecided),
    };
    regions.negate_runs(field, |region| verdicts[region] == Some(true));
    for (&l, _) in undecided.iter().zip(&per_node).filter(|(_, &ins)| ins) {
        field.values[l as usize] = -field.values[l as usize];
    }
}

/// Coarse lattice steps (in nodes) tried by [`winding_sides`], coarsest
/// first.
const COARSE_STEPS: [usize; 4] = [16, 8, 4, 2];
/// Winding numbers within this of 1/2 at a coarse corner are not trusted
/// to decide the nodes of its cells.
const WINDING_MARGIN: f64 = 0.2;

/// Inside (winding number above 1/2) for each node of `nodes`.
///
/// The winding number is harmonic away from the surface. A node farther
/// from the surface than the farthest corner of its cell in a lattice of
/// step S (at most the cell's diagonal) has no surface in that cell; when
/// the winding numbers at the cell's 8 corners all lie on one side of 1/2
/// by [`WINDING_MARGIN`], the node takes that side. Lattices from coarse to fine ([`COARSE_STEPS`]) decide the
/// nodes far, then less far, from the surface; the rest get their own
/// winding number. Leaky regions of scans with holes (all of the grid but
/// the surface's pockets) then cost a few evaluations per coarse cell
/// instead of one per node.
fn winding_sides(field: &Field3, tree: &WindingTree, nodes: &[u32]) -> Vec<bool> {
    let spec = field.spec;
    let mut side: Vec<Option<bool>> = vec![None; nodes.len()];
    for step in COARSE_STEPS {
        let lattice = Lattice::new(&spec, step);
        // Undecided nodes whose cell has no surface (NaN distances fail).
        let open: Vec<usize> = (0..nodes.len())
            .into_par_iter()
            .filter(|&k| {
                let l = nodes[k] as usize;
                let d = field.values[l];
                side[k].is_none() && d * d > lattice.reach_squared(&spec, spec.unlinear(l))
            })
            .collect();
        if open.is_empty() {
            continue;
        }
        let mut needed = vec![false; lattice.len()];
        for &k in &open {
            for c in lattice.corners(spec.unlinear(nodes[k] as usize)) {
                needed[c] = true;
            }
        }
        let winding: Vec<f64> = (0..needed.len())
            .into_par_iter()
            .map(|c| match needed[c] {
                true => tree.winding_number(lattice.position(&spec, c)),
                false => f64::NAN,
            })
            .collect();
        let decided: Vec<Option<bool>> = open
            .par_iter()
            .map(|&k| {
                let corners = lattice.corners(spec.unlinear(nodes[k] as usize));
                let (lo, hi) = corners
                    .map(|c| winding[c])
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), w| {
                        (lo.min(w), hi.max(w))
                    });
                (lo > 0.5 + WINDING_MARGIN || hi < 0.5 - WINDING_MARGIN).then_some(lo > 0.5)
            })
            .collect();
        for (&k, d) in open.iter().zip(decided) {
            side[k] = d;
        }
    }
    nodes
        .par_iter()
        .zip(&side)
        .map(|(&l, s)| {
            s.unwrap_or_else(|| {
                let p = spec.position(spec.unlinear(l as usize));
                tree.winding_number(DVec3::from_array(p)) > 0.5
            })
        })
        .collect()
}

/// The nodes of a grid whose indices are all multiples of `step` (the
/// last index on each axis clamped to the grid), as a coarse lattice.
struct Lattice {
    step: usize,
    /// Lattice points per axis.
    dims: [usize; 3],
}

impl Lattice {
    fn new(spec: &GridSpec<3>, step: usize) -> Self {
        Lattice {
            step,
            dims: spec.dims.map(|n| (n - 1).div_ceil(step) + 1),
        }
    }

    fn len(&self) -> usize {
        self.dims.iter().product()
    }

    /// Lattice indices of the 8 corners of the cell holding node `idx`.
    fn corners(&self, idx: [usize; 3]) -> impl Iterator<Item = usize> + '_ {
        let cell = idx.map(|i| i / self.step);
        (0..8).map(move |k| {
            let c: [usize; 3] =
                std::array::from_fn(|a| (cell[a] + (k >> a & 1)).min(self.dims[a] - 1));
            c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])
        })
    }

    /// Squared largest distance from node `idx` to a corner of its cell:
    /// the cell lies within that distance, as it is convex.
    fn reach_squared(&self, spec: &GridSpec<3>, idx: [usize; 3]) -> f64 {
        let cells: usize = (0..3)
            .map(|a| {
                let lo = idx[a] / self.step * self.step;
                let hi = (lo + self.step).min(spec.dims[a] - 1);
                (idx[a] - lo).max(hi - idx[a]).pow(2)
            })
            .sum();
        cells as f64 * spec.spacing * spec.spacing
    }

    /// Position of lattice point `c`.
    fn position(&self, spec: &GridSpec<3>, c: usize) -> DVec3 {
        let lattice = [
            c % self.dims[0],
            c / self.dims[0] % self.dims[1],
            c / (self.dims[0] * self.dims[1]),
        ];
        let idx = std::array::from_fn(|a| (lattice[a] * self.step).min(spec.dims[a] - 1));
        DVec3::from_array(spec.position(idx))
    }
}

/// The sum of two neighbours' distances above which no surface lies
/// between them: the spacing h, plus a margin for the rounding of node
/// positions and distances (relative to the coordinates' magnitude and
/// to h). Without it, the nodes on either side of a face square to their
/// edge, with distances summing to h exactly, were joined when rounding
/// put the sum a few ulps above h (an inside node of a box was signed
/// outside). Too small a sum only cuts an edge, which is always safe.
fn free_above(spec: &GridSpec<3>) -> f64 {
    let magnitude = spec
        .origin
        .iter()
        .chain(&spec.max_corner())
        .fold(spec.spacing, |m, c| m.max(c.abs()));
    spec.spacing * (1.0 + 1e-9) + 64.0 * f64::EPSILON * magnitude
}

/// Connected regions of nodes over free edges (`d(a) + d(b) >` [`free_above`]).
///
/// Built from runs: maximal segments of a grid row (along x) whose
/// consecutive nodes share free edges. The runs partition the nodes in index
/// order, so a run is just its first node, and regions are joined run by run
/// rather than node by node.
struct Regions {
    /// First node of each run, ascending, then the node count.
    run_start: Vec<u32>,
    /// Per row (`y + ny z`): index of its first run, then the run count.
    row_run: Vec<u32>,
    /// Region of each run; regions are numbered in order of their first node.
    run_region: Vec<u32>,
    /// Runs grouped by region, ascending within each.
    runs: Vec<u32>,
    /// Per region: its first entry in `runs`, then `runs.len()`.
    region_runs: Vec<u32>,
    /// Node count per region.
    sizes: Vec<u32>,
}

impl Regions {
    /// Layers (along z) per slab of the parallel joining; fixed, so the
    /// work split never depends on the thread count.
    const SLAB_LAYERS: usize = 8;

    fn new(field: &Field3) -> Self {
        let (run_start, row_run) = Self::runs(field);
        let mut regions = Regions {
            run_start,
            row_run,
            run_region: Vec::new(),
            runs: Vec::new(),
            region_runs: Vec::new(),
            sizes: Vec::new(),
        };
        let parent = regions.join(field);
        regions.group(parent);
        regions
    }

    /// First nodes of the runs and first runs of the rows (see the fields),
    /// one z layer per parallel task.
    fn runs(field: &Field3) -> (Vec<u32>, Vec<u32>) {
        let [nx, ny, nz] = field.spec.dims;
        let h = free_above(&field.spec);
        let layers: Vec<(Vec<u32>, Vec<u32>)> = field
            .values
            .par_chunks(nx * ny)
            .enumerate()
            .map(|(z, layer)| {
                let (mut starts, mut counts) = (Vec::new(), Vec::with_capacity(ny));
                for (y, row) in layer.chunks(nx).enumerate() {
                    let first = (z * ny + y) * nx;
                    let before = starts.len();
                    starts.push(first as u32);
                    Self::cuts(row, h, |x| starts.push((first + x) as u32));
                    counts.push((starts.len() - before) as u32);
                }
                (starts, counts)
            })
            .collect();
        let total: usize = layers.iter().map(|(s, _)| s.len()).sum();
        let mut run_start = Vec::with_capacity(total + 1);
        let mut row_run = Vec::with_capacity(ny * nz + 1);
        for (starts, counts) in layers {
            let mut next = run_start.len() as u32;
            for c in counts {
                row_run.push(next);
                next += c;
            }
            run_start.extend_from_slice(&starts);
        }
        row_run.push(run_start.len() as u32);
        run_start.push(field.values.len() as u32);
        (run_start, row_run)
    }

    /// Call `cut(x)` for each x (ascending) whose edge to x - 1 is not
    /// free (distances summing to at most `h`, see [`free_above`]).
    fn cuts(row: &[f64], h: f64, mut cut: impl FnMut(usize)) {
        // Most rows are mostly free: test blocks of edges without branches
        // (so the test vectorizes) and look closer only at blocks with a cut.
        const BLOCK: usize = 16;
        // A NaN distance fails the test, so it blocks its edges.
        let free = |a: f64, b: f64| a + b > h;
        let mut x = 1;
        while x < row.len() {
            let end = (x + BLOCK).min(row.len());
            let pairs = row[x - 1..end - 1].iter().zip(&row[x..end]);
            if pairs.fold(false, |any, (&a, &b)| any | !free(a, b)) {
                (x..end)
                    .filter(|&x| !free(row[x - 1], row[x]))
                    .for_each(&mut cut);
            }
            x = end;
        }
    }

    /// Union-find parents of the runs, joined over free y and z edges:
    /// within slabs of [`Self::SLAB_LAYERS`] layers in parallel, then across
    /// the slab boundaries.
    fn join(&self, field: &Field3) -> Vec<u32> {
        let [_, ny, nz] = field.spec.dims;
        let mut parent: Vec<u32> = (0..self.run_count() as u32).collect();
        // Split `parent` at the first run of each slab.
        let mut slabs = Vec::new();
        let mut rest = parent.as_mut_slice();
        let mut base = 0;
        for z in (0..nz).step_by(Self::SLAB_LAYERS) {
            let end = self.row_run[(z + Self::SLAB_LAYERS).min(nz) * ny] as usize;
            let (slab, tail) = rest.split_at_mut(end - base);
            slabs.push((z, base as u32, slab));
            rest = tail;
            base = end;
        }
        slabs.into_par_iter().for_each(|(z0, base, slab)| {
            for z in z0..(z0 + Self::SLAB_LAYERS).min(nz) {
                for y in 0..ny {
                    let row = y + ny * z;
                    if y > 0 {
                        self.join_rows(field, row - 1, row, slab, base);
                    }
                    if z > z0 {
                        self.join_rows(field, row - ny, row, slab, base);
                    }
                }
            }
        });
        for z in (Self::SLAB_LAYERS..nz).step_by(Self::SLAB_LAYERS) {
            for row in ny * z..ny * (z + 1) {
                self.join_rows(field, row - ny, row, &mut parent, 0);
            }
        }
        parent
    }

    fn run_count(&self) -> usize {
        self.run_start.len() - 1
    }

    /// Join the runs of rows `a` and `b` (neighbours along y or z) over
    /// their free edges. `parent` holds the parents of runs `base..`.
    ///
    /// Walks the overlaps of the two rows' runs: one free edge joins an
    /// overlapping pair, so the scan of an overlap stops at the first.
    fn join_rows(&self, field: &Field3, a: usize, b: usize, parent: &mut [u32], base: u32) {
        let nx = field.spec.dims[0];
        let h = free_above(&field.spec);
        let (row_a, row_b) = (&field.values[a * nx..][..nx], &field.values[b * nx..][..nx]);
        // End (in the row) of run `r` of row `row`: the next run's start,
        // which for the row's last run is the next row's first node (or the
        // sentinel).
        let end = |r: usize, row: usize| self.run_start[r + 1] as usize - row * nx;
        let (mut ra, mut rb) = (self.row_run[a] as usize, self.row_run[b] as usize);
        let mut x = 0;
        while x < nx {
            let (end_a, end_b) = (end(ra, a), end(rb, b));
            let stop = end_a.min(end_b);
            if (x..stop).any(|x| row_a[x] + row_b[x] > h) {
                union(parent, base, ra as u32, rb as u32);
            }
            x = stop;
            ra += usize::from(end_a == stop);
            rb += usize::from(end_b == stop);
        }
    }

    /// Number the regions in order of their first run and group the runs
    /// by region.
    fn group(&mut self, mut parent: Vec<u32>) {
        // Roots are the smallest runs of their sets and parents never
        // exceed their children, so in ascending order a run's parent
        // already holds its region number when the run is reached.
        let mut regions = 0u32;
        for r in 0..parent.len() {
            let p = parent[r] as usize;
            parent[r] = if p == r {
                regions += 1;
                regions - 1
            } else {
                parent[p]
            };
        }
        let mut sizes = vec![0u32; regions as usize];
        let mut next = vec![0u32; regions as usize + 1];
        for (r, &region) in parent.iter().enumerate() {
            sizes[region as usize] += self.run_len(r) as u32;
            next[region as usize + 1] += 1;
        }
        for i in 1..next.len() {
            next[i] += next[i - 1];
        }
        let region_runs = next.clone();
        let mut runs = vec![0u32; parent.len()];
        for (r, &region) in parent.iter().enumerate() {
            runs[next[region as usize] as usize] = r as u32;
            next[region as usize] += 1;
        }
        self.run_region = parent;
        self.runs = runs;
        self.region_runs = region_runs;
        self.sizes = sizes;
    }

    fn run_len(&self, r: usize) -> usize {
        (self.run_start[r + 1] - self.run_start[r]) as usize
    }

    /// The runs of `region`, ascending.
    fn runs_of(&self, region: usize) -> &[u32] {
        &self.runs[self.region_runs[region] as usize..self.region_runs[region + 1] as usize]
    }

    /// Per region: inside or outside when it is large and its winding
    /// numbers at [`REGION_SAMPLES`] nodes spread over it (evenly in index
    /// order) agree, else `None`.
    fn verdicts(&self, field: &Field3, tree: &WindingTree) -> Vec<Option<bool>> {
        let spec = field.spec;
        let position = |l: usize| DVec3::from_array(spec.position(spec.unlinear(l)));
        let large: Vec<usize> = (0..self.sizes.len())
            .filter(|&region| self.sizes[region] as usize > SMALL_REGION)
            .collect();
        let decided: Vec<Option<bool>> = large
            .par_iter()
            .map(|&region| {
                let samples = self.samples(region);
                let first = tree.winding_number(position(samples[0])) > 0.5;
                samples[1..]
                    .iter()
                    .all(|&l| (tree.winding_number(position(l)) > 0.5) == first)
                    .then_some(first)
            })
            .collect();
        let mut verdicts = vec![None; self.sizes.len()];
        for (&region, d) in large.iter().zip(decided) {
            verdicts[region] = d;
        }
        verdicts
    }

    /// The nodes of ranks `k len / REGION_SAMPLES` (k = 0, 1, ...) among
    /// the `len` nodes of `region` in index order.
    fn samples(&self, region: usize) -> Vec<usize> {
        let len = self.sizes[region] as usize;
        let mut ranks = (0..REGION_SAMPLES)
            .map(|k| k * len / REGION_SAMPLES)
            .peekable();
        let mut samples = Vec::with_capacity(REGION_SAMPLES);
        let mut passed = 0;
        for &r in self.runs_of(region) {
            let r = r as usize;
            let run_len = self.run_len(r);
            while let Some(rank) = ranks.next_if(|&rank| rank < passed + run_len) {
                samples.push(self.run_start[r] as usize + rank - passed);
            }
            passed += run_len;
        }
        samples
    }

    /// All nodes of the regions where `pick(region)` holds, ascending.
    fn nodes_where(&self, pick: impl Fn(usize) -> bool) -> Vec<u32> {
        let mut nodes = Vec::new();
        for (r, &region) in self.run_region.iter().enumerate() {
            if pick(region as usize) {
                nodes.extend(self.run_start[r]..self.run_start[r + 1]);
            }
        }
        nodes
    }

    /// Negate the values of the nodes of the regions where
    /// `inside(region)` holds, one z layer per parallel task.
    fn negate_runs(&self, field: &mut Field3, inside: impl Fn(usize) -> bool + Sync) {
        let [nx, ny, _] = field.spec.dims;
        let layer = nx * ny;
        field
            .values
            .par_chunks_mut(layer)
            .enumerate()
            .for_each(|(z, values)| {
                let runs = self.row_run[z * ny] as usize..self.row_run[(z + 1) * ny] as usize;
                for r in runs.filter(|&r| inside(self.run_region[r] as usize)) {
                    let start = self.run_start[r] as usize - z * layer;
                    for v in &mut values[start..start + self.run_len(r)] {
                        *v = -*v;
                    }
                }
            });
    }
}

/// Root of `x` in the union-find forest over ids `base..` (`parent[i]` is
/// the parent of id `base + i`), halving the path.
fn find(parent: &mut [u32], base: u32, mut x: u32) -> u32 {
    loop {
        let p = parent[(x - base) as usize];
        if p == x {
            return x;
        }
        let up = parent[(p - base) as usize];
        parent[(x - base) as usize] = up;
        x = up;
    }
}

/// Join the sets of `a` and `b` under the smaller root, so roots are the
/// smallest ids of their sets and every parent is below its child.
fn union(parent: &mut [u32], base: u32, a: u32, b: u32) {
    let (ra, rb) = (find(parent, base, a), find(parent, base, b));
    let (lo, hi) = (ra.min(rb), ra.max(rb));
    parent[(hi - base) as usize] = lo;
}

/// Bounding-volume tree over triangles for fast generalized winding
/// numbers: a cluster far from the query (relative to its radius) is
/// replaced by a dipole, its area-weighted normal at its area centroid.
pub struct WindingTree {
    triangles: Vec<[DVec3; 3]>,
    nodes: Vec<Cluster>,
}

#[derive(Default)]
struct Cluster {
    /// Area-weighted centroid of the triangles.
    centre: DVec3,
    /// Sum of the triangles' vector areas (half cross products).
    vector_area: DVec3,
    /// Squared distance beyond which the cluster counts as a dipole:
    /// [`FAR_RATIO`] times the largest distance from `centre` to a triangle
    /// corner, squared.
    far_squared: f64,
    /// Triangle range `start..end` in the tree's order.
    start: usize,
    end: usize,
    /// Clusters are stored depth first, so the first child of cluster `i`
    /// is `i + 1`; the second is `i + second`. Zero for leaves.
    second: usize,
}

/// Subtrees with more triangles than this build their halves in parallel.
const PARALLEL_BUILD: usize = 4096;

impl Cluster {
    /// Append to `out` the subtree over `tris` (triangles `offset..` of the
    /// tree), depth first, reordering `tris` by the splits. Returns the
    /// subtree's moments: a cluster's are the sums of its children's, so
    /// only leaves visit their triangles for them.
    fn build(tris: &mut [[DVec3; 3]], offset: usize, out: &mut Vec<Cluster>) -> Moments {
        let count = tris.len();
        if count <= LEAF_SIZE {
            let moments = Moments::of(tris);
            out.push(Cluster::new(tris, offset, &moments, 0));
            return moments;
        }
        let id = out.len();
        out.push(Cluster::default());
        let mid = split(tris);
        let (lo, hi) = tris.split_at_mut(mid);
        let (left, right, second) = if count <= PARALLEL_BUILD {
            let left = Cluster::build(lo, offset, out);
            let second = out.len() - id;
            (left, Cluster::build(hi, offset + mid, out), second)
        } else {
            let subtree = |tris: &mut [[DVec3; 3]], offset| {
                let mut nodes = Vec::new();
                let moments = Cluster::build(tris, offset, &mut nodes);
                (nodes, moments)
            };
            let ((left_nodes, left), (right_nodes, right)) =
                rayon::join(|| subtree(lo, offset), || subtree(hi, offset + mid));
            let second = 1 + left_nodes.len();
            out.extend(left_nodes);
            out.extend(right_nodes);
            (left, right, second)
        };
        let moments = left.add(&right);
        out[id] = Cluster::new(tris, offset, &moments, second);
        moments
    }

    /// The cluster over `tris` (triangles `offset..` of the tree) with
    /// `moments`, its second child at `second`.
    fn new(tris: &[[DVec3; 3]], offset: usize, moments: &Moments, second: usize) -> Cluster {
        let centre = moments.centre(tris.len());
        let radius_squared = tris
            .iter()
            .flatten()
            .map(|p| p.distance_squared(centre))
            .fold(0.0, f64::max);
        Cluster {
            centre,
            vector_area: moments.vector_area,
            far_squared: FAR_RATIO * FAR_RATIO * radius_squared,
            start: offset,
            end: offset + tris.len(),
            second,
        }
    }
}

/// Sums over a cluster's triangles.
#[derive(Clone, Copy, Default)]
struct Moments {
    vector_area: DVec3,
    /// Areas times centroids.
    weighted: DVec3,
    area: f64,
    /// Centroids (for clusters without area).
    centroids: DVec3,
}

impl Moments {
    fn of(tris: &[[DVec3; 3]]) -> Moments {
        tris.iter().fold(Moments::default(), |m, [a, b, c]| {
            let vector_area = 0.5 * (*b - *a).cross(*c - *a);
            let area = vector_area.length();
            let centroid = (*a + *b + *c) / 3.0;
            m.add(&Moments {
                vector_area,
                weighted: area * centroid,
                area,
                centroids: centroid,
            })
        })
    }

    fn add(&self, other: &Moments) -> Moments {
        Moments {
            vector_area: self.vector_area + other.vector_area,
            weighted: self.weighted + other.weighted,
            area: self.area + other.area,
            centroids: self.centroids + other.centroids,
        }
    }

    /// Area-weighted centroid of `count` triangles, or their mean centroid
    /// when they have no area.
    fn centre(&self, count: usize) -> DVec3 {
        if self.area > 0.0 {
            self.weighted / self.area
        } else {
            self.centroids / count as f64
        }
    }
}

/// Reorder `tris` about the median centroid along the widest axis; returns
/// the split position.
fn split(tris: &mut [[DVec3; 3]]) -> usize {
    let centroid = |t: &[DVec3; 3]| (t[0] + t[1] + t[2]) / 3.0;
    let (lo, hi) = tris.iter().map(centroid).fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), c| (lo.min(c), hi.max(c)),
    );
    let axis = (hi - lo).max_position();
    let key = |t: &[DVec3; 3]| centroid(t)[axis];
    // Find the median key among the keys alone, then move the triangles
    // below it first and those equal to it next (cheaper than selecting
    // the triangles themselves): the first `mid` are then a lower half.
    let mut keys: Vec<f64> = tris.iter().map(key).collect();
    let mid = tris.len() / 2;
    let median = *keys.select_nth_unstable_by(mid, f64::total_cmp).1;
    let below = partition(tris, |t| key(t).total_cmp(&median).is_lt());
    partition(&mut tris[below..], |t| key(t) == median);
    mid
}

/// Move the triangles where `first` holds to the front (stably for
/// those); returns their count.
fn partition(tris: &mut [[DVec3; 3]], first: impl Fn(&[DVec3; 3]) -> bool) -> usize {
    let mut count = 0;
    for k in 0..tris.len() {
        if first(&tris[k]) {
            tris.swap(count, k);
            count += 1;
        }
    }
    count
}

impl WindingTree {
    /// The tree over the triangles of `mesh` (indices must be valid).
    pub fn of_mesh(mesh: &TriMesh) -> Self {
        let triangles: Vec<[[f64; 3]; 3]> = (0..mesh.triangles.len())
            .map(|t| mesh.corners(t).map(|c| c.to_array()))
            .collect();
        Self::new(&triangles)
    }

    fn new(triangles: &[[[f64; 3]; 3]]) -> Self {
        let mut triangles: Vec<[DVec3; 3]> =
            triangles.iter().map(|t| t.map(DVec3::from_array)).collect();
        let mut nodes = Vec::new();
        Cluster::build(&mut triangles, 0, &mut nodes);
        WindingTree { triangles, nodes }
    }

    /// Generalized winding number at `q` (1 inside a closed outward mesh,
    /// 0 outside).
    pub fn winding_number(&self, q: DVec3) -> f64 {
        let mut total = 0.0;
        // Each pop pushes at most two, so the stack never exceeds the depth
        // plus one; halving splits keep the depth below 64.
        let mut stack = [0usize; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let i = stack[top];
            let c = &self.nodes[i];
            let r = c.centre - q;
            let dist_squared = r.length_squared();
            if dist_squared > c.far_squared {
                let dist = dist_squared.sqrt();
                total += c.vector_area.dot(r) / (dist_squared * dist);
                continue;
            }
            match c.second {
                0 => {
                    total += self.triangles[c.start..c.end]
                        .iter()
                        .map(|t| solid_angle(t, q))
                        .sum::<f64>()
                }
                second => {
                    stack[top] = i + 1;
                    stack[top + 1] = i + second;
                    top += 2;
                }
            }
        }
        total / (4.0 * std::f64::consts::PI)
    }
}

/// Signed solid angle of triangle `t` seen from `q` (Van Oosterom and
/// Strackee): positive when `q` is behind the triangle's front side.
fn solid_angle(t: &[DVec3; 3], q: DVec3) -> f64 {
    let [a, b, c] = t.map(|p| p - q);
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let num = a.dot(b.cross(c));
    let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    2.0 * num.atan2(den)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::GridSize;
    use surfrecon_geom::shapes;

    fn grid_around(mesh: &TriMesh, cells: usize) -> GridSpec<3> {
        let b = mesh.bounds();
        GridSpec::from_bounds(
            b.min.to_array(),
            b.max.to_array(),
            GridSize::Resolution(cells),
            4,
        )
        .unwrap()
    }

    /// Max |field - exact| (nodes where `exact` is NaN are skipped), checking
    /// signs where |exact| exceeds `sign_margin`.
    fn compare(field: &Field3, exact: impl Fn(DVec3) -> f64 + Sync, sign_margin: f64) -> f64 {
        let spec = field.spec;
        (0..spec.node_count())
            .into_par_iter()
            .map(|l| {
                let p = DVec3::from_array(spec.position(spec.unlinear(l)));
                let (got, want) = (field.values[l], exact(p));
                if want.is_nan() {
                    return 0.0;
                }
                if want.abs() > sign_margin {
                    assert_eq!(
                        got < 0.0,
                        want < 0.0,
                        "sign at {p}: got {got}, exact {want}"
                    );
                }
                (got - want).abs()
            })
            .reduce(|| 0.0, f64::max)
    }

    /// How far the planes of a sphere mesh's flat triangles sink below the
    /// sphere (bounds the Hausdorff distance between mesh and sphere).
    fn sphere_tessellation_error(mesh: &TriMesh, centre: DVec3, radius: f64) -> f64 {
        (0..mesh.triangles.len())
            .map(|t| {
                let [a, b, c] = mesh.corners(t);
                let n = (b - a).cross(c - a).normalize();
                radius - n.dot(a - centre).abs()
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn sphere_matches_exact_sdf() {
        let centre = DVec3::new(0.1, -0.2, 0.3);
        let mesh = shapes::icosphere(centre, 1.0, 4);
        let spec = grid_around(&mesh, 40);
        let field = signed_distance(&mesh, &spec, None).unwrap();
        let tess = sphere_tessellation_error(&mesh, centre, 1.0);
        let data = DataSet::<3>::from_mesh(&mesh).unwrap();
        let brute = |p: DVec3| {
            (0..data.len())
                .map(|i| data.distance(i, &p.to_array()))
                .fold(f64::INFINITY, f64::min)
        };
        // Brute force on every 5th node (5120 triangles each), split into
        // within 5 h of the surface and beyond.
        let h = spec.spacing;
        let (near, far) = (0..spec.node_count())
            .into_par_iter()
            .step_by(5)
            .map(|l| {
                let p = DVec3::from_array(spec.position(spec.unlinear(l)));
                let exact = brute(p);
                let e = (field.values[l].abs() - exact).abs();
                if exact <= 5.0 * h {
                    (e, 0.0)
                } else {
                    (0.0, e)
                }
            })
            .reduce(|| (0.0, 0.0), |a, b| (a.0.max(b.0), a.1.max(b.1)));
        println!(
            "sphere SDF unsigned error: {:.2e} h near, {:.2e} h far",
            near / h,
            far / h
        );
        assert!(near <= 0.05 * h, "near error {near}");
        // Far from the surface, propagation is near-exact (see
        // `distance::propagate`).
        assert!(far <= 0.2 * h, "far error {far}");
        let err = compare(&field, |p| (p - centre).length() - 1.0, tess + far);
        assert!(
            err <= tess + far + 1e-12,
            "error {err}, tessellation {tess}"
        );
    }

    #[test]
    fn cube_with_sharp_edges_is_exact() {
        let (lo, hi) = (DVec3::new(-1.0, -0.5, -0.25), DVec3::new(1.0, 0.5, 0.75));
        let mesh = shapes::cuboid(lo, hi);
        let spec = grid_around(&mesh, 36);
        let field = signed_distance(&mesh, &spec, None).unwrap();
        let centre = 0.5 * (lo + hi);
        let half = 0.5 * (hi - lo);
        let exact = |p: DVec3| {
            let q = (p - centre).abs() - half;
            q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
        };
        let err = compare(&field, exact, 1e-9);
        assert!(err < 1e-9, "error {err}");
    }

    #[test]
    fn torus_matches_exact_sdf() {
        let (major, minor) = (1.0, 0.35);
        let mesh = shapes::torus(major, minor, 96, 48);
        let spec = grid_around(&mesh, 48);
        let field = signed_distance(&mesh, &spec, None).unwrap();
        let exact = |p: DVec3| {
            let ring = (p.x * p.x + p.y * p.y).sqrt() - major;
            (ring * ring + p.z * p.z).sqrt() - minor
        };
        // Chord sag of the two tessellation directions.
        let sag = (major + minor) * (1.0 - (std::f64::consts::PI / 96.0).cos())
            + minor * (1.0 - (std::f64::consts::PI / 48.0).cos());
        let h = spec.spacing;
        let near = |p: DVec3| exact(p).abs() <= 5.0 * h;
        let near_err = compare(
            &field,
            |p| if near(p) { exact(p) } else { f64::NAN },
            2.0 * sag,
        );
        let far_err = compare(
            &field,
            |p| if near(p) { f64::NAN } else { exact(p) },
            2.0 * sag,
        );
        println!(
            "torus SDF error: near {:.2e} h, far {:.2e} h, sag {:.2e} h",
            near_err / h,
            far_err / h,
            sag / h
        );
        assert!(near_err <= 2.0 * sag, "near error {near_err}, sag {sag}");
        assert!(
            far_err <= 2.0 * sag + 0.2 * h,
            "far error {far_err}, sag {sag}"
        );
    }

    #[test]
    fn sphere_with_a_missing_triangle_still_signs_correctly() {
        let mut mesh = shapes::icosphere(DVec3::ZERO, 1.0, 3);
        mesh.triangles.remove(100);
        assert!(check_closed(&mesh).is_err());
        let spec = grid_around(&mesh, 40);
        let field = signed_distance(&mesh, &spec, None).unwrap();
        let tess = sphere_tessellation_error(&mesh, DVec3::ZERO, 1.0);
        // Near the hole the distance is to its rim, so only signs are checked
        // away from the surface.
        compare(&field, |p| p.length() - 1.0, tess + 2.0 * spec.spacing);
    }

    /// A hole many cells wide lets the outside region leak in, so its
    /// nodes are signed by (interpolated) winding numbers: the signs must
    /// equal the exact winding number's at every node.
    #[test]
    fn wide_hole_signs_match_exact_winding_numbers() {
        let mut mesh = shapes::icosphere(DVec3::ZERO, 1.0, 3);
        // Drop every triangle with a corner in a cap around +z.
        mesh.triangles
            .retain(|t| t.iter().all(|&i| mesh.vertices[i as usize].z < 0.8));
        let spec = grid_around(&mesh, 40);
        let field = signed_distance(&mesh, &spec, None).unwrap();
        let data = DataSet::<3>::from_mesh(&mesh).unwrap();
        let tree = WindingTree::new(&data.triangles);
        let wrong = (0..spec.node_count())
            .into_par_iter()
            .filter(|&l| {
                let p = DVec3::from_array(spec.position(spec.unlinear(l)));
                let exact = tree.winding_number(p);
                // Exactly on the surface either side is right.
                field.values[l] != 0.0 && (field.values[l] < 0.0) != (exact > 0.5)
            })
            .count();
        assert_eq!(wrong, 0);
    }

    #[test]
    fn overlapping_spheres_sign_as_their_union() {
        let a = shapes::icosphere(DVec3::new(-0.4, 0.0, 0.0), 0.7, 3);
        let b = shapes::icosphere(DVec3::new(0.4, 0.0, 0.0), 0.7, 3);
        let offset = a.vertices.len() as u32;
        let mesh = TriMesh {
            vertices: [a.vertices.clone(), b.vertices.clone()].concat(),
            triangles: a
                .triangles
                .iter()
                .copied()
                .chain(b.triangles.iter().map(|t| t.map(|i| i + offset)))
                .collect(),
            normals: None,
        };
        let spec = grid_around(&mesh, 40);
        let field = signed_distance(&mesh, &spec, None).unwrap();
        let tess = sphere_tessellation_error(&a, DVec3::new(-0.4, 0.0, 0.0), 0.7);
        let union = |p: DVec3| {
            let da = (p - DVec3::new(-0.4, 0.0, 0.0)).length() - 0.7;
            let db = (p - DVec3::new(0.4, 0.0, 0.0)).length() - 0.7;
            da.min(db)
        };
        compare(&field, union, tess + 1e-9);
    }

    #[test]
    fn narrow_band_matches_dense_inside_and_clamps_outside() {
        let mesh = shapes::icosphere(DVec3::ZERO, 1.0, 3);
        let spec = grid_around(&mesh, 32);
        let dense = signed_distance(&mesh, &spec, None).unwrap();
        let w = 3.0 * spec.spacing;
        let band = signed_distance(&mesh, &spec, Some(w)).unwrap();
        for (d, b) in dense.values.iter().zip(&band.values) {
            if d.abs() <= w {
                assert_eq!(d, b);
            } else {
                assert_eq!(*b, w.copysign(*d));
            }
        }
        assert!(signed_distance(&mesh, &spec, Some(0.1 * spec.spacing)).is_err());
        assert!(signed_distance(&mesh, &spec, Some(f64::NAN)).is_err());
    }

    #[test]
    fn closed_check_and_bad_meshes() {
        assert!(check_closed(&shapes::torus(1.0, 0.3, 12, 8)).is_ok());
        let mut open = shapes::cuboid(DVec3::ZERO, DVec3::ONE);
        open.triangles.pop();
        let msg = check_closed(&open).unwrap_err().to_string();
        assert!(msg.contains("3 boundary edges"), "{msg}");
        let spec = grid_around(&shapes::cuboid(DVec3::ZERO, DVec3::ONE), 8);
        assert!(signed_distance(&TriMesh::default(), &spec, None).is_err());
        let bad = TriMesh {
            vertices: vec![DVec3::ZERO; 3],
            triangles: vec![[0, 1, 5]],
            normals: None,
        };
        assert!(signed_distance(&bad, &spec, None).is_err());
    }

    /// Per node: its flood-fill component over free edges, components
    /// numbered in order of their first node.
    fn flood_fill(field: &Field3) -> Vec<u32> {
        let spec = field.spec;
        let strides = spec.strides();
        let mut component = vec![u32::MAX; spec.node_count()];
        let mut count = 0;
        for seed in 0..spec.node_count() {
            if component[seed] != u32::MAX {
                continue;
            }
            component[seed] = count;
            let mut stack = vec![seed];
            while let Some(l) = stack.pop() {
                let idx = spec.unlinear(l);
                for a in 0..3 {
                    let lower = (idx[a] > 0).then(|| l - strides[a]);
                    let upper = (idx[a] + 1 < spec.dims[a]).then(|| l + strides[a]);
                    for m in lower.into_iter().chain(upper) {
                        let free = field.values[l] + field.values[m] > free_above(&spec);
                        if free && component[m] == u32::MAX {
                            component[m] = count;
                            stack.push(m);
                        }
                    }
                }
            }
            count += 1;
        }
        component
    }

    /// Regions joined run by run (over several slabs, with NaN distances
    /// blocking their edges) equal a node-by-node flood fill, and their
    /// samples are the nodes of the promised ranks. Random fields below,
    /// near and above the percolation threshold give regions of all sizes.
    #[test]
    fn regions_match_a_flood_fill() {
        use rand::{Rng, SeedableRng};
        let spec = GridSpec::<3> {
            origin: [0.0; 3],
            spacing: 1.0,
            dims: [13, 7, 27],
        };
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        for scale in [0.7, 0.9, 1.4] {
            let values = (0..spec.node_count())
                .map(|_| match rng.random::<f64>() {
                    u if u < 0.01 => f64::NAN,
                    _ => scale * rng.random::<f64>(),
                })
                .collect();
            let field = Field3 { spec, values };
            let component = flood_fill(&field);
            let regions = Regions::new(&field);
            let mut region = vec![u32::MAX; spec.node_count()];
            for r in 0..regions.run_count() {
                let nodes = regions.run_start[r] as usize..regions.run_start[r + 1] as usize;
                region[nodes].fill(regions.run_region[r]);
            }
            assert_eq!(region, component, "scale {scale}");
            let mut members = vec![Vec::new(); regions.sizes.len()];
            for (l, &c) in component.iter().enumerate() {
                members[c as usize].push(l);
            }
            let largest = members.iter().map(Vec::len).max().unwrap_or(0);
            println!(
                "scale {scale}: {} regions, largest {largest}",
                members.len()
            );
            for (c, nodes) in members.iter().enumerate() {
                assert_eq!(regions.sizes[c] as usize, nodes.len());
                let want: Vec<usize> = (0..REGION_SAMPLES)
                    .map(|k| nodes[k * nodes.len() / REGION_SAMPLES])
                    .collect();
                assert_eq!(regions.samples(c), want);
            }
            let odd: Vec<u32> = (0..spec.node_count() as u32)
                .filter(|&l| component[l as usize] % 2 == 1)
                .collect();
            assert_eq!(regions.nodes_where(|c| c % 2 == 1), odd);
        }
    }

    /// A node's reach is its distance to the farthest corner of its cell,
    /// clamped cells at the grid's far ends included.
    #[test]
    fn lattice_reach_is_the_farthest_corner() {
        let spec = GridSpec::<3> {
            origin: [0.5, -1.0, 2.0],
            spacing: 0.3,
            dims: [11, 6, 17],
        };
        for step in COARSE_STEPS {
            let lattice = Lattice::new(&spec, step);
            for l in 0..spec.node_count() {
                let idx = spec.unlinear(l);
                let p = DVec3::from_array(spec.position(idx));
                let farthest = lattice
                    .corners(idx)
                    .map(|c| lattice.position(&spec, c).distance_squared(p))
                    .fold(0.0, f64::max);
                let reach = lattice.reach_squared(&spec, idx);
                assert!((reach - farthest).abs() < 1e-9, "step {step}, node {idx:?}");
            }
        }
    }

    /// Many copies of a triangle collapsed onto a cube edge (equal
    /// centroids, no area) change neither distances nor signs.
    #[test]
    fn collapsed_duplicate_triangles_change_nothing() {
        let cube = shapes::cuboid(DVec3::splat(-0.5), DVec3::splat(0.5));
        let [a, b, _] = cube.triangles[0];
        let mut padded = cube.clone();
        padded.triangles.extend(std::iter::repeat_n([a, a, b], 40));
        let spec = grid_around(&cube, 20);
        let plain = signed_distance(&cube, &spec, None).unwrap();
        let field = signed_distance(&padded, &spec, None).unwrap();
        for (p, f) in plain.values.iter().zip(&field.values) {
            assert_eq!(p.abs(), f.abs());
            assert!(*p == 0.0 || (*p < 0.0) == (*f < 0.0), "{p} vs {f}");
        }
    }

    /// The sign stage gives the same bits on one thread and on three.
    #[test]
    fn signs_do_not_depend_on_the_thread_count() {
        let mut mesh = shapes::icosphere(DVec3::ZERO, 1.0, 3);
        mesh.triangles
            .retain(|t| t.iter().all(|&i| mesh.vertices[i as usize].z < 0.8));
        let spec = grid_around(&mesh, 40);
        let data = DataSet::<3>::from_mesh(&mesh).unwrap();
        let unsigned = unsigned_distance_with(&data, &spec, &DistanceOptions::default())
            .unwrap()
            .field;
        let signed = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let mut field = unsigned.clone();
                negate_inside(&mut field, &WindingTree::new(&data.triangles), None);
                field.values.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            })
        };
        assert_eq!(signed(1), signed(3));
    }

    /// A closed mesh's nodes signed by crossings along rows get the signs
    /// of the winding numbers, also where the grid's rows pass through
    /// the mesh's vertices and edges (a box whose faces and corners lie
    /// on grid nodes, and a torus).
    #[test]
    fn row_crossings_sign_like_winding_numbers() {
        let meshes = [
            shapes::cuboid(DVec3::splat(-1.0), DVec3::splat(1.0)),
            shapes::torus(1.0, 0.4, 40, 20),
        ];
        for mesh in meshes {
            assert!(rows::closed_and_oriented(&mesh.triangles));
            let spec =
                GridSpec::from_bounds([-1.5; 3], [1.5; 3], crate::GridSize::Resolution(24), 0)
                    .unwrap();
            let data = DataSet::<3>::from_mesh(&mesh).unwrap();
            let unsigned = unsigned_distance_with(&data, &spec, &DistanceOptions::default())
                .unwrap()
                .field;
            let tree = WindingTree::new(&data.triangles);
            let mut by_rows = unsigned.clone();
            negate_inside(&mut by_rows, &tree, Some(&data.triangles));
            let mut by_winding = unsigned.clone();
            negate_inside(&mut by_winding, &tree, None);
            let mut inside = 0;
            for (r, w) in by_rows.values.iter().zip(&by_winding.values) {
                // On the surface either side is right.
                assert!(*r == 0.0 || (*r < 0.0) == (*w < 0.0), "{r} vs {w}");
                inside += (*r < 0.0) as usize;
            }
            assert!(inside > 0);
        }
    }

    #[test]
    fn winding_number_tree_matches_exact_sum() {
        let mesh = shapes::torus(1.0, 0.4, 40, 20);
        let data = DataSet::<3>::from_mesh(&mesh).unwrap();
        let tree = WindingTree::new(&data.triangles);
        for q in [
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.3, 0.1, 0.2),
            DVec3::new(3.0, -2.0, 1.0),
            DVec3::new(0.0, -1.1, 0.1),
        ] {
            let exact: f64 = tree
                .triangles
                .iter()
                .map(|t| solid_angle(t, q))
                .sum::<f64>()
                / (4.0 * std::f64::consts::PI);
            let fast = tree.winding_number(q);
            // The dipole approximation is a few percent off: ample to
            // decide inside (> 1/2) away from the surface.
            assert!((exact - fast).abs() < 0.05, "{q}: {exact} vs {fast}");
        }
    }
}
