//! Marching cubes over a dense 3D field, parallel over slabs of cells.

use super::tables::{cube_table, EDGE_CORNERS, FACE_CORNERS, MAX_LOOP_CENTRES};
use crate::{Field3, GridSpec};
use rayon::prelude::*;
use surfrecon_geom::{DVec3, TriMesh};

/// Cell layers per parallel slab. Fixed (not derived from the thread count)
/// so the output is the same on any machine.
const SLAB_LAYERS: usize = 8;

/// Edge crossings are kept at least this fraction of a cell away from the
/// nodes, so a node at or next to iso never collapses triangles to (near)
/// zero area: 1e-6 left edges of 5e-9 of the diagonal and thousands of
/// slivers of relative area 1e-18 in level-set meshes, which tools that
/// weld close vertices turn non-manifold. Moving a vertex by 1e-3 of a cell
/// is far below the accuracy of the grid.
const MIN_EDGE_FRACTION: f64 = 1e-3;

/// Read access to node values of a 3D grid (dense or sparse).
pub(crate) trait Samples3: Sync {
    fn spec(&self) -> &GridSpec<3>;
    fn at(&self, idx: [usize; 3]) -> f64;
}

impl Samples3 for Field3 {
    fn spec(&self) -> &GridSpec<3> {
        &self.spec
    }
    #[inline]
    fn at(&self, idx: [usize; 3]) -> f64 {
        self.get(idx)
    }
}

/// Field gradient at a node (central differences, one-sided on the grid
/// boundary), in index units: only its direction is used.
pub(crate) fn node_gradient<S: Samples3>(s: &S, idx: [usize; 3]) -> DVec3 {
    let dims = s.spec().dims;
    let g: [f64; 3] = std::array::from_fn(|a| {
        let mut lo = idx;
        let mut hi = idx;
        lo[a] = idx[a].saturating_sub(1);
        hi[a] = (idx[a] + 1).min(dims[a] - 1);
        let span = (hi[a] - lo[a]) as f64;
        (s.at(hi) - s.at(lo)) / span
    });
    DVec3::from_array(g)
}

/// Position and unit normal of the crossing on the edge from node `lo`
/// along `axis`: linear interpolation of the values and of the node
/// gradients (trilinear interpolation restricted to the edge).
pub(crate) fn edge_vertex<S: Samples3>(
    s: &S,
    lo: [usize; 3],
    axis: usize,
    iso: f64,
) -> (DVec3, DVec3) {
    let mut hi = lo;
    hi[axis] += 1;
    let (a, b) = (s.at(lo), s.at(hi));
    let t = crossing_fraction(a, b, iso);
    let spec = s.spec();
    let mut p = spec.position(lo);
    p[axis] += t * spec.spacing;
    let g = node_gradient(s, lo).lerp(node_gradient(s, hi), t);
    (DVec3::from_array(p), g.normalize_or_zero())
}

/// Where along an edge with end values `a`, `b` the field crosses `iso`
/// (kept a little off the ends, see `MIN_EDGE_FRACTION`).
#[inline]
pub fn crossing_fraction(a: f64, b: f64, iso: f64) -> f64 {
    let t = (iso - a) / (b - a);
    if t.is_nan() {
        0.5
    } else {
        t.clamp(MIN_EDGE_FRACTION, 1.0 - MIN_EDGE_FRACTION)
    }
}

/// Corner-sign configuration and ambiguous-face choices of one cell, with
/// corners numbered `x + 2y + 4z` (the keys of [`super::tables::cube_table`]).
#[inline]
pub fn cell_case(v: &[f64; 8], iso: f64) -> (u8, u8) {
    let mut config = 0u8;
    for (c, &x) in v.iter().enumerate() {
        config |= ((x >= iso) as u8) << c;
    }
    if config == 0 || config == 255 {
        return (config, 0);
    }
    let amb = cube_table().ambiguous_faces[config as usize];
    let mut bits = 0u8;
    if amb != 0 {
        for (f, &face) in FACE_CORNERS.iter().enumerate() {
            if (amb >> f) & 1 == 1 && positive_connected(v, iso, face) {
                bits |= 1 << f;
            }
        }
    }
    (config, bits)
}

