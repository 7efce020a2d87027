//! Surface-following meshing of a fitted model: evaluate f only at grid
//! nodes of cells near the zero set, found by growing from the cells that
//! hold the data points, then run the grid crate's sparse marching cubes.
//!
//! Growth is breadth first over blocks of 4³ cells, in waves: every wave
//! evaluates the nodes of its blocks in parallel (batched per block), and a
//! cell on a block's rim passes growth on to the blocks it touches when its
//! corners change sign or one of them is within a cell diagonal of zero
//! (f approximates the signed distance, so any cell the surface crosses
//! qualifies). Waves are sorted, so the result does not depend on the
//! thread count.

use crate::bridges::{fill_pinholes, join_and_reach_thin_parts};
use crate::cells::{FastMap, FastSet};
use crate::error::{Result, SvmError};
use crate::model::SvmModel;
use glam::DVec3;
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::{Aabb, TriMesh};
use surfrecon_grid::sparse::{marching_cubes_sparse, BlockGrid};
use surfrecon_grid::{GridSize, GridSpec};

/// How finely to mesh.
#[derive(Clone, Copy, Debug)]
pub struct MeshOptions {
    /// Cells along the longest axis of the (padded) data bounds.
    pub resolution: usize,
    /// Extra room around the data bounds, relative to their diagonal, so
    /// surfaces that bulge past the data (e.g. over holes) stay closed.
    pub margin: f64,
    /// The noise of the data the seeds come from (RMS distance from the
    /// surface, world units): 0 for exact samples. Below this scale the
    /// data cannot tell a pinch of f from a thin part, so data this much
    /// farther off a pinch still run across it (see
    /// [`crate::bridges::bridge_thin_parts`]).
    pub data_noise: f64,
}

impl Default for MeshOptions {
    fn default() -> Self {
        MeshOptions {
            resolution: 128,
            margin: 0.05,
            data_noise: 0.0,
        }
    }
}

/// Counts from a meshing run.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshReport {
    pub grid_dims: [usize; 3],
    pub spacing: f64,
    /// Cells visited by the surface-following growth.
    pub cells_visited: usize,
    /// Grid nodes where f was evaluated.
    pub nodes_evaluated: usize,
    /// Closed pieces dropped from the mesh: smaller than [`SPECK_CELLS`],
    /// or away from the data ([`DATA_CELLS`]).
    pub specks_removed: usize,
    /// Pieces of f's inside joined where they are thinner than a cell
    /// (see [`crate::bridges`]).
    pub thin_joins: usize,
    /// Grid nodes set inside so that the mesh reaches samples on parts
    /// thinner than a cell (see [`crate::bridges::join_and_reach_thin_parts`]).
    pub thin_samples_reached: usize,
    /// Grid nodes set inside to close pinholes f leaves through a sheet
    /// (see [`crate::bridges::fill_pinholes`]).
    pub pinholes_filled: usize,
}

/// A closed piece whose bounding-box diagonal is under this many cells is
/// a speck: a blob of f a cell or two wide (a stray sample's, or one
/// beyond where a thin tip narrows under a cell), which the mesh cannot
/// show faithfully and a user would not want.
pub const SPECK_CELLS: f64 = 3.0;

/// A closed piece none of whose vertices lies within this many cells of a
/// seed (an input point) is a speck too, whatever its size: a bubble of f
/// inside the solid or beside it that no data asked for.
pub const DATA_CELLS: f64 = 1.0;

/// An implicit function the mesher can follow: negative inside, and near
/// its zero set close to a signed distance (growth stops a cell diagonal
/// away from the surface).
pub trait Implicit: Sync {
    /// f at `points`; `groups` partition the indices into compact clusters
    /// (one per grid block) for implementations that gather per cluster.
    fn values_grouped(&self, points: &[DVec3], groups: &[Vec<u32>]) -> Vec<f64>;
    /// ∇f at `points` (the mesh's vertex normals).
    fn gradients(&self, points: &[DVec3]) -> Vec<DVec3>;
}

impl Implicit for SvmModel {
    fn values_grouped(&self, points: &[DVec3], groups: &[Vec<u32>]) -> Vec<f64> {
        SvmModel::values_grouped(self, points, groups)
    }

