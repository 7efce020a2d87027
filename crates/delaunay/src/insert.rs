//! Incremental insertion (Bowyer–Watson) and point location.
//!
//! A point is located by a visibility walk from the last created
//! tetrahedron; the tetrahedra whose (perturbed) circumsphere contains it —
//! the conflict cavity — are found by a search from the located one, then
//! replaced by the cone from the new point over the cavity's boundary.

use crate::error::{DelaunayError, Result};
use crate::predicates::{insphere_sos, orient3d};
use crate::triangulation::{Location, TetId, Triangulation, VertexId, FACET, INF, MAX_TETS, NONE};
use glam::DVec3;

/// Reusable buffers of one insertion or removal, kept between calls so
/// insertions allocate nothing.
#[derive(Clone, Debug, Default)]
pub(crate) struct Scratch {
    /// Per tetrahedron: `epoch` if in the current cavity, `epoch + 1` if
    /// tested and not in it.
    mark: Vec<u32>,
    epoch: u32,
    stack: Vec<u32>,
    pub(crate) cavity: Vec<u32>,
    /// Facets of the hole to fill: vertices ordered with the hole on their
    /// positive side, and the encoded neighbour outside the hole.
    pub(crate) boundary: Vec<([u32; 3], u32)>,
    edges: EdgeTable,
}

/// Open-addressing table pairing the new tetrahedra's facets through the
/// apex: a facet `(apex, u, w)` meets the facet `(apex, w, u)` of its
/// neighbour. Cleared in O(1) by bumping a stamp.
#[derive(Clone, Debug, Default)]
struct EdgeTable {
    keys: Vec<u64>,
    values: Vec<u32>,
    stamps: Vec<u32>,
    stamp: u32,
}

impl EdgeTable {
    fn reset(&mut self, entries: usize) {
        let capacity = (entries * 4).next_power_of_two().max(64);
        if capacity > self.keys.len() || self.stamp == u32::MAX {
            let capacity = capacity.max(self.keys.len());
            self.keys = vec![0; capacity];
            self.values = vec![0; capacity];
            self.stamps = vec![0; capacity];
            self.stamp = 0;
        }
        self.stamp += 1;
    }

    #[inline]
    fn slot(&self, key: u64) -> usize {
        let bits = self.keys.len().trailing_zeros();
        (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - bits)) as usize
    }

    /// The value stored under `(w, u)` if any; otherwise store `value`
    /// under `(u, w)`.
    #[inline]
    fn pair(&mut self, u: u32, w: u32, value: u32) -> Option<u32> {
        let mask = self.keys.len() - 1;
        let want = ((w as u64) << 32) | u as u64;
        let mut i = self.slot(want);
        while self.stamps[i] == self.stamp {
            if self.keys[i] == want {
                return Some(self.values[i]);
            }
            i = (i + 1) & mask;
        }
        let own = ((u as u64) << 32) | w as u64;
        let mut i = self.slot(own);
        while self.stamps[i] == self.stamp {
            i = (i + 1) & mask;
        }
        self.keys[i] = own;
        self.values[i] = value;
        self.stamps[i] = self.stamp;
        None
    }
}

