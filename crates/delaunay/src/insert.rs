//! Incremental insertion (Bowyer–Watson) and point location.
//!
//! A point is located by a visibility walk from the last created
//! tetrahedron; the tetrahedra whose (perturbed) circumsphere contains it —
//! the conflict cavity — are found by a search from the located one, then
//! replaced by the cone from the new point over the cavity's boundary.

use crate::error::{DelaunayError, Result};
use crate::predicates::{insphere_sos, insphere_static, orient3d, orient3d_filtered, StaticFilter};
use crate::triangulation::{
    Cell, Location, TetId, Triangulation, VertexId, FACET, INF, MAX_TETS, MAX_VERTICES, NONE,
};
use glam::DVec3;

/// Reusable buffers of one insertion or removal, kept between calls so
/// insertions allocate nothing.
#[derive(Clone, Debug, Default)]
pub(crate) struct Scratch {
    stack: Vec<u32>,
    pub(crate) cavity: Vec<u32>,
    /// Facets of the hole to fill: vertices ordered with the hole on their
    /// positive side, and the encoded neighbour outside the hole.
    pub(crate) boundary: Vec<([u32; 3], u32)>,
    edges: EdgeTable,
    rim: RimNumbers,
    /// The tetrahedra `cone` made, one per boundary facet.
    created: Vec<u32>,
}

/// Pairs the new tetrahedra's facets through the apex without hashing:
/// the hole's rim has few vertices (about 16 for 27 boundary facets on
/// uniform points), so each gets a small local number, and the facet
/// stored under the directed edge (u, w) sits at row u, column w of a
/// square table of width the next power of two (1 KB for 16 vertices,
/// always warm in L1). No probe loop and no branch that depends on the
/// data: the edge table's probes were most of the cone's time.
///
/// Local numbers live in `mark`, one entry per vertex id (the last for the
/// infinite vertex): `stamp << 8 | number`, valid for the current hole
/// when its stamp is current, so nothing is cleared between holes. Holes
/// with more than 256 rim vertices are left to the edge table.
#[derive(Clone, Debug, Default)]
struct RimNumbers {
    mark: Vec<u32>,
    stamp: u32,
    /// Per boundary facet: the local numbers of its vertices and its
    /// infinite-slot shift (see [`infinite_slot_shift`]).
    facets: Vec<[u8; 4]>,
    /// log2 of the table's width for the current hole.
    shift: u32,
    table: Vec<u32>,
}

/// Rim numbers fit in the low 8 bits of a mark.
const RIM_LIMIT: u32 = 256;
/// Marks hold the stamp above the number; it restarts before overflowing.
const RIM_STAMP_LIMIT: u32 = 1 << 24;

impl RimNumbers {
    /// Number the vertices of `boundary` (vertex ids below `vertices`, or
    /// the infinite vertex) in order of first appearance. False if there
    /// are more than [`RIM_LIMIT`].
    fn number(&mut self, boundary: &[([u32; 3], u32)], vertices: usize) -> bool {
        self.start_hole(vertices);
        self.facets.clear();
        let mut count = 0;
        for &(f, _) in boundary {
            let [a, b, c] = f.map(|v| self.local(v, &mut count));
            self.facets.push([a, b, c, infinite_slot_shift(f) as u8]);
        }
        if count > RIM_LIMIT {
            return false;
        }
        self.shift = count.max(2).next_power_of_two().trailing_zeros();
        let size = 1 << (2 * self.shift);
        if self.table.len() < size {
            self.table.resize(size, NONE);
        }
        true
    }

    /// A new stamp, and a mark for every vertex id below `vertices` plus
    /// the infinite vertex's (the last entry).
    fn start_hole(&mut self, vertices: usize) {
        if self.mark.len() < vertices + 1 {
            let old = self.mark.len();
            self.mark.resize((vertices + 1).max(2 * old), 0);
            // The old infinite vertex's entry now belongs to a vertex id.
            if let Some(m) = old.checked_sub(1) {
                self.mark[m] = 0;
            }
        }
        self.stamp += 1;
        if self.stamp == RIM_STAMP_LIMIT {
            self.mark.fill(0);
            self.stamp = 1;
        }
    }