    fn gradients(&self, points: &[DVec3]) -> Vec<DVec3> {
        SvmModel::gradients(self, points)
    }
}

/// Extract the zero set of `model` around `seeds` (usually the input
/// points) inside `bounds` enlarged by the margin. Vertex normals are the
/// normalized gradient of f (outward).
pub fn mesh_model(
    model: &(impl Implicit + ?Sized),
    seeds: &[DVec3],
    bounds: Aabb,
    opts: &MeshOptions,
) -> Result<(TriMesh, MeshReport)> {
    crate::error::require_positive("resolution", opts.resolution as f64)?;
    let padded = bounds.padded(opts.margin.max(0.0) * bounds.diagonal());
    let spec = GridSpec::<3>::from_bounds(
        padded.min.to_array(),
        padded.max.to_array(),
        GridSize::Resolution(opts.resolution),
        1,
    )?;
    let mut values = follow_surface(model, seeds, &spec)?;
    let (cells_visited, nodes_evaluated) = (values.cells_visited, values.nodes.len());
    let pinholes_filled = fill_pinholes(&spec, &mut values.nodes);
    let (thin_joins, thin_samples_reached) =
        join_and_reach_thin_parts(model, &spec, seeds, opts.data_noise, &mut values.nodes);
    let background = 2.0 * spec.spacing;
    let nodes = outside_on_the_rim(values.nodes, spec.dims, background);
    let grid = BlockGrid::from_nodes(spec, background, nodes)?;
    let seed_tree = KdTree::new(seeds);
    let near_data = |p: &DVec3| {
        seed_tree
            .nearest(*p)
            .is_some_and(|n| n.distance <= DATA_CELLS * spec.spacing)
    };
    let (mut mesh, specks_removed) =
        marching_cubes_sparse(&grid, 0.0).retain_pieces(|bounds, vertices| {
            bounds.diagonal() >= SPECK_CELLS * spec.spacing && vertices.iter().any(near_data)
        });
    let report = MeshReport {
        grid_dims: spec.dims,
        spacing: spec.spacing,
        cells_visited,
        nodes_evaluated,
        specks_removed,
        thin_joins,
        thin_samples_reached,
        pinholes_filled,
    };
    mesh.normals = Some(
        model
            .gradients(&mesh.vertices)
            .into_iter()
            .map(|g| g.normalize_or_zero())
            .collect(),
    );
    Ok((mesh, report))
}

/// `nodes` with every node on the grid's outer faces outside (evaluated
/// ones clamped, the others added): a zero set that runs out of the grid
/// is then closed along its faces, never left open, even where the block
/// grid's tiles beyond the evaluated band are taken to be inside.
fn outside_on_the_rim(
    mut nodes: Vec<([usize; 3], f64)>,
    dims: [usize; 3],
    outside: f64,
) -> Vec<([usize; 3], f64)> {
    let on_rim = |n: [usize; 3]| (0..3).any(|a| n[a] == 0 || n[a] + 1 == dims[a]);
    let known: FastSet = nodes.iter().map(|(n, _)| pack(*n)).collect();
    for (n, v) in &mut nodes {
        if on_rim(*n) {
            *v = v.max(outside);
        }
    }
    for a in 0..3 {
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        for side in [0, dims[a] - 1] {
            for i in 0..dims[b] {
                for j in 0..dims[c] {
                    let mut n = [0; 3];
                    (n[a], n[b], n[c]) = (side, i, j);
                    if !known.contains(&pack(n)) {
                        nodes.push((n, outside));
                    }
                }
            }
        }
    }
    nodes.sort_unstable_by_key(|(n, _)| *n);
    nodes.dedup_by_key(|(n, _)| *n);
    nodes
}

struct Band {
    nodes: Vec<([usize; 3], f64)>,
    cells_visited: usize,
}

/// Cells per block edge: growth and evaluation go block by block, so the
/// centres near a block are gathered once for all its nodes.
const BLOCK: usize = 4;

/// Node or block coordinates packed into one key (each < 2^21).
fn pack(c: [usize; 3]) -> u64 {
    c[0] as u64 | (c[1] as u64) << 21 | (c[2] as u64) << 42
}

