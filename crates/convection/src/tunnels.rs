//! Tunnels through thin parts: where a plate thinner than the sampling
//! (the fin of the harness `spikes`) is swept through over a patch with no
//! sheet left to thicken, the solid has a hole through the plate, and the
//! mesh a handle the shape does not have.
//!
//! The inside of such a hole is made of small swept tetrahedra spanning
//! the plate from one face to the other; a real tunnel (the hole of a
//! handle or a torus) is spanned only by tetrahedra as large as the tunnel.
//! So the holes are closed by a growth with topology control over small
//! swept tetrahedra, followed by an erosion ([`close_tunnels`]):
//! 1. growth, smallest first: a candidate tetrahedron is added when it
//!    meets both the solid and the open (non-solid) tetrahedra in a disk
//!    of its facets (the topology stays the same and the boundary a
//!    manifold), or when it closes a tunnel: it meets the solid in a
//!    connected set with one loop, and the open regions across its free
//!    facets stay connected without it (no cavity is sealed off);
//! 2. erosion, largest first: every added tetrahedron that meets both the
//!    rest of the solid and the open tetrahedra in a disk is removed again
//!    (the topology stays the same), so creases filled on the way are
//!    emptied and only a membrane across each closed tunnel is left.
//!
//! No vertex may end inside the solid (every input point stays on the
//! mesh): an addition that would leave a vertex no open tetrahedron is
//! refused.

use crate::thin::edge_ring;
use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap, VecDeque};
use surfrecon_delaunay::{TetId, Triangulation};

/// What [`close_tunnels`] did.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct TunnelClosing {
    /// Additions that closed a tunnel.
    pub closed: usize,
    /// Tetrahedra added and kept after the erosion.
    pub kept: usize,
}

/// How a tetrahedron meets the solid, or the open, tetrahedra other than
/// itself (the part of its boundary they cover).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Contact {
    /// A disk made of 1 to 3 of its facets (with nothing else): adding or
    /// removing it keeps the topology and the boundary manifold.
    Disk,
    /// Connected with one loop: adding it closes a tunnel or seals a
    /// cavity.
    Loop,
    /// Anything else (none, all four facets, several pieces, edges or
    /// corners touching outside the facets).
    Other,
}

/// A key for the heaps: the size, then (tetrahedra around one longest edge
/// tie) the sorted corners, so the order does not depend on how the
/// triangulation numbers its tetrahedra.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Size(f64, [u32; 4], TetId);

impl Size {
    fn of(tri: &Triangulation, rank: &[u32], size: &impl Fn(TetId) -> f64, t: TetId) -> Self {
        Size(size(t), sorted_corners(tri, rank, t), t)
    }
}

impl Eq for Size {}

impl PartialOrd for Size {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Size {
    fn cmp(&self, other: &Self) -> Ordering {
        self.0
            .total_cmp(&other.0)
            .then(self.1.cmp(&other.1))
            .then(self.2.cmp(&other.2))
    }
}

/// The corners of `t` by their `rank` per vertex (the input index, which
/// does not depend on how the triangulation numbers its vertices and
/// tetrahedra), sorted; the infinite vertex ranks last.
pub(crate) fn sorted_corners(tri: &Triangulation, rank: &[u32], t: TetId) -> [u32; 4] {
    let mut corners = tri
        .tet_vertices(t)
        .map(|v| rank.get(v.index()).copied().unwrap_or(u32::MAX));
    corners.sort_unstable();
    corners
}

/// The solid (per tetrahedron slot) with, per vertex, the solid and the
/// open (non-solid finite or ghost) tetrahedra around it.
struct Solid<'a> {
    tri: &'a Triangulation,
    solid: &'a mut [bool],
    solid_around: Vec<u32>,
    open_around: Vec<u32>,
}