    /// The local number of vertex `v`, the next one (`count`) if it has
    /// none yet. Branch-free: whether a vertex is new is as good as random.
    #[inline(always)]
    fn local(&mut self, v: u32, count: &mut u32) -> u8 {
        // Real vertex ids are below the last entry; the infinite one maps to it.
        let i = (v as usize).min(self.mark.len() - 1);
        let mark = self.mark[i];
        let fresh = mark >> 8 != self.stamp;
        let number = if fresh { *count } else { mark & 0xff } & 0xff;
        self.mark[i] = self.stamp << 8 | number;
        *count += u32::from(fresh);
        number as u8
    }

    #[inline(always)]
    fn slot(&self, u: u8, w: u8) -> usize {
        ((u as usize) << self.shift) | w as usize
    }
}

/// Open-addressing table pairing the new tetrahedra's facets through the
/// apex. Facet `(a, b, c)` of the hole's boundary, traversed in that cyclic
/// order, gives its new tetrahedron the facets through the apex and the
/// directed edges (b, c), (c, a), (a, b); the neighbouring boundary facet
/// traverses the shared edge the other way. So the cone stores every facet
/// under its directed edge, then finds each facet's partner under the
/// reversed edge: two passes, but no branch that depends on which of the
/// two facets came first. Cleared in O(1) by a stamp.
///
/// Each hole uses only a prefix of the entries sized for it: spread over
/// the whole table, which grows to the largest hole ever filled, a typical
/// hole's 80 entries touched as many cache lines, a third of all the
/// build's L1 misses.
#[derive(Clone, Debug, Default)]
struct EdgeTable {
    entries: Vec<EdgeEntry>,
    /// Size of the prefix in use, minus one.
    mask: usize,
    shift: u32,
    stamp: u32,
}

#[derive(Clone, Copy, Debug, Default)]
struct EdgeEntry {
    key: u64,
    value: u32,
    stamp: u32,
}

impl EdgeTable {
    fn reset(&mut self, entries: usize) {
        let capacity = (entries * 4).next_power_of_two().max(64);
        if capacity > self.entries.len() || self.stamp == u32::MAX {
            let size = capacity.max(self.entries.len());
            self.entries = vec![EdgeEntry::default(); size];
            self.stamp = 0;
        }
        self.mask = capacity - 1;
        self.shift = 64 - capacity.trailing_zeros();
        self.stamp += 1;
    }

    #[inline]
    fn slot(&self, key: u64) -> usize {
        (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> self.shift) as usize
    }

    /// Store `value` under the directed edge (u, w).
    #[inline]
    fn insert(&mut self, u: u32, w: u32, value: u32) {
        let key = ((u as u64) << 32) | w as u64;
        let mask = self.mask;
        let mut i = self.slot(key);
        while self.entries[i & mask].stamp == self.stamp {
            i += 1;
        }
        self.entries[i & mask] = EdgeEntry {
            key,
            value,
            stamp: self.stamp,
        };
    }

    /// The value stored under the directed edge (u, w), if any.
    #[inline]
    fn find(&self, u: u32, w: u32) -> Option<u32> {
        let key = ((u as u64) << 32) | w as u64;
        let mask = self.mask;
        let mut i = self.slot(key);
        loop {
            let entry = &self.entries[i & mask];
            if entry.stamp != self.stamp {
                return None;
            }
            if entry.key == key {
                return Some(entry.value);
            }
            i += 1;
        }
    }
}

/// Flag on `v[0]` of a cell in the cavity being searched. Vertex ids stay
/// below 2^30 (see `MAX_VERTICES`), so the top bit is free; slots 0 and 1
/// never hold the infinite vertex, and dead cells are never searched.
const IN_CAVITY: u32 = 1 << 31;
/// Flag on `v[1]` of a cell tested and found not in conflict.
const REJECTED: u32 = 1 << 31;
const FLAGS: u32 = 1 << 31;

/// Result of a walk: the tetrahedron where it stopped and whether the point
/// is outside the hull (the tetrahedron is then a ghost).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Walk {
    pub tet: u32,
    pub outside: bool,
}

