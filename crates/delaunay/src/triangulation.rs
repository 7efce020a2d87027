//! The triangulation's storage, typed handles and read-only queries.
//!
//! Storage invariants (checked by [`Triangulation::validate`]):
//! - every live tetrahedron is either *finite* (four finite vertices, exact
//!   `orient3d > 0`) or a *ghost*: a convex-hull facet `abc` plus the
//!   infinite vertex, always stored in slot 3, with `orient3d(a, b, c, q) < 0`
//!   for every finite vertex `q` not on the facet (the hull facet faces out);
//!   so every facet of the complex has exactly two sides;
//! - `n[i]` of tetrahedron `t` is the tetrahedron across the facet opposite slot `i`,
//!   encoded as `4 · tet + slot` where `slot` is the facet's index in that
//!   neighbour, and following it back leads to `4 · t + i` (neighbour
//!   symmetry);
//! - facet `i` of a tetrahedron is `FACET[i]`, ordered so that the vertex in
//!   slot `i` lies on its positive side;
//! - every tetrahedron is Delaunay for the symbolically perturbed points
//!   (see [`crate::predicates::insphere_sos`]).

use crate::predicates::{orient3d, StaticFilter};
use glam::DVec3;

/// The infinite vertex, apex of every ghost tetrahedron (slot 3).
pub(crate) const INF: u32 = u32::MAX - 1;
/// "No tetrahedron" (a vertex not in the triangulation) and the mark of a
/// freed tetrahedron in slot 0.
pub(crate) const NONE: u32 = u32::MAX;
/// Vertex ids stay below 2^30, leaving the top bits of a cell's vertex
/// slots free for search flags.
pub(crate) const MAX_VERTICES: usize = 1 << 30;
/// Tetrahedra are addressed as `4 · tet + slot` in `u32`.
pub(crate) const MAX_TETS: usize = (u32::MAX / 4) as usize;

/// Vertex slots of the facet opposite slot `i`, ordered so that slot `i` is
/// on its positive side (each row followed by `i` is an even permutation).
pub(crate) const FACET: [[usize; 3]; 4] = [[1, 3, 2], [0, 2, 3], [0, 3, 1], [0, 1, 2]];

/// A vertex: an index into [`Triangulation::points`]. `bulk_load` numbers
/// its vertices in insertion order (see [`Triangulation::vertex_of_input`]);
/// [`Triangulation::insert`] appends.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct VertexId(pub u32);

impl VertexId {
    /// The vertex at infinity that ghost tetrahedra share.
    pub const INFINITE: VertexId = VertexId(INF);

    pub fn index(self) -> usize {
        self.0 as usize
    }

    pub fn is_infinite(self) -> bool {
        self.0 == INF
    }
}

/// A tetrahedron slot; stable until the next insertion or removal.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TetId(pub u32);

impl TetId {
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// Where a query point lies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// In the closed finite tetrahedron.
    Inside(TetId),
    /// Outside the convex hull, strictly beyond the hull facet of this
    /// ghost tetrahedron.
    Outside(TetId),
}

/// One tetrahedron: its vertices `v` and encoded neighbours `n` side by
/// side in 32 bytes, because every step of the walk and of the cavity
/// search reads both.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub(crate) struct Cell {
    pub v: [u32; 4],
    pub n: [u32; 4],
}

/// A 3D Delaunay tetrahedralization with a vertex at infinity.
#[derive(Clone, Debug)]
pub struct Triangulation {
    /// Point of every vertex id (also of merged duplicates and removed
    /// vertices, which no tetrahedron uses).
    pub(crate) points: Vec<DVec3>,
    /// One tetrahedron incident to each vertex, `NONE` if not a vertex.
    pub(crate) vertex_tet: Vec<u32>,
    pub(crate) cells: Vec<Cell>,
    /// A box holding every point (`lo`, `hi`) and the predicates' static
    /// error bounds for it.
    pub(crate) bounds: [DVec3; 2],
    pub(crate) filter: StaticFilter,
    /// Freed tetrahedron slots for reuse.
    pub(crate) free: Vec<u32>,
    /// Input points merged into an existing vertex by `bulk_load`.
    pub(crate) merged: usize,
    /// Vertex of each `bulk_load` input point (the kept one for duplicates).
    pub(crate) input_vertex: Vec<u32>,
    /// `bulk_load` input index of each of its vertices.
    pub(crate) vertex_input: Vec<u32>,
    pub(crate) live_vertices: usize,
    pub(crate) finite_tets: usize,
    pub(crate) ghost_tets: usize,
    /// Whether insertions keep `vertex_tet` current; `bulk_load` skips it
    /// (nothing reads it while building) and sets it in one pass at the end.
    pub(crate) track_vertex_tets: bool,
    /// Where the next walk starts: the last tetrahedron created.
    pub(crate) hint: u32,
    /// Tetrahedra freed and created since the last [`Triangulation::take_changes`],
    /// when [`Triangulation::track_changes`] turned it on (off while building).
    pub(crate) changes: Option<Changes>,
    pub(crate) scratch: crate::insert::Scratch,
}