/// Evaluate f on the nodes of every block reached by the growth.
fn follow_surface(
    model: &(impl Implicit + ?Sized),
    seeds: &[DVec3],
    spec: &GridSpec<3>,
) -> Result<Band> {
    if spec.dims.iter().any(|&n| n >= 1 << 21) {
        return Err(SvmError::InvalidParameter {
            name: "resolution",
            message: format!("grid {:?} is too large to mesh", spec.dims),
        });
    }
    let cell_dims = spec.dims.map(|n| n - 1);
    let block_dims = cell_dims.map(|n| n.div_ceil(BLOCK));
    let near = spec.spacing * 3f64.sqrt();
    let mut frontier: Vec<[usize; 3]> = seeds
        .iter()
        .filter_map(|p| cell_of(spec, *p))
        .map(|c| c.map(|i| i / BLOCK))
        .collect();
    frontier.sort_unstable();
    frontier.dedup();
    let mut visited = FastSet::default();
    let mut values: FastMap<f64> = FastMap::default();
    while !frontier.is_empty() {
        visited.extend(frontier.iter().map(|b| pack(*b)));
        evaluate_blocks(model, spec, &frontier, &mut values);
        let mut next: Vec<[usize; 3]> = frontier
            .iter()
            .flat_map(|&b| blocks_reached(&values, b, cell_dims, block_dims, near))
            .filter(|n| !visited.contains(&pack(*n)))
            .collect();
        next.sort_unstable();
        next.dedup();
        frontier = next;
    }
    let unpack = |k: u64| {
        [
            (k & 0x1f_ffff) as usize,
            ((k >> 21) & 0x1f_ffff) as usize,
            (k >> 42) as usize,
        ]
    };
    let mut nodes: Vec<([usize; 3], f64)> =
        values.into_iter().map(|(k, v)| (unpack(k), v)).collect();
    nodes.sort_unstable_by_key(|(i, _)| *i);
    Ok(Band {
        nodes,
        cells_visited: visited.len() * BLOCK.pow(3),
    })
}

/// The cell holding `p`, if inside the grid.
fn cell_of(spec: &GridSpec<3>, p: DVec3) -> Option<[usize; 3]> {
    let g = spec.to_grid(p.to_array());
    let mut c = [0usize; 3];
    for a in 0..3 {
        if g[a].is_nan() || g[a] < 0.0 || g[a] >= (spec.dims[a] - 1) as f64 {
            return None;
        }
        c[a] = g[a] as usize;
    }
    Some(c)
}

/// Index range of the cells of block `b` along each axis.
fn block_cells(b: [usize; 3], cell_dims: [usize; 3]) -> [std::ops::Range<usize>; 3] {
    std::array::from_fn(|a| b[a] * BLOCK..((b[a] + 1) * BLOCK).min(cell_dims[a]))
}

fn cells_of(r: &[std::ops::Range<usize>; 3]) -> impl Iterator<Item = [usize; 3]> + '_ {
    r[2].clone().flat_map(move |z| {
        r[1].clone()
            .flat_map(move |y| r[0].clone().map(move |x| [x, y, z]))
    })
}

fn corners(c: [usize; 3]) -> impl Iterator<Item = [usize; 3]> {
    (0..8).map(move |k| [c[0] + (k & 1), c[1] + ((k >> 1) & 1), c[2] + ((k >> 2) & 1)])
}

/// Evaluate the not yet known nodes of `blocks`, one group per block.
fn evaluate_blocks(
    model: &(impl Implicit + ?Sized),
    spec: &GridSpec<3>,
    blocks: &[[usize; 3]],
    values: &mut FastMap<f64>,
) {
    let cell_dims = spec.dims.map(|n| n - 1);
    let mut claimed = FastSet::default();
    let mut keys = Vec::new();
    let mut positions = Vec::new();
    let mut groups = Vec::new();
    for &b in blocks {
        let cells = block_cells(b, cell_dims);
        // Nodes of the block: one more than its cells along each axis.
        let nodes: [std::ops::Range<usize>; 3] =
            std::array::from_fn(|a| cells[a].start..cells[a].end + 1);
        let mut group = Vec::new();
        for n in cells_of(&nodes) {
            let k = pack(n);
            if !values.contains_key(&k) && claimed.insert(k) {
                group.push(positions.len() as u32);
                keys.push(k);
                positions.push(DVec3::from_array(spec.position(n)));
            }
        }
        groups.push(group);
    }
    let fresh = model.values_grouped(&positions, &groups);
    values.extend(keys.into_iter().zip(fresh));
}