/// For a boundary facet `(a, b, c)` with the hole on its positive side,
/// `(a, b, c, apex)` is positive; the even permutation `slot ^ x` of it
/// moves the infinite vertex, if any, to slot 3.
#[inline]
fn infinite_slot_shift([a, b, c]: [u32; 3]) -> usize {
    if a == INF {
        3
    } else if b == INF {
        2
    } else if c == INF {
        1
    } else {
        0
    }
}

/// A cell's vertex ids without the search flags (only slots 0 and 1
/// carry them; slot 3 may be the infinite vertex, whose id has the top
/// bit set).
#[inline(always)]
fn unflagged(v: [u32; 4]) -> [u32; 4] {
    [v[0] & !FLAGS, v[1] & !FLAGS, v[2], v[3]]
}

/// Append `item` to `list` if `keep`, with no branch on `keep`: the item is
/// written past the end either way and the length grows by `keep`.
#[inline(always)]
fn push_if<T: Copy>(list: &mut Vec<T>, item: T, keep: bool) {
    if list.len() == list.capacity() {
        list.reserve(list.len().max(16));
    }
    list.spare_capacity_mut()[0].write(item);
    // SAFETY: the element at `len` was just initialised and lies within
    // the capacity; `T: Copy`, so the written item needs no drop if it is
    // not kept.
    unsafe { list.set_len(list.len() + usize::from(keep)) };
}

/// Cheap xorshift step for the walk's random facet order.
#[inline]
fn next_random(state: &mut u32) -> u32 {
    *state ^= *state << 13;
    *state ^= *state >> 17;
    *state ^= *state << 5;
    *state
}

impl Triangulation {
    /// Insert a point; returns its new vertex, or the existing vertex at
    /// exactly the same position (duplicates are merged).
    pub fn insert(&mut self, p: DVec3) -> Result<VertexId> {
        if !p.is_finite() {
            return Err(DelaunayError::NonFinite {
                index: self.points.len(),
            });
        }
        if self.points.len() >= MAX_VERTICES {
            return Err(DelaunayError::TooLarge);
        }
        let v = self.points.len() as u32;
        self.include_in_bounds(p);
        self.points.push(p);
        self.vertex_tet.push(NONE);
        match self.insert_vertex(v) {
            Ok(None) => Ok(VertexId(v)),
            Ok(Some(existing)) => {
                self.points.pop();
                self.vertex_tet.pop();
                Ok(VertexId(existing))
            }
            Err(e) => {
                self.points.pop();
                self.vertex_tet.pop();
                Err(e)
            }
        }
    }

    /// Grow the box holding every point to hold `p` too, with its filter.
    fn include_in_bounds(&mut self, p: DVec3) {
        let [lo, hi] = self.bounds;
        if lo.cmple(p).all() && p.cmple(hi).all() {
            return;
        }
        self.bounds = [lo.min(p), hi.max(p)];
        self.filter = StaticFilter::for_box(self.bounds[0], self.bounds[1]);
    }

    /// The orientation tests' static bound for a walk towards `p`, which
    /// may lie outside the box of the vertices.
    fn orient_bound_towards(&self, p: DVec3) -> f64 {
        let [lo, hi] = self.bounds;
        if lo.cmple(p).all() && p.cmple(hi).all() {
            self.filter.orient
        } else {
            StaticFilter::for_box(lo.min(p), hi.max(p)).orient
        }
    }

    /// Where `p` lies: in a finite tetrahedron or beyond a hull facet.
    pub fn locate(&self, p: DVec3) -> Result<Location> {
        self.locate_from(p, TetId(self.hint))
    }

    /// [`Triangulation::locate`] with the walk starting at `start` (a
    /// tetrahedron near `p` makes it fast).
    pub fn locate_from(&self, p: DVec3, start: TetId) -> Result<Location> {
        if !p.is_finite() {
            return Err(DelaunayError::NonFinite { index: 0 });
        }
        let start = if self
            .cells
            .get(start.index())
            .is_some_and(|c| c.v[0] != NONE)
        {
            start.0
        } else {
            self.hint
        };
        let walk = self.walk(p, start, self.orient_bound_towards(p));
        Ok(if walk.outside {
            Location::Outside(TetId(walk.tet))
        } else {
            Location::Inside(TetId(walk.tet))
        })
    }