impl<'a> Solid<'a> {
    fn new(tri: &'a Triangulation, solid: &'a mut [bool]) -> Self {
        let n = tri.points().len();
        let (mut solid_around, mut open_around) = (vec![0; n], vec![0; n]);
        for t in tri.finite_tets().chain(tri.ghost_tets()) {
            let counts = match solid[t.index()] && !tri.is_ghost(t) {
                true => &mut solid_around,
                false => &mut open_around,
            };
            for v in tri.tet_vertices(t).iter().filter(|v| !v.is_infinite()) {
                counts[v.index()] += 1;
            }
        }
        Solid {
            tri,
            solid,
            solid_around,
            open_around,
        }
    }

    fn is_solid(&self, t: TetId) -> bool {
        self.solid[t.index()] && !self.tri.is_ghost(t)
    }

    fn set(&mut self, t: TetId, solid: bool) {
        self.solid[t.index()] = solid;
        for v in self.tri.tet_vertices(t) {
            let (gain, loss) = match solid {
                true => (&mut self.solid_around, &mut self.open_around),
                false => (&mut self.open_around, &mut self.solid_around),
            };
            gain[v.index()] += 1;
            loss[v.index()] -= 1;
        }
    }

    /// How `t` meets the tetrahedra other than itself that are solid
    /// (`solid` true) or open (false; ghosts are open).
    fn contact(&self, t: TetId, solid: bool) -> Contact {
        let tri = self.tri;
        let verts = tri.tet_vertices(t);
        let is_side = |u: TetId| self.is_solid(u) == solid;
        let around = match solid {
            true => &self.solid_around,
            false => &self.open_around,
        };
        let own = u32::from(is_side(t));
        let face_in: [bool; 4] = tri.neighbors(t).map(is_side);
        let vertex_in: [bool; 4] = verts.map(|v| around[v.index()] > own);
        let mut parent = [0, 1, 2, 3];
        let (mut edges, mut closed_by_faces) = (0, true);
        for i in 0..4 {
            for j in i + 1..4 {
                // The two facets holding edge ij are those opposite the
                // other two corners.
                let [k, l] = others(i, j);
                let by_face = face_in[k] || face_in[l];
                let inside = by_face
                    || (vertex_in[i]
                        && vertex_in[j]
                        && edge_ring(tri, t, verts[i], verts[j])
                            .into_iter()
                            .skip(1)
                            .any(is_side));
                if inside {
                    edges += 1;
                    closed_by_faces &= by_face;
                    let (a, b) = (find(&mut parent, i), find(&mut parent, j));
                    parent[a] = b;
                }
            }
        }
        let faces = face_in.iter().filter(|&&f| f).count();
        let vertices = vertex_in.iter().filter(|&&v| v).count();
        let mut roots = [false; 4];
        for i in (0..4).filter(|&i| vertex_in[i]) {
            roots[find(&mut parent, i)] = true;
        }
        let pieces = roots.iter().filter(|&&r| r).count();
        // Corner i lies on the facets other than facet i.
        closed_by_faces &= (0..4).all(|i| !vertex_in[i] || (0..4).any(|k| k != i && face_in[k]));
        let euler = vertices as i64 - edges as i64 + faces as i64;
        match (faces, pieces, euler) {
            (1..=3, 1, 1) if closed_by_faces => Contact::Disk,
            (1..=3, 1, 0) => Contact::Loop,
            _ => Contact::Other,
        }
    }

    /// Whether `t` can be added to (or removed from) the solid without
    /// changing the topology of either side or pinching the boundary: it
    /// meets both the solid and the open tetrahedra in a disk.
    fn is_simple(&self, t: TetId) -> bool {
        self.contact(t, true) == Contact::Disk && self.contact(t, false) == Contact::Disk
    }

    /// Whether adding `t` leaves every corner an open tetrahedron.
    fn buries_no_vertex(&self, t: TetId) -> bool {
        self.tri
            .tet_vertices(t)
            .iter()
            .all(|v| self.open_around[v.index()] > 1)
    }