/// Asymptotic decider for an ambiguous face: the positive corners are
/// connected when the bilinear saddle value is >= iso, i.e. when the product
/// of the positive diagonal's offsets is >= that of the negative diagonal.
/// Products commute exactly in floating point, so both cells sharing the
/// face decide alike.
#[inline]
fn positive_connected(v: &[f64; 8], iso: f64, face: [u8; 4]) -> bool {
    positive_corners_joined(face.map(|c| v[c as usize] - iso))
}

/// The asymptotic decider on a face's four offsets from iso in cyclic
/// order: whether its positive corners are joined.
#[inline]
pub(crate) fn positive_corners_joined(d: [f64; 4]) -> bool {
    let (diag_a, diag_b) = (d[0] * d[2], d[1] * d[3]);
    if d[0] >= 0.0 {
        diag_a >= diag_b
    } else {
        diag_b >= diag_a
    }
}

/// Extract the `iso` level set of `field` as an indexed triangle mesh.
///
/// One vertex per sign-changing grid edge (a node is on the positive side
/// when its value is `>= iso`), placed by linear interpolation; unit vertex
/// normals from the field gradient point towards larger values, and
/// triangles wind counter-clockwise seen from that side. Ambiguous faces are
/// resolved by the asymptotic decider, identically from both cells, so a
/// level set that stays inside the grid gives a closed, edge-manifold mesh.
/// A level set that reaches the grid boundary is cut open there: pad the
/// grid if a closed mesh is needed. Output is identical for any thread count.
pub fn marching_cubes(field: &Field3, iso: f64) -> TriMesh {
    let dims = field.spec.dims;
    if dims.iter().any(|&n| n < 2) || field.values.len() != field.spec.node_count() {
        return TriMesh::default();
    }
    let cell_layers = dims[2] - 1;
    let slabs: Vec<Slab> = (0..cell_layers.div_ceil(SLAB_LAYERS))
        .into_par_iter()
        .map(|s| {
            let z0 = s * SLAB_LAYERS;
            extract_slab(field, iso, z0, (z0 + SLAB_LAYERS).min(cell_layers))
        })
        .collect();
    merge_slabs(slabs)
}

/// The mesh of one slab; its first `bottom` vertices lie on its lowest node
/// plane and `top` is the range of vertices on its highest node plane,
/// both in the canonical plane order, so neighbouring slabs can be stitched.
struct Slab {
    vertices: Vec<DVec3>,
    normals: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    bottom: usize,
    top: std::ops::Range<usize>,
}

const NONE: u32 = u32::MAX;

/// Vertex ids of the x- and y-edges of one node plane (two per node), and
/// the sign state of each node row.
struct PlaneEdges {
    ids: Vec<u32>,
    rows: Vec<RowState>,
}

/// Signs along one row of nodes: rows that are entirely on one side (most
/// of them) are skipped without looking at single cells.
#[derive(Clone, Copy, PartialEq, Eq)]
enum RowState {
    Negative,
    Positive,
    Mixed,
}

fn row_state(row: &[f64], iso: f64) -> RowState {
    let positive = row.iter().filter(|&&v| v >= iso).count();
    match positive {
        0 => RowState::Negative,
        p if p == row.len() => RowState::Positive,
        _ => RowState::Mixed,
    }
}

/// Whether rows in these states may hold a sign change between them.
#[inline]
fn may_cross(states: &[RowState]) -> bool {
    states
        .iter()
        .any(|&s| s == RowState::Mixed || s != states[0])
}