    /// The vertex nearest to `p`: from a corner of the tetrahedron where
    /// `p` lies, see [`Triangulation::nearest_vertex_from`].
    pub fn nearest_vertex(&self, p: DVec3) -> Result<VertexId> {
        let t = match self.locate(p)? {
            Location::Inside(t) | Location::Outside(t) => t,
        };
        let start = self.cells[t.index()].v[0];
        self.nearest_vertex_from(p, VertexId(start))
    }

    /// The vertex nearest to `p`, by moving from vertex `start` (a vertex
    /// near `p` makes it fast) to a closer Delaunay neighbour while there
    /// is one: in a Delaunay triangulation a vertex that is not the nearest
    /// has a closer neighbour (the segment to `p` leaves its Voronoi cell
    /// through a neighbour's).
    pub fn nearest_vertex_from(&self, p: DVec3, start: VertexId) -> Result<VertexId> {
        if !p.is_finite() {
            return Err(DelaunayError::NonFinite { index: 0 });
        }
        if start.is_infinite() || !self.contains_vertex(start) {
            return Err(DelaunayError::UnknownVertex(start.0));
        }
        let distance = |v: u32| self.points[v as usize].distance_squared(p);
        let mut best = start.0;
        let mut star = Vec::new();
        loop {
            self.star(best, &mut star);
            let closer = star
                .iter()
                .flat_map(|&t| self.cells[t as usize].v)
                .filter(|&v| v != INF)
                .min_by(|&a, &b| distance(a).total_cmp(&distance(b)).then(a.cmp(&b)))
                .filter(|&v| distance(v) < distance(best));
            match closer {
                Some(v) => best = v,
                None => return Ok(VertexId(best)),
            }
        }
    }

    /// Make vertex `v` (its point already stored) part of the triangulation.
    /// Returns the existing vertex if `v`'s point is a duplicate.
    pub(crate) fn insert_vertex(&mut self, v: u32) -> Result<Option<u32>> {
        let p = self.points[v as usize];
        // Vertices are inside the box (`insert` grew it).
        let walk = self.walk(p, self.hint, self.filter.orient);
        if !walk.outside {
            let tv = self.cells[walk.tet as usize].v;
            if let Some(&w) = tv.iter().find(|&&w| self.points[w as usize] == p) {
                return Ok(Some(w));
            }
        }
        self.find_cavity(walk.tet, v);
        let created = self.scratch.boundary.len();
        if self.cells.len() + created > MAX_TETS {
            return Err(DelaunayError::TooLarge);
        }
        let cavity = std::mem::take(&mut self.scratch.cavity);
        self.free_tets(&cavity);
        self.scratch.cavity = cavity;
        self.cone(v, &[]);
        self.live_vertices += 1;
        Ok(None)
    }