    /// Whether the open tetrahedra across the free facets of `t` stay
    /// connected without `t` through open tetrahedra: then adding `t` cuts
    /// a loop of the outside rather than a cavity off it. The searches
    /// from the free facets advance in turn and merge where they meet, so
    /// an enclosed side is found after visiting about its own size; past
    /// `budget` tetrahedra in all the answer is no.
    fn free_sides_connected(&self, t: TetId, budget: usize) -> bool {
        let free: Vec<TetId> = self
            .tri
            .neighbors(t)
            .into_iter()
            .filter(|&u| !self.is_solid(u))
            .collect();
        if free.len() < 2 {
            return false;
        }
        let mut group: HashMap<TetId, usize> = HashMap::from([(t, usize::MAX)]);
        let mut parent: Vec<usize> = (0..free.len()).collect();
        let mut fronts: Vec<VecDeque<TetId>> = Vec::new();
        for (g, &u) in free.iter().enumerate() {
            group.insert(u, g);
            fronts.push(VecDeque::from([u]));
        }
        let mut groups = free.len();
        while group.len() <= budget {
            let mut advanced = false;
            for g in 0..fronts.len() {
                if parent[g] != g {
                    continue;
                }
                let Some(s) = fronts[g].pop_front() else {
                    // This side is enclosed.
                    return false;
                };
                advanced = true;
                for u in self.tri.neighbors(s) {
                    if self.is_solid(u) {
                        continue;
                    }
                    match group.get(&u) {
                        None => {
                            group.insert(u, g);
                            fronts[g].push_back(u);
                        }
                        Some(&h) if h != usize::MAX => {
                            let h = root(&mut parent, h);
                            if h != g {
                                parent[h] = g;
                                let moved = std::mem::take(&mut fronts[h]);
                                fronts[g].extend(moved);
                                groups -= 1;
                                if groups == 1 {
                                    return true;
                                }
                            }
                        }
                        Some(_) => {}
                    }
                }
            }
            if !advanced {
                return false;
            }
        }
        false
    }
}

fn root(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        i = parent[i];
    }
    i
}

/// The two indices of 0..4 other than `i` and `j`.
fn others(i: usize, j: usize) -> [usize; 2] {
    let mut o = (0..4).filter(|&k| k != i && k != j);
    [o.next().expect("two left"), o.next().expect("two left")]
}

fn find(parent: &mut [usize; 4], mut i: usize) -> usize {
    while parent[i] != i {
        i = parent[i];
    }
    i
}

/// Close tunnels of `solid` (per tetrahedron slot) through thin parts by
/// the growth over `candidate` tetrahedra (smallest `size` first) and the
/// erosion of what was added (largest first) described in the module doc.
/// `budget` bounds each connectivity search of the outside; `rank` (per
/// vertex) breaks ties of `size`.
pub(crate) fn close_tunnels(
    tri: &Triangulation,
    rank: &[u32],
    solid: &mut [bool],
    candidate: impl Fn(TetId) -> bool,
    size: impl Fn(TetId) -> f64,
    budget: usize,
) -> TunnelClosing {
    let mut s = Solid::new(tri, solid);
    let mut stats = TunnelClosing::default();
    let mut added = vec![false; s.solid.len()];
    let mut heap: BinaryHeap<std::cmp::Reverse<Size>> = BinaryHeap::new();
    let open_candidate = |s: &Solid, u: TetId| !s.is_solid(u) && !tri.is_ghost(u) && candidate(u);
    for t in tri.finite_tets().filter(|&t| s.is_solid(t)) {
        for u in tri.neighbors(t) {
            if open_candidate(&s, u) {
                heap.push(std::cmp::Reverse(Size::of(tri, rank, &size, u)));
            }
        }
    }
    while let Some(std::cmp::Reverse(Size(_, _, t))) = heap.pop() {
        if s.is_solid(t) || !s.buries_no_vertex(t) {
            continue;
        }
        match s.contact(t, true) {
            Contact::Disk if s.contact(t, false) == Contact::Disk => {}
            Contact::Loop if s.free_sides_connected(t, budget) => stats.closed += 1,
            _ => continue,
        }
        s.set(t, true);
        added[t.index()] = true;
        for u in tri.neighbors(t) {
            if open_candidate(&s, u) {
                heap.push(std::cmp::Reverse(Size::of(tri, rank, &size, u)));
            }
        }
    }
    erode(&mut s, rank, &mut added, &size);
    stats.kept = added.iter().filter(|&&a| a).count();
    stats
}