/// Tetrahedron slots an edit freed and created (a slot can be in both: it
/// was freed, then reused for a new tetrahedron).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Changes {
    pub freed: Vec<TetId>,
    pub created: Vec<TetId>,
}

impl Triangulation {
    /// Record which tetrahedra later edits ([`Triangulation::insert`],
    /// [`Triangulation::remove`]) free and create, for callers that keep
    /// data per tetrahedron and update it locally.
    pub fn track_changes(&mut self, on: bool) {
        self.changes = on.then(Changes::default);
    }

    /// The tetrahedra freed and created since the last call (empty when
    /// tracking is off).
    pub fn take_changes(&mut self) -> Changes {
        match &mut self.changes {
            Some(c) => std::mem::take(c),
            None => Changes::default(),
        }
    }

    /// Number of vertices (merged duplicates and removed vertices excluded).
    pub fn num_vertices(&self) -> usize {
        self.live_vertices
    }

    /// Number of finite tetrahedra.
    pub fn num_tets(&self) -> usize {
        self.finite_tets
    }

    /// One more than the largest tetrahedron index in use, finite or
    /// ghost: the length of a table indexed by [`TetId::index`].
    pub fn tet_slots(&self) -> usize {
        self.cells.len()
    }

    /// Number of convex-hull facets (= ghost tetrahedra).
    pub fn num_hull_facets(&self) -> usize {
        self.ghost_tets
    }

    /// Number of `bulk_load` input points that were exact duplicates of
    /// another and were merged into its vertex.
    pub fn merged_duplicates(&self) -> usize {
        self.merged
    }

    /// The vertex made for input point `i` of `bulk_load` (for a duplicate,
    /// the vertex it was merged into); it may since have been removed.
    pub fn vertex_of_input(&self, i: usize) -> Option<VertexId> {
        self.input_vertex.get(i).map(|&v| VertexId(v))
    }

    /// The `bulk_load` input index of vertex `v` (`None` for vertices added
    /// by [`Triangulation::insert`]).
    pub fn input_of_vertex(&self, v: VertexId) -> Option<usize> {
        self.vertex_input.get(v.index()).map(|&i| i as usize)
    }

    /// All points by vertex id, including merged and removed ones.
    pub fn points(&self) -> &[DVec3] {
        &self.points
    }

    /// The point of a finite vertex id.
    pub fn point(&self, v: VertexId) -> DVec3 {
        self.points[v.index()]
    }

    /// Whether `v` is a vertex of the triangulation now.
    pub fn contains_vertex(&self, v: VertexId) -> bool {
        self.vertex_tet.get(v.index()).is_some_and(|&t| t != NONE)
    }