    /// Visibility walk from `start` towards `p`: cross a facet that has
    /// `p` strictly on its far side, trying facets in a random order and
    /// never straight back (the remembering stochastic walk, which ends with
    /// probability 1 whatever the triangulation). Stops in the finite
    /// tetrahedron containing `p`, or in the first ghost reached, which
    /// means `p` is outside the hull.
    /// `orient_bound` is the static filter's bound for a box holding `p`
    /// and every vertex.
    pub(crate) fn walk(&self, p: DVec3, start: u32, orient_bound: f64) -> Walk {
        let mut t = start as usize;
        if self.cells[t].v[3] == INF {
            t = (self.cells[t].n[3] >> 2) as usize;
        }
        let mut previous = NONE;
        // Seeded from the point so that `locate` needs no mutable state.
        let mut random =
            (p.x.to_bits() ^ p.y.to_bits().rotate_left(21) ^ p.z.to_bits().rotate_left(42)) as u32
                | 1;
        let mut steps = 0usize;
        'walk: loop {
            steps += 1;
            if steps > self.cells.len() + 16 {
                // Unreachable for a valid triangulation; a scan is the safe
                // answer rather than a hang.
                return self.scan_locate(p);
            }
            let cell = &self.cells[t];
            let first = next_random(&mut random) as usize;
            for k in 0..4 {
                let i = (first + k) & 3;
                let n = cell.n[i] >> 2;
                if n == previous {
                    continue;
                }
                let f = &FACET[i];
                let a = self.points[cell.v[f[0]] as usize];
                let b = self.points[cell.v[f[1]] as usize];
                let c = self.points[cell.v[f[2]] as usize];
                if orient3d_filtered(a, b, c, p, orient_bound) < 0.0 {
                    previous = t as u32;
                    t = n as usize;
                    if self.cells[t].v[3] == INF {
                        return Walk {
                            tet: t as u32,
                            outside: true,
                        };
                    }
                    continue 'walk;
                }
            }
            return Walk {
                tet: t as u32,
                outside: false,
            };
        }
    }

    /// Locate by testing every tetrahedron (fallback only).
    fn scan_locate(&self, p: DVec3) -> Walk {
        let inside = |t: u32| {
            let tv = self.cells[t as usize].v;
            (0..4).all(|i| {
                let [a, b, c] = FACET[i].map(|s| self.points[tv[s] as usize]);
                orient3d(a, b, c, p) >= 0.0
            })
        };
        if let Some(t) = self.finite_tets().map(|t| t.0).find(|&t| inside(t)) {
            return Walk {
                tet: t,
                outside: false,
            };
        }
        let beyond = |t: u32| {
            let tv = self.cells[t as usize].v;
            let [a, b, c] = [0, 1, 2].map(|s| self.points[tv[s] as usize]);
            orient3d(a, b, c, p) > 0.0
        };
        let ghost = self
            .ghost_tets()
            .map(|t| t.0)
            .find(|&t| beyond(t))
            .unwrap_or(self.hint);
        Walk {
            tet: ghost,
            outside: true,
        }
    }

    /// Whether vertex `v` lies in the perturbed circumsphere of `t`. For a
    /// ghost, the "sphere" is the open half-space beyond its hull facet; a
    /// point on the facet's plane conflicts exactly when it conflicts with
    /// the finite tetrahedron behind the facet (the limit of that sphere as
    /// its apex goes to infinity, same perturbation).
    #[inline]
    pub(crate) fn in_conflict(&self, t: u32, v: u32) -> bool {
        let cell = &self.cells[t as usize];
        if cell.v[3] != INF {
            return self.finite_conflict(t, v);
        }
        let p = self.points[v as usize];
        let a = self.points[(cell.v[0] & !FLAGS) as usize];
        let b = self.points[(cell.v[1] & !FLAGS) as usize];
        let c = self.points[cell.v[2] as usize];
        let o = orient3d_filtered(a, b, c, p, self.filter.orient);
        if o != 0.0 {
            return o > 0.0;
        }
        self.finite_conflict(cell.n[3] >> 2, v)
    }

    #[inline]
    fn finite_conflict(&self, t: u32, v: u32) -> bool {
        // `t` may be flagged when reached from a coplanar ghost.
        let ids = unflagged(self.cells[t as usize].v);
        // One by one: an array of points went through the stack, and
        // reading it back in other widths stalled on store forwarding.
        let a = self.points[ids[0] as usize];
        let b = self.points[ids[1] as usize];
        let c = self.points[ids[2] as usize];
        let d = self.points[ids[3] as usize];
        let e = self.points[v as usize];
        match insphere_static(a, b, c, d, e, self.filter.insphere) {
            Some(det) => det > 0.0,
            None => self.finite_conflict_exact(ids, v),
        }
    }

    /// [`Triangulation::finite_conflict`] when the static filter does not
    /// decide: the exact test with its symbolic perturbation.
    #[cold]
    #[inline(never)]
    fn finite_conflict_exact(&self, [i0, i1, i2, i3]: [u32; 4], v: u32) -> bool {
        let pts = [i0, i1, i2, i3, v].map(|i| self.points[i as usize]);
        insphere_sos(pts, [i0, i1, i2, i3, v])
    }

    /// Fill `scratch.cavity` with the tetrahedra in conflict with `v`
    /// (connected, found by a search from `start`, which is in conflict) and
    /// `scratch.boundary` with the cavity's boundary facets.
    ///
    /// Search state lives in the cells themselves (flag bits on vertex ids,
    /// see [`IN_CAVITY`]): the cell is loaded anyway, a side array would
    /// cost one more cache miss per test. Before a neighbour's in-sphere
    /// test, its own neighbours are prefetched: the test takes long enough
    /// to hide much of their load if it joins the cavity (about half do).
    /// The search stays depth first, each cell's facets in slot order: the
    /// new tetrahedra are numbered in the order of the boundary it lists,
    /// and callers' results can depend on that numbering (a breadth-first
    /// search, as fast, changed the convection's result on the thin-fin
    /// test; the convection's mesh no longer depends on it, other callers'
    /// may).
    ///
    /// The stack holds each cell with the facet it was reached through
    /// (encoded like a neighbour), and that facet, whose other side is in
    /// the cavity, is not visited again: it was half of the "already in
    /// the cavity" outcomes, as good as random to the branch predictor.
    fn find_cavity(&mut self, start: u32, v: u32) {
        let mut s = std::mem::take(&mut self.scratch);
        s.stack.clear();
        s.cavity.clear();
        s.boundary.clear();
        self.cells[start as usize].v[0] |= IN_CAVITY;
        s.cavity.push(start);
        self.prefetch_neighbours(start);
        let cell = self.cells[start as usize];
        let verts = unflagged(cell.v);
        for i in 0..4 {
            self.visit_neighbour(&mut s, &verts, i, cell.n[i], v);
        }
        while let Some(reached) = s.stack.pop() {
            let (t, entry) = ((reached >> 2) as usize, (reached & 3) as usize);
            let cell = self.cells[t];
            let verts = unflagged(cell.v);
            // The other three slots in increasing order (the order of a
            // visit of all four, so the same boundary order); spelled out,
            // as a loop its branch mispredicted once per cell.
            let [i, j, k] = [0, 1, 2].map(|k| k + usize::from(k >= entry));
            self.visit_neighbour(&mut s, &verts, i, cell.n[i], v);
            self.visit_neighbour(&mut s, &verts, j, cell.n[j], v);
            self.visit_neighbour(&mut s, &verts, k, cell.n[k], v);
        }
        // The tetrahedra tested and found not in conflict are those
        // behind the boundary.
        for &(_, outside) in &s.boundary {
            self.cells[(outside >> 2) as usize].v[1] &= !REJECTED;
        }
        self.scratch = s;
    }

    /// One step of [`Triangulation::find_cavity`]: the neighbour `across`
    /// facet `i` of a cavity cell with vertices `verts` joins the cavity,
    /// or that facet joins the boundary.
    ///
    /// The in-sphere test's outcome, as good as random, drives no branch:
    /// each list the neighbour or the facet could go to gets the entry and
    /// keeps it or not ([`push_if`]), and one of the neighbour's two flags
    /// is set by index. A mispredicted branch on it threw away the tests
    /// of the cell's other neighbours that had started meanwhile; now they
    /// overlap.
    #[inline(always)]
    fn visit_neighbour(
        &mut self,
        s: &mut Scratch,
        verts: &[u32; 4],
        i: usize,
        across: u32,
        v: u32,
    ) {
        let n = across >> 2;
        let other = &self.cells[n as usize];
        if other.v[0] & IN_CAVITY != 0 {
            return;
        }
        // Rejected already (reached through another facet): rare.
        let conflict = if other.v[1] & REJECTED == 0 {
            // Whether `n` joins the cavity is known only after its test;
            // start loading its neighbours now, in case.
            self.prefetch_neighbours(n);
            self.in_conflict(n, v)
        } else {
            false
        };
        // IN_CAVITY on slot 0 if in conflict, else REJECTED on slot 1.
        self.cells[n as usize].v[usize::from(!conflict)] |= FLAGS;
        push_if(&mut s.stack, across, conflict);
        push_if(&mut s.cavity, n, conflict);
        let f = &FACET[i];
        let facet = [verts[f[0]], verts[f[1]], verts[f[2]]];
        push_if(&mut s.boundary, (facet, across), !conflict);
    }

    /// Start loading the neighbours of `t` (no effect on results): their
    /// first touch is a cache miss far more often than not.
    #[inline(always)]
    fn prefetch_neighbours(&self, t: u32) {
        #[cfg(target_arch = "x86_64")]
        for &a in &self.cells[t as usize].n {
            let cell: *const Cell = &self.cells[(a >> 2) as usize];
            // SAFETY: prefetching has no effect on memory and cannot fault;
            // the address is in bounds anyway.
            unsafe {
                std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(cell.cast())
            };
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = t;
    }

    /// Fill the hole described by `scratch.boundary` with the cone from
    /// `apex`: one tetrahedron per boundary facet, glued to the outside
    /// neighbour and to each other (see [`RimNumbers`], or the edge table
    /// for very large holes and for seeds). `seeds` are existing facets
    /// through the apex on the hole's rim, given like the boundary (hole on
    /// the positive side, outside neighbour).
    pub(crate) fn cone(&mut self, apex: u32, seeds: &[([u32; 3], u32)]) {
        let boundary = std::mem::take(&mut self.scratch.boundary);
        let mut created = std::mem::take(&mut self.scratch.created);
        created.clear();
        let mut ghosts = 0;
        for &([a, b, c], outside) in &boundary {
            let x = infinite_slot_shift([a, b, c]);
            // Slot `s` holds corner `s ^ x` of (a, b, c, apex); spelled out
            // with constant indices so the cell is built in registers (a
            // permutation by a variable index goes through the stack, and
            // reading it back whole stalls on store forwarding).
            let verts = match x {
                0 => [a, b, c, apex],
                1 => [b, a, apex, c],
                2 => [c, apex, a, b],
                _ => [apex, c, b, a],
            };
            let t = self.alloc_uncounted(verts);
            ghosts += usize::from(verts[3] == INF);
            created.push(t);
            self.link(t * 4 + (3 ^ x) as u32, outside);
            if self.track_vertex_tets {
                for &y in &verts {
                    if y != INF {
                        self.vertex_tet[y as usize] = t;
                    }
                }
            }
            if verts[3] != INF {
                self.hint = t;
            }
        }
        self.count_tets(boundary.len() - ghosts, ghosts);
        if seeds.is_empty() && self.pair_by_rim_numbers(&boundary, &created) {
            // Done without the edge table.
        } else {
            self.pair_by_edge_table(apex, seeds, &boundary, &created);
        }
        self.scratch.boundary = boundary;
        self.scratch.created = created;
    }

    /// Glue the cone's tetrahedra `created` (one per facet of `boundary`)
    /// to each other through [`RimNumbers`]. False, with nothing glued,
    /// if the rim has too many vertices.
    fn pair_by_rim_numbers(&mut self, boundary: &[([u32; 3], u32)], created: &[u32]) -> bool {
        let mut rim = std::mem::take(&mut self.scratch.rim);
        let numbered = rim.number(boundary, self.points.len());
        if numbered {
            // Facet (a, b, c) traversed in that cyclic order gives its
            // tetrahedron the facets through the apex opposite a, b, c,
            // holding the directed edges (b, c), (c, a), (a, b); the
            // neighbouring boundary facet traverses the shared edge the
            // other way, so every facet is stored first, then found under
            // its reversed edge (every directed edge of the closed rim is
            // stored once).
            for (&[a, b, c, x], &t) in rim.facets.iter().zip(created) {
                let (t, x) = (t * 4, x as u32);
                let slots = [rim.slot(b, c), rim.slot(c, a), rim.slot(a, b)];
                rim.table[slots[0]] = t + x;
                rim.table[slots[1]] = t + (1 ^ x);
                rim.table[slots[2]] = t + (2 ^ x);
            }
            for (&[a, b, c, x], &t) in rim.facets.iter().zip(created) {
                let x = x as usize;
                let n = [
                    rim.table[rim.slot(c, b)],
                    rim.table[rim.slot(a, c)],
                    rim.table[rim.slot(b, a)],
                ];
                let cell = &mut self.cells[t as usize];
                cell.n[x] = n[0];
                cell.n[1 ^ x] = n[1];
                cell.n[2 ^ x] = n[2];
            }
        }
        self.scratch.rim = rim;
        numbered
    }

    /// Glue the cone's tetrahedra `created` (one per facet of `boundary`)
    /// to each other and to `seeds` through the hashed [`EdgeTable`].
    fn pair_by_edge_table(
        &mut self,
        apex: u32,
        seeds: &[([u32; 3], u32)],
        boundary: &[([u32; 3], u32)],
        created: &[u32],
    ) {
        let mut edges = std::mem::take(&mut self.scratch.edges);
        edges.reset(3 * boundary.len() + seeds.len());
        for &(facet, outside) in seeds {
            // The seed (apex, u, w) has the hole on its positive side: the
            // new tetrahedron behind it traverses the edge as (w, u) and
            // looks its partner up under (u, w).
            let k = facet.iter().position(|&x| x == apex).unwrap_or(0);
            let (u, w) = (facet[(k + 1) % 3], facet[(k + 2) % 3]);
            edges.insert(u, w, outside);
        }
        for (&([a, b, c], _), &t) in boundary.iter().zip(created) {
            let x = infinite_slot_shift([a, b, c]) as u32;
            // The facet through the apex opposite a holds the edge (b, c);
            // likewise for b and c.
            edges.insert(b, c, t * 4 + x);
            edges.insert(c, a, t * 4 + (1 ^ x));
            edges.insert(a, b, t * 4 + (2 ^ x));
        }
        // Each new facet through the apex sets its own side; the partner
        // sets the other when its turn comes, except seeds, linked here.
        for &(facet, outside) in seeds {
            let k = facet.iter().position(|&x| x == apex).unwrap_or(0);
            let (u, w) = (facet[(k + 1) % 3], facet[(k + 2) % 3]);
            if let Some(here) = edges.find(w, u) {
                self.link(here, outside);
            }
        }
        for (&([a, b, c], _), &t) in boundary.iter().zip(created) {
            let x = infinite_slot_shift([a, b, c]);
            let cell = &mut self.cells[t as usize];
            for (slot, u, w) in [(x, c, b), (1 ^ x, a, c), (2 ^ x, b, a)] {
                let there = edges.find(u, w);
                debug_assert!(there.is_some(), "cone: no partner for edge {u}-{w}");
                if let Some(there) = there {
                    cell.n[slot] = there;
                }
            }
        }
        self.scratch.edges = edges;
    }

    /// Make two encoded facets neighbours of each other.
    #[inline]
    pub(crate) fn link(&mut self, a: u32, b: u32) {
        self.cells[(a >> 2) as usize].n[(a & 3) as usize] = b;
        self.cells[(b >> 2) as usize].n[(b & 3) as usize] = a;
    }

    #[inline]
    pub(crate) fn alloc_tet(&mut self, verts: [u32; 4]) -> u32 {
        self.count_tets(usize::from(verts[3] != INF), usize::from(verts[3] == INF));
        self.alloc_uncounted(verts)
    }

    /// Add to the counts of finite and ghost tetrahedra. Callers that make
    /// or free many sum them first: counting each in place compiled to an
    /// add to memory at an address chosen by the ghost test, each waiting
    /// for the one before.
    #[inline]
    fn count_tets(&mut self, finite: usize, ghosts: usize) {
        self.finite_tets += finite;
        self.ghost_tets += ghosts;
    }

    /// [`Triangulation::alloc_tet`] without counting it.
    #[inline]
    fn alloc_uncounted(&mut self, verts: [u32; 4]) -> u32 {
        let t = match self.free.pop() {
            Some(t) => {
                self.cells[t as usize].v = verts;
                t
            }
            None => {
                self.cells.push(Cell {
                    v: verts,
                    n: [NONE; 4],
                });
                (self.cells.len() - 1) as u32
            }
        };
        if let Some(c) = &mut self.changes {
            c.created.push(TetId(t));
        }
        t
    }

    /// [`Triangulation::free_tet`] for each of `tets`, counted once.
    fn free_tets(&mut self, tets: &[u32]) {
        let mut ghosts = 0;
        for &t in tets {
            let cell = &mut self.cells[t as usize];
            ghosts += usize::from(cell.v[3] == INF);
            cell.v[0] = NONE;
        }
        self.finite_tets -= tets.len() - ghosts;
        self.ghost_tets -= ghosts;
        self.free.extend_from_slice(tets);
        if let Some(c) = &mut self.changes {
            c.freed.extend(tets.iter().map(|&t| TetId(t)));
        }
    }

    pub(crate) fn free_tet(&mut self, t: u32) {
        if self.cells[t as usize].v[3] == INF {
            self.ghost_tets -= 1;
        } else {
            self.finite_tets -= 1;
        }
        self.cells[t as usize].v[0] = NONE;
        self.free.push(t);
        if let Some(c) = &mut self.changes {
            c.freed.push(TetId(t));
        }
    }
}