/// Remove the `added` tetrahedra whose removal keeps the topology, largest
/// first, until none is left to remove.
fn erode(s: &mut Solid, rank: &[u32], added: &mut [bool], size: &impl Fn(TetId) -> f64) {
    let tri = s.tri;
    let mut heap: BinaryHeap<Size> = (0..added.len())
        .filter(|&i| added[i])
        .map(|i| Size::of(tri, rank, size, TetId(i as u32)))
        .collect();
    while let Some(Size(_, _, t)) = heap.pop() {
        if !added[t.index()] || !s.is_simple(t) {
            continue;
        }
        s.set(t, false);
        added[t.index()] = false;
        for u in tri.neighbors(t) {
            if added[u.index()] {
                heap.push(Size::of(tri, rank, size, u));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use surfrecon_geom::DVec3;

    /// Two jittered 13×13 grids 0.04 apart: a plate whose Delaunay
    /// tetrahedra all span it (its hull is the plate itself).
    fn plate() -> Triangulation {
        let mut points = Vec::new();
        let mut x = 0x2545f4914f6cdd1d_u64;
        let mut jitter = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            ((x >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.02
        };
        for i in 0..13 {
            for j in 0..13 {
                for z in [0.0, 0.04] {
                    let (u, v) = (i as f64 / 12.0 + jitter(), j as f64 / 12.0 + jitter());
                    points.push(DVec3::new(u, v, z));
                }
            }
        }
        Triangulation::bulk_load(&points).unwrap()
    }

    fn identity(tri: &Triangulation) -> Vec<u32> {
        (0..tri.points().len() as u32).collect()
    }

    /// Distance in the plate's plane from the centroid of `t` to the centre.
    fn off_centre(tri: &Triangulation, t: TetId) -> f64 {
        let p = tri.tet_points(t);
        let m = (p[0] + p[1] + p[2] + p[3]) / 4.0;
        (m.x - 0.5).hypot(m.y - 0.5)
    }

    /// The tetrahedra farther than `radius` from the centre.
    fn plate_with_hole(tri: &Triangulation, radius: f64) -> Vec<bool> {
        let mut solid = vec![false; tri.tet_slots()];
        for t in tri.finite_tets() {
            solid[t.index()] = off_centre(tri, t) > radius;
        }
        solid
    }

    #[test]
    fn hole_through_a_plate_is_closed_by_a_membrane() {
        let tri = plate();
        let mut solid = plate_with_hole(&tri, 0.2);
        let before = solid.iter().filter(|&&s| s).count();
        let all = |_| true;
        let size = |t| crate::thin::longest_edge(&tri, t);
        let closing = close_tunnels(&tri, &identity(&tri), &mut solid, all, size, 20_000);
        assert_eq!(closing.closed, 1);
        let added = solid.iter().filter(|&&s| s).count() - before;
        assert_eq!(added, closing.kept);
        // The erosion leaves a membrane, not the filled hole.
        let hole = tri
            .finite_tets()
            .filter(|&t| off_centre(&tri, t) <= 0.2)
            .count();
        assert!(added > 0 && added < hole, "{added} of {hole}");
    }

    #[test]
    fn growth_that_closes_nothing_is_eroded_away() {
        let tri = plate();
        let original = plate_with_hole(&tri, 0.3);
        let mut solid = original.clone();
        // Only a ring around the hole may be added: it cannot close it.
        let ring = |t| off_centre(&tri, t) > 0.15;
        let size = |t| crate::thin::longest_edge(&tri, t);
        let closing = close_tunnels(&tri, &identity(&tri), &mut solid, ring, size, 20_000);
        assert_eq!(closing.closed, 0);
        assert_eq!(closing.kept, 0);
        assert_eq!(solid, original);
    }
}