/// Blocks next to `b` that a near-surface cell of `b` touches (through a
/// face, edge or corner of the cell).
fn blocks_reached(
    values: &FastMap<f64>,
    b: [usize; 3],
    cell_dims: [usize; 3],
    block_dims: [usize; 3],
    near: f64,
) -> Vec<[usize; 3]> {
    let mut out = Vec::new();
    let range = block_cells(b, cell_dims);
    for c in cells_of(&range) {
        let on_rim = (0..3).any(|a| c[a] == range[a].start || c[a] + 1 == range[a].end);
        if !on_rim || !is_near_surface(values, c, near) {
            continue;
        }
        for k in 0..27usize {
            let d = [k % 3, (k / 3) % 3, k / 9];
            let mut nb = [0usize; 3];
            let mut inside = true;
            for a in 0..3 {
                match (c[a] + d[a]).checked_sub(1) {
                    Some(v) if v < cell_dims[a] => nb[a] = v / BLOCK,
                    _ => inside = false,
                }
            }
            if inside && nb != b && (0..3).all(|a| nb[a] < block_dims[a]) {
                out.push(nb);
            }
        }
    }
    out.sort_unstable();
    out.dedup();
    out
}

fn is_near_surface(values: &FastMap<f64>, c: [usize; 3], near: f64) -> bool {
    let (mut pos, mut neg, mut close) = (false, false, false);
    for n in corners(c) {
        let v = values[&pack(n)];
        pos |= v >= 0.0;
        neg |= v < 0.0;
        close |= v.abs() <= near;
    }
    (pos && neg) || close
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The union of two balls (distance to the nearer sphere, negative inside).
    struct TwoBalls([(DVec3, f64); 2]);

    impl TwoBalls {
        fn value(&self, p: DVec3) -> f64 {
            self.0
                .iter()
                .map(|&(c, r)| p.distance(c) - r)
                .fold(f64::INFINITY, f64::min)
        }
    }

    /// Gradients of `value` by central differences.
    fn central_gradients(points: &[DVec3], value: impl Fn(DVec3) -> f64) -> Vec<DVec3> {
        let h = 1e-6;
        let d = |p: DVec3, e: DVec3| (value(p + e * h) - value(p - e * h)) / (2.0 * h);
        points
            .iter()
            .map(|&p| DVec3::new(d(p, DVec3::X), d(p, DVec3::Y), d(p, DVec3::Z)))
            .collect()
    }

    /// `Implicit` for a test shape from its `value`, with gradients by
    /// central differences.
    macro_rules! implicit_from_value {
        ($($shape:ty),*) => {$(
            impl Implicit for $shape {
                fn values_grouped(&self, points: &[DVec3], _: &[Vec<u32>]) -> Vec<f64> {
                    points.iter().map(|&p| self.value(p)).collect()
                }

                fn gradients(&self, points: &[DVec3]) -> Vec<DVec3> {
                    central_gradients(points, |p| self.value(p))
                }
            }
        )*};
    }

    implicit_from_value!(TwoBalls, BallAndSheet, PinchedRod, HoledPlate);

    #[test]
    fn a_piece_away_from_the_data_is_dropped() {
        // Seeds on the big ball only; the small ball sits 0.04 (4 cells)
        // beside it: found by the mesher, but no datum asked for it.
        let balls = TwoBalls([(DVec3::ZERO, 0.5), (DVec3::new(0.62, 0.0, 0.0), 0.08)]);
        let seeds: Vec<DVec3> = (0..2000)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / 2000.0;
                let phi = i as f64 * 2.399963;
                let r = (1.0 - z * z).sqrt();
                DVec3::new(r * phi.cos(), r * phi.sin(), z) * 0.5
            })
            .collect();
        let opts = MeshOptions {
            resolution: 128,
            margin: 0.1,
            ..Default::default()
        };
        let (mesh, report) = mesh_model(&balls, &seeds, Aabb::from_points(&seeds), &opts).unwrap();
        assert_eq!(report.specks_removed, 1);
        let farthest = mesh.vertices.iter().map(|v| v.length()).fold(0.0, f64::max);
        assert!(farthest < 0.51, "the small ball is still there: {farthest}");
    }

    /// A ball of radius 0.5 with a rod of radius 0.4 cells along x from
    /// its centre, through grid nodes at its start and rising one cell
    /// (in y) every eight: nodes lie inside the rod for about four cells
    /// each time the rod passes a row of nodes, and none lie inside for
    /// two cells between, so marching cubes alone cuts the rod into
    /// pieces.
    struct BallAndRod {
        /// A grid node on the rod's axis, the grid spacing.
        start: DVec3,
        cell: f64,
    }

    impl BallAndRod {
        const LENGTH_CELLS: f64 = 40.0;

        fn axis(&self) -> (DVec3, DVec3) {
            let direction = DVec3::new(8.0, 1.0, 0.0).normalize();
            (self.start, direction)
        }

        fn value(&self, p: DVec3) -> f64 {
            let (start, direction) = self.axis();
            let length = Self::LENGTH_CELLS * self.cell;
            let along = (p - start).dot(direction).clamp(0.0, length);
            let rod = p.distance(start + direction * along) - 0.4 * self.cell;
            rod.min(p.length() - 0.5)
        }

        fn seeds(&self) -> Vec<DVec3> {
            let (start, direction) = self.axis();
            let length = Self::LENGTH_CELLS * self.cell;
            let rod = (0..400).map(|i| start + direction * (length * i as f64 / 400.0));
            fibonacci_sphere(2000, 0.5).into_iter().chain(rod).collect()
        }
    }

    impl Implicit for BallAndRod {
        fn values_grouped(&self, points: &[DVec3], _: &[Vec<u32>]) -> Vec<f64> {
            points.iter().map(|&p| self.value(p)).collect()
        }

        fn gradients(&self, points: &[DVec3]) -> Vec<DVec3> {
            points.iter().map(|p| p.normalize_or_zero()).collect()
        }
    }

    fn fibonacci_sphere(n: usize, radius: f64) -> Vec<DVec3> {
        (0..n)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let phi = i as f64 * 2.399963;
                let r = (1.0 - z * z).sqrt();
                DVec3::new(r * phi.cos(), r * phi.sin(), z) * radius
            })
            .collect()
    }

    /// Mesh options, fixed bounds reaching `max_x` and the grid that
    /// `mesh_model` builds for them, so a rod can be laid out against it.
    fn rod_layout(max_x: f64) -> (MeshOptions, Aabb, GridSpec<3>) {
        let opts = MeshOptions {
            resolution: 96,
            margin: 0.0,
            ..Default::default()
        };
        let bounds = Aabb {
            min: DVec3::new(-0.6, -0.6, -0.6),
            max: DVec3::new(max_x, 0.6, 0.6),
        };
        let spec = GridSpec::<3>::from_bounds(
            bounds.min.to_array(),
            bounds.max.to_array(),
            GridSize::Resolution(opts.resolution),
            1,
        )
        .unwrap();
        (opts, bounds, spec)
    }

    #[test]
    fn a_rod_thinner_than_a_cell_stays_joined_to_its_body() {
        let (opts, bounds, spec) = rod_layout(1.8);
        let node = |p: DVec3| DVec3::from_array(spec.position(cell_of(&spec, p).unwrap()));
        let shape = BallAndRod {
            start: node(DVec3::new(0.2, 0.0, 0.0)),
            cell: spec.spacing,
        };
        let (mesh, report) = mesh_model(&shape, &shape.seeds(), bounds, &opts).unwrap();
        assert!(report.thin_joins >= 3, "{report:?}");
        assert_eq!(mesh.piece_count(), 1, "{report:?}");
        let farthest = mesh.vertices.iter().map(|v| v.x).fold(f64::MIN, f64::max);
        let end = shape.start.x + 0.99 * BallAndRod::LENGTH_CELLS * spec.spacing;
        assert!(farthest > end, "the rod ends at x = {farthest}, not {end}");
    }

    #[test]
    fn separate_balls_near_each_other_are_not_joined() {
        // Two balls two cells apart (0.03 at 128 cells over 1.9): f is
        // positive between them, so no join, whatever the distance.
        let balls = TwoBalls([(DVec3::ZERO, 0.5), (DVec3::new(0.63, 0.0, 0.0), 0.1)]);
        let mut seeds = fibonacci_sphere(2000, 0.5);
        seeds.extend(
            fibonacci_sphere(200, 0.1)
                .into_iter()
                .map(|p| p + DVec3::new(0.63, 0.0, 0.0)),
        );
        let opts = MeshOptions {
            resolution: 128,
            margin: 0.1,
            ..Default::default()
        };
        let (mesh, report) = mesh_model(&balls, &seeds, Aabb::from_points(&seeds), &opts).unwrap();
        assert_eq!(report.thin_joins, 0);
        assert_eq!(mesh.piece_count(), 2);
    }

    /// A ball of radius 0.5 with a flat disc (radius 0.9) through its
    /// centre, 0.6 cells thick and laid half-way between two layers of
    /// grid nodes, so that no node lies inside the disc beyond the ball.
    struct BallAndSheet {
        /// The disc's mid-plane height and half thickness.
        middle: f64,
        half: f64,
    }

    impl BallAndSheet {
        const RADIUS: f64 = 0.9;

        fn value(&self, p: DVec3) -> f64 {
            let across = (p.y - self.middle).abs() - self.half;
            let outward = DVec3::new(p.x, 0.0, p.z).length() - Self::RADIUS;
            across.max(outward).min(p.length() - 0.5)
        }

        /// Samples on the ball and on both faces of the disc outside it.
        fn seeds(&self, step: f64) -> Vec<DVec3> {
            let mut seeds = fibonacci_sphere(4000, 0.5);
            let n = (Self::RADIUS / step).ceil() as i64;
            for i in -n..=n {
                for k in -n..=n {
                    let (x, z) = (i as f64 * step, k as f64 * step);
                    let r = x.hypot(z);
                    if r > 0.5 && r < Self::RADIUS - step {
                        for y in [self.middle - self.half, self.middle + self.half] {
                            seeds.push(DVec3::new(x, y, z));
                        }
                    }
                }
            }
            seeds
        }
    }

    /// Mesh options at `resolution` without margin over the cube of
    /// half-width `half` about the origin, and its grid.
    fn cube_grid(resolution: usize, half: f64) -> (MeshOptions, Aabb, GridSpec<3>) {
        let opts = MeshOptions {
            resolution,
            margin: 0.0,
            ..Default::default()
        };
        let bounds = Aabb {
            min: DVec3::splat(-half),
            max: DVec3::splat(half),
        };
        let spec = GridSpec::<3>::from_bounds(
            bounds.min.to_array(),
            bounds.max.to_array(),
            GridSize::Resolution(resolution),
            1,
        )
        .unwrap();
        (opts, bounds, spec)
    }

    #[test]
    fn a_sheet_thinner_than_a_cell_between_node_layers_is_reached() {
        let (opts, bounds, spec) = cube_grid(96, 1.0);
        let h = spec.spacing;
        // Half-way between the node layers next to y = 0.
        let middle = (spec.to_grid([0.0; 3])[1].floor() + 0.5) * h + spec.origin[1];
        let sheet = BallAndSheet {
            middle,
            half: 0.3 * h,
        };
        let seeds = sheet.seeds(0.7 * h);
        let (mesh, report) = mesh_model(&sheet, &seeds, bounds, &opts).unwrap();
        assert_eq!(mesh.piece_count(), 1, "{report:?}");
        // Every sample within 1.5 cells of a vertex (vertices, not the
        // surface: up to a cell apart): the sheet is there up to its rim
        // (marching cubes alone ends it at the ball, 19 cells short).
        let vertices = KdTree::new(&mesh.vertices);
        let farthest = seeds
            .iter()
            .map(|&p| vertices.nearest(p).map_or(f64::INFINITY, |n| n.distance))
            .fold(0.0, f64::max);
        assert!(
            farthest < 1.5 * h,
            "a sample {:.2} cells from the mesh; {report:?}",
            farthest / h
        );
        // And it stays a sheet, not a slab: no vertex more than a cell off
        // the disc's mid-plane beyond the ball.
        let off_plane = mesh
            .vertices
            .iter()
            .filter(|v| DVec3::new(v.x, 0.0, v.z).length() > 0.6)
            .map(|v| (v.y - middle).abs())
            .fold(0.0, f64::max);
        assert!(off_plane < h, "{:.2} cells off the sheet", off_plane / h);
    }

    /// A disc of radius 0.6 and 1.2 cells thick, its mid-plane a layer of
    /// grid nodes, with a hole one node wide through its centre where f,
    /// across the disc, rises `lift` above the mid-plane's distance to it;
    /// or, `stepped`, where the sheet steps down half a cell (and `lift`)
    /// over that node's column: no hole in f, but only the node a layer
    /// below is inside there, touching the disc's inside nodes across cell
    /// diagonals (spikes' fin at 0.25 % noise, where its inside passes
    /// from one node layer to the next).
    struct HoledPlate {
        middle: f64,
        cell: f64,
        lift: f64,
        stepped: bool,
    }

    impl HoledPlate {
        const RADIUS: f64 = 0.6;

        fn value(&self, p: DVec3) -> f64 {
            let across = (p.y - self.middle).abs();
            let from_axis = DVec3::new(p.x, 0.0, p.z).length();
            let plate = (across - 0.6 * self.cell).max(from_axis - Self::RADIUS);
            if from_axis < 0.6 * self.cell && self.stepped {
                let lowered = self.middle - 0.5 * self.cell - self.lift;
                (p.y - lowered).abs() - 0.5 * self.cell
            } else if from_axis < 0.6 * self.cell {
                plate.max(self.lift + across)
            } else {
                plate
            }
        }

        /// Samples on both faces of the disc, hole included.
        fn seeds(&self) -> Vec<DVec3> {
            let step = 0.7 * self.cell;
            let n = (Self::RADIUS / step) as i64;
            let on_disc = |i: i64, k: i64| {
                let (x, z) = (i as f64 * step, k as f64 * step);
                (x.hypot(z) < Self::RADIUS - step).then_some((x, z))
            };
            (-n..=n)
                .flat_map(|i| (-n..=n).filter_map(move |k| on_disc(i, k)))
                .flat_map(|(x, z)| {
                    let faces = [-0.6, 0.6].map(|side| self.middle + side * self.cell);
                    faces.map(|y| DVec3::new(x, y, z))
                })
                .collect()
        }
    }

    /// The Euler characteristic of `plate` meshed on a grid whose node
    /// layer and node column run through the disc's mid-plane and axis.
    fn euler_of_holed_plate(lift_cells: f64, stepped: bool) -> (i64, MeshReport) {
        let (opts, bounds, spec) = cube_grid(80, 0.8);
        let node = spec.position(spec.to_grid([0.0; 3]).map(|c| c.round() as usize));
        assert!(node[0].abs() < 1e-9 && node[2].abs() < 1e-9, "{node:?}");
        let plate = HoledPlate {
            middle: node[1],
            cell: spec.spacing,
            lift: lift_cells * spec.spacing,
            stepped,
        };
        let (mesh, report) = mesh_model(&plate, &plate.seeds(), bounds, &opts).unwrap();
        assert_eq!(mesh.piece_count(), 1, "{report:?}");
        (surfrecon_geom::metrics::topology(&mesh).euler, report)
    }

    #[test]
    fn a_pinhole_through_a_sheet_is_closed_but_a_hole_is_kept() {
        // f 0.05 cells above 0 in the hole: within the fit's slack of
        // closing (spikes' fin: +0.0001 with cells of 0.024). Marching
        // cubes alone opens it: a handle (Euler characteristic 0).
        let (pinhole, report) = euler_of_holed_plate(0.05, false);
        assert_eq!(pinhole, 2, "{report:?}");
        assert!(report.pinholes_filled >= 1, "{report:?}");
        // Half a cell above 0: f clearly open there, the hole stays.
        let (hole, report) = euler_of_holed_plate(0.5, false);
        assert_eq!(hole, 0, "{report:?}");
        assert_eq!(report.pinholes_filled, 0, "{report:?}");
    }

    #[test]
    fn a_sheet_stepping_between_node_layers_is_not_opened() {
        // The node in the disc's layer 0.05 cells above 0, the one below
        // it 0.05 cells inside: only a dip's one side is higher. Marching
        // cubes alone parts the two inside nodes (a hole, Euler
        // characteristic 0, the lone node below a speck).
        let (stepped, report) = euler_of_holed_plate(0.05, true);
        assert_eq!(stepped, 2, "{report:?}");
        assert!(report.pinholes_filled >= 1, "{report:?}");
    }

    /// A ball of radius 0.5 with a rod of radius 0.4 cells along x through
    /// a row of grid nodes, which f pinches: positive within 0.75 cells of
    /// a node on the axis, so one node of the row lies outside and the rod
    /// beyond is a piece of its own, although samples run on along it.
    struct PinchedRod {
        start: DVec3,
        cell: f64,
    }

    impl PinchedRod {
        const LENGTH_CELLS: f64 = 20.0;
        const PINCH_CELLS: f64 = 8.0;

        fn value(&self, p: DVec3) -> f64 {
            let length = Self::LENGTH_CELLS * self.cell;
            let along = (p.x - self.start.x).clamp(0.0, length);
            let rod = p.distance(self.start + DVec3::X * along) - 0.4 * self.cell;
            let pinch_x = self.start.x + Self::PINCH_CELLS * self.cell;
            let pinch = 0.75 * self.cell - (p.x - pinch_x).abs();
            rod.max(pinch).min(p.length() - 0.5)
        }

        /// Samples along the rod, `off_axis` cells from its axis (turning
        /// around it, as noise scatters a thin part's samples).
        fn seeds(&self, samples_in_the_pinch: bool, off_axis: f64) -> Vec<DVec3> {
            let pinch_x = self.start.x + Self::PINCH_CELLS * self.cell;
            let rod = (0..200)
                .map(|i| {
                    let around = i as f64 * 2.399963;
                    let off = DVec3::new(0.0, around.cos(), around.sin()) * (off_axis * self.cell);
                    self.start
                        + DVec3::X * (Self::LENGTH_CELLS * self.cell * i as f64 / 200.0)
                        + off
                })
                .filter(|p| samples_in_the_pinch || (p.x - pinch_x).abs() > 1.5 * self.cell);
            fibonacci_sphere(2000, 0.5).into_iter().chain(rod).collect()
        }
    }

    #[test]
    fn a_sampled_part_pinched_by_f_stays_one_piece() {
        let (opts, bounds, spec) = rod_layout(1.0);
        let node = |p: DVec3| DVec3::from_array(spec.position(cell_of(&spec, p).unwrap()));
        let shape = PinchedRod {
            start: node(DVec3::new(0.45, 0.0, 0.0)),
            cell: spec.spacing,
        };
        // Samples run on through the pinch: the data say it is one part.
        let (mesh, report) = mesh_model(&shape, &shape.seeds(true, 0.0), bounds, &opts).unwrap();
        assert_eq!(mesh.piece_count(), 1, "{report:?}");
        let farthest = mesh.vertices.iter().map(|v| v.x).fold(f64::MIN, f64::max);
        let end = shape.start.x + 0.9 * PinchedRod::LENGTH_CELLS * spec.spacing;
        assert!(farthest > end, "the rod ends at x = {farthest}, not {end}");
        // Without samples in the pinch f's gap stands: two pieces.
        let (mesh, report) = mesh_model(&shape, &shape.seeds(false, 0.0), bounds, &opts).unwrap();
        assert_eq!(mesh.piece_count(), 2, "{report:?}");
    }

    #[test]
    fn noisy_samples_across_a_pinch_join_it_within_their_noise() {
        let (mut opts, bounds, spec) = rod_layout(1.0);
        let node = |p: DVec3| DVec3::from_array(spec.position(cell_of(&spec, p).unwrap()));
        let shape = PinchedRod {
            start: node(DVec3::new(0.45, 0.0, 0.0)),
            cell: spec.spacing,
        };
        // The rod's samples 1.2 cells off its axis: taken as exact, they
        // lie too far from the pinch to say the rod runs on across it.
        let seeds = shape.seeds(true, 1.2);
        let (mesh, report) = mesh_model(&shape, &seeds, bounds, &opts).unwrap();
        assert_eq!(mesh.piece_count(), 2, "{report:?}");
        // Data that noisy cannot tell the pinch from the rod: one piece.
        opts.data_noise = 0.8 * spec.spacing;
        let (mesh, report) = mesh_model(&shape, &seeds, bounds, &opts).unwrap();
        assert_eq!(mesh.piece_count(), 1, "{report:?}");
    }
}