    /// Vertices of the triangulation in id order.
    pub fn vertices(&self) -> impl Iterator<Item = VertexId> + '_ {
        (0..self.points.len() as u32)
            .filter(|&v| self.vertex_tet[v as usize] != NONE)
            .map(VertexId)
    }

    /// The finite tetrahedra, each positively oriented.
    /// Whether slot `t` holds a tetrahedron (finite or ghost) now.
    pub fn is_live(&self, t: TetId) -> bool {
        self.cells.get(t.index()).is_some_and(|c| c.v[0] != NONE)
    }

    pub fn finite_tets(&self) -> impl Iterator<Item = TetId> + '_ {
        self.live_slots()
            .filter(|&t| self.cells[t as usize].v[3] != INF)
            .map(TetId)
    }

    /// The ghost tetrahedra (one per hull facet, infinite vertex in slot 3).
    pub fn ghost_tets(&self) -> impl Iterator<Item = TetId> + '_ {
        self.live_slots()
            .filter(|&t| self.cells[t as usize].v[3] == INF)
            .map(TetId)
    }

    fn live_slots(&self) -> impl Iterator<Item = u32> + '_ {
        (0..self.cells.len() as u32).filter(|&t| self.cells[t as usize].v[0] != NONE)
    }

    /// The four vertices of `t` (a ghost has [`VertexId::INFINITE`] last).
    pub fn tet_vertices(&self, t: TetId) -> [VertexId; 4] {
        self.cells[t.index()].v.map(VertexId)
    }

    /// The four corner points of a finite tetrahedron.
    pub fn tet_points(&self, t: TetId) -> [DVec3; 4] {
        self.cells[t.index()].v.map(|v| self.points[v as usize])
    }

    /// Whether `t` is a ghost tetrahedron (outside the hull).
    pub fn is_ghost(&self, t: TetId) -> bool {
        self.cells[t.index()].v[3] == INF
    }

    /// Neighbour `i` is across the facet opposite vertex `i`.
    pub fn neighbors(&self, t: TetId) -> [TetId; 4] {
        self.cells[t.index()].n.map(|a| TetId(a >> 2))
    }

    /// The neighbour across facet `i` of `t` and that facet's index in it.
    pub fn mirror(&self, t: TetId, i: usize) -> (TetId, usize) {
        let a = self.cells[t.index()].n[i];
        (TetId(a >> 2), (a & 3) as usize)
    }

    /// Facet `i` of `t` (the three vertices other than slot `i`), ordered so
    /// that vertex `i` is on its positive side.
    pub fn facet(&self, t: TetId, i: usize) -> [VertexId; 3] {
        let v = self.cells[t.index()].v;
        FACET[i].map(|s| VertexId(v[s]))
    }

    /// Hull facets ordered so that `(b − a) × (c − a)` points outward.
    pub fn hull_facets(&self) -> impl Iterator<Item = [VertexId; 3]> + '_ {
        self.ghost_tets().map(|t| {
            let v = self.cells[t.index()].v;
            [VertexId(v[0]), VertexId(v[1]), VertexId(v[2])]
        })
    }

    /// All tetrahedra (finite and ghost) incident to vertex `v`; empty if
    /// `v` is not a vertex.
    pub fn incident_tets(&self, v: VertexId) -> Vec<TetId> {
        let mut out = Vec::new();
        if self.contains_vertex(v) {
            self.star(v.0, &mut out);
        }
        out.into_iter().map(TetId).collect()
    }

    /// Tetrahedra incident to `v` by a search over facets through `v`.
    pub(crate) fn star(&self, v: u32, out: &mut Vec<u32>) {
        out.clear();
        let start = self.vertex_tet[v as usize];
        out.push(start);
        let mut next = 0;
        while next < out.len() {
            let t = out[next] as usize;
            next += 1;
            for i in 0..4 {
                // Facets opposite the other slots contain v.
                if self.cells[t].v[i] == v {
                    continue;
                }
                let n = self.cells[t].n[i] >> 2;
                if !out.contains(&n) {
                    out.push(n);
                }
            }
        }
    }

    /// Sum of the finite tetrahedra's volumes: the convex hull's volume.
    pub fn volume(&self) -> f64 {
        // Six times the volumes, divided once: exact for integer points.
        let mut sum = 0.0;
        let mut compensation = 0.0;
        for t in self.finite_tets() {
            let [a, b, c, d] = self.tet_points(t);
            let six_volume = (b - a).cross(c - a).dot(d - a);
            // Kahan summation: millions of small terms.
            let y = six_volume - compensation;
            let s = sum + y;
            compensation = (s - sum) - y;
            sum = s;
        }
        sum / 6.0
    }

    /// Exact orientation of the finite tetrahedron `t` (positive if valid).
    pub fn orientation(&self, t: TetId) -> f64 {
        let [a, b, c, d] = self.tet_points(t);
        orient3d(a, b, c, d)
    }
}