/// Result of a walk: the tetrahedron where it stopped and whether the point
/// is outside the hull (the tetrahedron is then a ghost).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Walk {
    pub tet: u32,
    pub outside: bool,
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
        if self.points.len() >= INF as usize {
            return Err(DelaunayError::TooLarge);
        }
        let v = self.points.len() as u32;
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
        let start = if self.tets.get(start.index()).is_some_and(|t| t[0] != NONE) {
            start.0
        } else {
            self.hint
        };
        let walk = self.walk(p, start);
        Ok(if walk.outside {
            Location::Outside(TetId(walk.tet))
        } else {
            Location::Inside(TetId(walk.tet))
        })
    }

    /// Make vertex `v` (its point already stored) part of the triangulation.
    /// Returns the existing vertex if `v`'s point is a duplicate.
    pub(crate) fn insert_vertex(&mut self, v: u32) -> Result<Option<u32>> {
        let p = self.points[v as usize];
        let walk = self.walk(p, self.hint);
        if !walk.outside {
            let tv = self.tets[walk.tet as usize];
            if let Some(&w) = tv.iter().find(|&&w| self.points[w as usize] == p) {
                return Ok(Some(w));
            }
        }
        self.find_cavity(walk.tet, v);
        let created = self.scratch.boundary.len();
        if self.tets.len() + created > MAX_TETS {
            return Err(DelaunayError::TooLarge);
        }
        let cavity = std::mem::take(&mut self.scratch.cavity);
        for &t in &cavity {
            self.free_tet(t);
        }
        self.scratch.cavity = cavity;
        self.cone(v, &[]);
        self.live_vertices += 1;
        Ok(None)
    }

    /// Visibility walk from `start` towards `p`: cross any facet that has
    /// `p` strictly on its far side, in a random facet order and never back
    /// through the facet just crossed (the "remembering stochastic walk",
    /// which cannot cycle). Stops in the finite tetrahedron containing `p`
    /// or in the first ghost, which means `p` is outside the hull.
    pub(crate) fn walk(&self, p: DVec3, start: u32) -> Walk {
        let mut t = start;
        if self.tets[t as usize][3] == INF {
            t = self.adj[t as usize][3] >> 2;
        }
        let mut previous = NONE;
        // Seeded from the point so that `locate` needs no mutable state.
        let mut random = (p.x.to_bits() ^ p.y.to_bits().rotate_left(21) ^ p.z.to_bits().rotate_left(42)) as u32 | 1;
        let mut steps = 0usize;
        'walk: loop {
            steps += 1;
            if steps > self.tets.len() + 16 {
                // Unreachable for a valid triangulation; a scan is the safe
                // answer rather than a hang.
                return self.scan_locate(p);
            }
            let tv = self.tets[t as usize];
            let first = next_random(&mut random) as usize;
            for k in 0..4 {
                let i = (first + k) & 3;
                let n = self.adj[t as usize][i] >> 2;
                if n == previous {
                    continue;
                }
                let [a, b, c] = FACET[i].map(|s| self.points[tv[s] as usize]);
                if orient3d(a, b, c, p) < 0.0 {
                    previous = t;
                    t = n;
                    if self.tets[t as usize][3] == INF {
                        return Walk { tet: t, outside: true };
                    }
                    continue 'walk;
                }
            }
            return Walk { tet: t, outside: false };
        }
    }

    /// Locate by testing every tetrahedron (fallback only).
    fn scan_locate(&self, p: DVec3) -> Walk {
        let inside = |t: u32| {
            let tv = self.tets[t as usize];
            (0..4).all(|i| {
                let [a, b, c] = FACET[i].map(|s| self.points[tv[s] as usize]);
                orient3d(a, b, c, p) >= 0.0
            })
        };
        if let Some(t) = self.finite_tets().map(|t| t.0).find(|&t| inside(t)) {
            return Walk { tet: t, outside: false };
        }
        let beyond = |t: u32| {
            let tv = self.tets[t as usize];
            let [a, b, c] = [0, 1, 2].map(|s| self.points[tv[s] as usize]);
            orient3d(a, b, c, p) > 0.0
        };
        let ghost = self.ghost_tets().map(|t| t.0).find(|&t| beyond(t)).unwrap_or(self.hint);
        Walk { tet: ghost, outside: true }
    }

    /// Whether vertex `v` lies in the perturbed circumsphere of `t`. For a
    /// ghost, the "sphere" is the open half-space beyond its hull facet; a
    /// point on the facet's plane conflicts exactly when it conflicts with
    /// the finite tetrahedron behind the facet (the limit of that sphere as
    /// its apex goes to infinity, same perturbation).
    #[inline]
    pub(crate) fn in_conflict(&self, t: u32, v: u32) -> bool {
        let tv = self.tets[t as usize];
        if tv[3] != INF {
            return self.finite_conflict(t, v);
        }
        let p = self.points[v as usize];
        let [a, b, c] = [0, 1, 2].map(|s| self.points[tv[s] as usize]);
        let o = orient3d(a, b, c, p);
        if o != 0.0 {
            return o > 0.0;
        }
        self.finite_conflict(self.adj[t as usize][3] >> 2, v)
    }

    #[inline]
    fn finite_conflict(&self, t: u32, v: u32) -> bool {
        let tv = self.tets[t as usize];
        let ids = [tv[0], tv[1], tv[2], tv[3], v];
        insphere_sos(ids.map(|i| self.points[i as usize]), ids)
    }

    /// Fill `scratch.cavity` with the tetrahedra in conflict with `v`
    /// (connected, found by a search from `start`, which is in conflict) and
    /// `scratch.boundary` with the cavity's boundary facets.
    fn find_cavity(&mut self, start: u32, v: u32) {
        let epoch = self.next_epoch();
        let s = &mut self.scratch;
        s.stack.clear();
        s.cavity.clear();
        s.boundary.clear();
        s.mark[start as usize] = epoch;
        s.stack.push(start);
        s.cavity.push(start);
        while let Some(t) = self.scratch.stack.pop() {
            for i in 0..4 {
                let n = self.adj[t as usize][i] >> 2;
                let mark = self.scratch.mark[n as usize];
                let inside = if mark == epoch {
                    continue;
                } else if mark == epoch + 1 {
                    false
                } else if self.in_conflict(n, v) {
                    self.scratch.mark[n as usize] = epoch;
                    self.scratch.stack.push(n);
                    self.scratch.cavity.push(n);
                    true
                } else {
                    self.scratch.mark[n as usize] = epoch + 1;
                    false
                };
                if !inside {
                    let tv = self.tets[t as usize];
                    let facet = FACET[i].map(|s| tv[s]);
                    self.scratch.boundary.push((facet, self.adj[t as usize][i]));
                }
            }
        }
    }

    /// A fresh pair of mark values (`epoch`, `epoch + 1`).
    pub(crate) fn next_epoch(&mut self) -> u32 {
        let s = &mut self.scratch;
        if s.mark.len() < self.tets.len() {
            s.mark.resize(self.tets.len(), 0);
        }
        if s.epoch >= u32::MAX - 2 {
            s.mark.iter_mut().for_each(|m| *m = 0);
            s.epoch = 0;
        }
        s.epoch += 2;
        s.epoch
    }

    /// Fill the hole described by `scratch.boundary` with the cone from
    /// `apex`: one tetrahedron per boundary facet, glued to the outside
    /// neighbour and, through the edge table, to each other. `seeds` are
    /// existing facets through the apex on the hole's rim, given like the
    /// boundary (hole on the positive side, outside neighbour).
    pub(crate) fn cone(&mut self, apex: u32, seeds: &[([u32; 3], u32)]) {
        let boundary = std::mem::take(&mut self.scratch.boundary);
        self.scratch.edges.reset(3 * boundary.len() + seeds.len());
        for &(facet, outside) in seeds {
            let k = facet.iter().position(|&x| x == apex).expect("seed facet holds the apex");
            let (u, w) = (facet[(k + 1) % 3], facet[(k + 2) % 3]);
            // Seen from the outside tetrahedron the facet is (apex, w, u).
            self.scratch.edges.pair(w, u, outside);
        }
        for &(facet, outside) in &boundary {
            let verts = ghost_last([facet[0], facet[1], facet[2], apex]);
            let t = self.alloc_tet(verts);
            for (slot, &x) in verts.iter().enumerate() {
                if x == apex {
                    self.link(t * 4 + slot as u32, outside);
                    continue;
                }
                let f = FACET[slot].map(|s| verts[s]);
                let k = f.iter().position(|&y| y == apex).expect("apex on the facet");
                let (u, w) = (f[(k + 1) % 3], f[(k + 2) % 3]);
                let here = t * 4 + slot as u32;
                if let Some(there) = self.scratch.edges.pair(u, w, here) {
                    self.link(here, there);
                }
            }
            for &x in &verts {
                if x != INF {
                    self.vertex_tet[x as usize] = t;
                }
            }
            if verts[3] != INF {
                self.hint = t;
            }
        }
        self.scratch.boundary = boundary;
    }

    /// Make two encoded facets neighbours of each other.
    #[inline]
    pub(crate) fn link(&mut self, a: u32, b: u32) {
        self.adj[(a >> 2) as usize][(a & 3) as usize] = b;
        self.adj[(b >> 2) as usize][(b & 3) as usize] = a;
    }

    pub(crate) fn alloc_tet(&mut self, verts: [u32; 4]) -> u32 {
        if verts[3] == INF {
            self.ghost_tets += 1;
        } else {
            self.finite_tets += 1;
        }
        if let Some(t) = self.free.pop() {
            self.tets[t as usize] = verts;
            return t;
        }
        self.tets.push(verts);
        self.adj.push([NONE; 4]);
        self.scratch.mark.push(0);
        (self.tets.len() - 1) as u32
    }

    pub(crate) fn free_tet(&mut self, t: u32) {
        if self.tets[t as usize][3] == INF {
            self.ghost_tets -= 1;
        } else {
            self.finite_tets -= 1;
        }
        self.tets[t as usize][0] = NONE;
        self.free.push(t);
    }
}

/// Reorder a tetrahedron by an even permutation (same orientation) so that
/// the infinite vertex, if any, is in slot 3.
#[inline]
pub(crate) fn ghost_last(v: [u32; 4]) -> [u32; 4] {
    if v[0] == INF {
        [v[3], v[2], v[1], v[0]]
    } else if v[1] == INF {
        [v[2], v[3], v[0], v[1]]
    } else if v[2] == INF {
        [v[1], v[0], v[3], v[2]]
    } else {
        v
    }
}