fn extract_slab(field: &Field3, iso: f64, z0: usize, z1: usize) -> Slab {
    let [nx, ny, _] = field.spec.dims;
    let mut slab = Slab {
        vertices: Vec::new(),
        normals: Vec::new(),
        triangles: Vec::new(),
        bottom: 0,
        top: 0..0,
    };
    let mut lower = plane_edges(field, iso, z0, &mut slab);
    slab.bottom = slab.vertices.len();
    let mut vertical = vec![NONE; nx * ny];
    for k in z0..z1 {
        let upper_rows = plane_rows(field, iso, k + 1);
        vertical_edges(
            field,
            iso,
            k,
            [&lower.rows, &upper_rows],
            &mut vertical,
            &mut slab,
        );
        let top_start = slab.vertices.len();
        let upper = plane_edges_with(field, iso, k + 1, upper_rows, &mut slab);
        slab.top = top_start..slab.vertices.len();
        cell_layer(field, iso, k, [&lower, &upper], &vertical, &mut slab);
        lower = upper;
    }
    slab
}

fn push_vertex(slab: &mut Slab, (p, n): (DVec3, DVec3)) -> u32 {
    slab.vertices.push(p);
    slab.normals.push(n);
    (slab.vertices.len() - 1) as u32
}

/// The values of node row `j` of plane `k`.
#[inline]
fn row(field: &Field3, j: usize, k: usize) -> &[f64] {
    let nx = field.spec.dims[0];
    let start = field.spec.linear([0, j, k]);
    &field.values[start..start + nx]
}

fn plane_rows(field: &Field3, iso: f64, k: usize) -> Vec<RowState> {
    (0..field.spec.dims[1])
        .map(|j| row_state(row(field, j, k), iso))
        .collect()
}

fn plane_edges(field: &Field3, iso: f64, k: usize, slab: &mut Slab) -> PlaneEdges {
    let rows = plane_rows(field, iso, k);
    plane_edges_with(field, iso, k, rows, slab)
}

/// Crossings on the x- and y-edges of node plane `k`, in node order.
fn plane_edges_with(
    field: &Field3,
    iso: f64,
    k: usize,
    rows: Vec<RowState>,
    slab: &mut Slab,
) -> PlaneEdges {
    let [nx, ny, _] = field.spec.dims;
    let mut ids = vec![NONE; 2 * nx * ny];
    for j in 0..ny {
        let x_edges = rows[j] == RowState::Mixed;
        let y_edges = j + 1 < ny && may_cross(&rows[j..j + 2]);
        if !x_edges && !y_edges {
            continue;
        }
        let here = row(field, j, k);
        let next = if y_edges { row(field, j + 1, k) } else { here };
        for i in 0..nx {
            let positive = here[i] >= iso;
            if x_edges && i + 1 < nx && positive != (here[i + 1] >= iso) {
                ids[2 * (j * nx + i)] = push_vertex(slab, edge_vertex(field, [i, j, k], 0, iso));
            }
            if y_edges && positive != (next[i] >= iso) {
                ids[2 * (j * nx + i) + 1] =
                    push_vertex(slab, edge_vertex(field, [i, j, k], 1, iso));
            }
        }
    }
    PlaneEdges { ids, rows }
}

/// Crossings on the z-edges between node planes `k` and `k + 1`.
fn vertical_edges(
    field: &Field3,
    iso: f64,
    k: usize,
    rows: [&[RowState]; 2],
    ids: &mut [u32],
    slab: &mut Slab,
) {
    let [nx, ny, _] = field.spec.dims;
    ids.fill(NONE);
    for j in 0..ny {
        if !may_cross(&[rows[0][j], rows[1][j]]) {
            continue;
        }
        let (lo, hi) = (row(field, j, k), row(field, j, k + 1));
        for i in 0..nx {
            if (lo[i] >= iso) != (hi[i] >= iso) {
                ids[j * nx + i] = push_vertex(slab, edge_vertex(field, [i, j, k], 2, iso));
            }
        }
    }
}

/// Triangles of all cells between node planes `k` and `k + 1`.
fn cell_layer(
    field: &Field3,
    iso: f64,
    k: usize,
    planes: [&PlaneEdges; 2],
    vertical: &[u32],
    slab: &mut Slab,
) {
    let [nx, ny, _] = field.spec.dims;
    for j in 0..ny - 1 {
        let states = [
            planes[0].rows[j],
            planes[0].rows[j + 1],
            planes[1].rows[j],
            planes[1].rows[j + 1],
        ];
        if !may_cross(&states) {
            continue;
        }
        let rows: [&[f64]; 4] = std::array::from_fn(|r| row(field, j + (r & 1), k + (r >> 1)));
        for i in 0..nx - 1 {
            let v: [f64; 8] = std::array::from_fn(|c| rows[c >> 1][i + (c & 1)]);
            let (config, bits) = cell_case(&v, iso);
            if config == 0 || config == 255 {
                continue;
            }
            let vertex_of = |e: u8| {
                let lc = EDGE_CORNERS[e as usize][0];
                let (x, y, z) = (
                    i + (lc & 1) as usize,
                    j + ((lc >> 1) & 1) as usize,
                    (lc >> 2) as usize,
                );
                let node = y * nx + x;
                match e / 4 {
                    0 => planes[z].ids[2 * node],
                    1 => planes[z].ids[2 * node + 1],
                    _ => vertical[node],
                }
            };
            emit_cell(config, bits, vertex_of, slab);
        }
    }
}

/// Append the triangles of one cell, given the ids of its edge vertices
/// (and creating its loop-centre vertices, if the case has any).
#[inline]
fn emit_cell(config: u8, bits: u8, vertex_of: impl Fn(u8) -> u32, slab: &mut Slab) {
    let table = cube_table();
    let mut centre_ids = [NONE; MAX_LOOP_CENTRES];
    for (k, lp) in table.loop_centres(config, bits).iter().enumerate() {
        let ends: Vec<_> = lp.iter().map(|&e| vertex_of(e) as usize).collect();
        let centre = loop_centre(ends.iter().map(|&v| (slab.vertices[v], slab.normals[v])));
        centre_ids[k] = push_vertex(slab, centre);
    }
    for tri in table.triangles(config, bits) {
        slab.triangles.push(tri.map(|e| {
            if e < 12 {
                vertex_of(e)
            } else {
                centre_ids[e as usize - 12]
            }
        }));
    }
}

/// The extra vertex of a loop that needs one: mean position and normal.
pub(crate) fn loop_centre(points: impl ExactSizeIterator<Item = (DVec3, DVec3)>) -> (DVec3, DVec3) {
    let n = points.len() as f64;
    let (p, g) = points.fold((DVec3::ZERO, DVec3::ZERO), |(p, g), (q, h)| (p + q, g + h));
    (p / n, g.normalize_or_zero())
}

/// Concatenate slabs, identifying each slab's bottom plane vertices with
/// the previous slab's top plane vertices (same edges, same order).
fn merge_slabs(slabs: Vec<Slab>) -> TriMesh {
    let total_v: usize = slabs
        .iter()
        .map(|s| s.vertices.len() - s.bottom)
        .sum::<usize>()
        + slabs.first().map_or(0, |s| s.bottom);
    let total_t: usize = slabs.iter().map(|s| s.triangles.len()).sum();
    let mut mesh = TriMesh {
        vertices: Vec::with_capacity(total_v),
        triangles: Vec::with_capacity(total_t),
        normals: Some(Vec::with_capacity(total_v)),
    };
    let normals = mesh.normals.as_mut().expect("normals allocated above");
    let mut prev_top = 0usize;
    for (s, slab) in slabs.into_iter().enumerate() {
        let skip = if s == 0 { 0 } else { slab.bottom };
        let base = mesh.vertices.len();
        let remap = |v: u32| {
            let v = v as usize;
            (if v < skip {
                prev_top + v
            } else {
                base + v - skip
            }) as u32
        };
        mesh.triangles
            .extend(slab.triangles.iter().map(|t| t.map(remap)));
        mesh.vertices.extend_from_slice(&slab.vertices[skip..]);
        normals.extend_from_slice(&slab.normals[skip..]);
        prev_top = base + slab.top.start - skip;
    }
    mesh
}
