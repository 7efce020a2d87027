//! The evolving pseudo-surface: oriented Delaunay facets, opened and
//! collapsed by the convection.
//!
//! An oriented facet is a (tetrahedron, slot) pair of the triangulation,
//! facing *into* that tetrahedron (the inside of the pseudo-surface is on
//! the tetrahedron's side). Each Delaunay facet thus has two oriented
//! facets, one per side. Tetrahedra are *internal* (not yet reached) or
//! *external* (swept by the surface; every ghost from the start).
//!
//! Invariants (kept by [`PseudoSurface::open`] and [`PseudoSurface::collapse`]):
//! - the tetrahedron behind a surface facet is external;
//! - a surface facet facing an external tetrahedron has its mirror facet on
//!   the surface too: the two are *coupled* (a sheet of zero thickness).
//!
//! Storage: one flag per oriented facet and per tetrahedron, and a FIFO
//! queue of facets to test (breadth-first, as in the paper); nothing is
//! allocated per facet.

use crate::gabriel::in_diametral_ball;
use rayon::prelude::*;
use std::collections::VecDeque;
use surfrecon_delaunay::{TetId, Triangulation, VertexId};
use surfrecon_geom::DVec3;

/// Facet `slot` of tetrahedron `tet`, facing into `tet`; stored as
/// `4 · tet + slot`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct OrientedFacet(u32);

impl OrientedFacet {
    pub fn new(tet: TetId, slot: usize) -> Self {
        OrientedFacet(tet.0 * 4 + slot as u32)
    }

    pub fn tet(self) -> TetId {
        TetId(self.0 >> 2)
    }

    pub fn slot(self) -> usize {
        (self.0 & 3) as usize
    }

    fn index(self) -> usize {
        self.0 as usize
    }
}

/// The oriented Gabriel test of every oriented facet, decided for all of
/// them up front, in parallel: four bits per tetrahedron slot. A facet's
/// test reads only its own tetrahedron (three corners and the apex), so a
/// pass over the cells in storage order is cheap, while the convection's
/// own order reaches cells and points at random (a cache miss each: the
/// tests took 10% of an all-points Dragon-scale run).
struct GabrielTable {
    violations: Vec<u8>,
}

impl GabrielTable {
    fn new(tri: &Triangulation) -> Self {
        let violations = (0..tri.tet_slots() as u32)
            .into_par_iter()
            .with_min_len(4096)
            .map(|t| Self::tet_violations(tri, TetId(t)))
            .collect();
        GabrielTable { violations }
    }

    /// Bit `slot` set when facet `slot` of `t`, facing into `t`, violates
    /// the property (see [`PseudoSurface::violates_gabriel`]); none for
    /// ghosts and free slots.
    fn tet_violations(tri: &Triangulation, t: TetId) -> u8 {
        if !tri.is_live(t) || tri.is_ghost(t) {
            return 0;
        }
        let apexes = tri.tet_points(t);
        let mut bits = 0;
        for (slot, &apex) in apexes.iter().enumerate() {
            let [a, b, c] = tri.facet(t, slot).map(|v| tri.point(v));
            if in_diametral_ball(a, b, c, apex) {
                bits |= 1 << slot;
            }
        }
        bits
    }

    fn violates(&self, f: OrientedFacet) -> bool {
        self.violations[f.tet().index()] >> f.slot() & 1 != 0
    }
}

/// Why a facet is opened.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Opening {
    /// It violates the oriented Gabriel property.
    Gabriel,
    /// It blocks a pocket (normals test) though Gabriel holds.
    Pocket,
}

/// The pseudo-surface over one triangulation.
pub(crate) struct PseudoSurface<'a> {
    tri: &'a Triangulation,
    gabriel: GabrielTable,
    on_surface: Vec<bool>,
    external: Vec<bool>,
    queue: VecDeque<OrientedFacet>,
    facets: usize,
    pub tets_opened: usize,
    pub collapses: usize,
    /// One oriented facet of every collapsed pair: where two fronts met.
    pub collapsed: Vec<OrientedFacet>,
    pub pockets_opened: usize,
}

impl<'a> PseudoSurface<'a> {
    /// No facet, nothing queued, the tetrahedra flagged in `external` swept.
    fn empty(tri: &'a Triangulation, external: Vec<bool>) -> Self {
        PseudoSurface {
            tri,
            gabriel: GabrielTable::new(tri),
            on_surface: vec![false; 4 * tri.tet_slots()],
            external,
            queue: VecDeque::new(),
            facets: 0,
            tets_opened: 0,
            collapses: 0,
            collapsed: Vec::new(),
            pockets_opened: 0,
        }
    }

    /// The convex hull, facets oriented inward, all queued.
    pub fn from_hull(tri: &'a Triangulation) -> Self {
        let mut surface = Self::empty(tri, vec![false; tri.tet_slots()]);
        for g in tri.ghost_tets() {
            surface.external[g.index()] = true;
        }
        for g in tri.ghost_tets() {
            // The infinite vertex is in slot 3: its facet is the hull facet.
            let (t, slot) = tri.mirror(g, 3);
            surface.add(OrientedFacet::new(t, slot));
        }
        surface
    }

    /// The converged Gabriel surface of a triangulation whose swept
    /// tetrahedra are `external` (every ghost among them), as the
    /// convection from the hull leaves it: a facet facing an unswept
    /// tetrahedron from a swept one, and both sides of a facet between two
    /// swept ones that neither side violates (a pair the convection did not
    /// collapse; see [`crate::dynamic`]). Nothing is queued.
    pub fn from_swept(tri: &'a Triangulation, external: Vec<bool>) -> Self {
        let mut surface = Self::empty(tri, external);
        let mut between_swept = 0;
        let mut coupled = 0;
        for t in tri.finite_tets() {
            if surface.external[t.index()] {
                surface.tets_opened += 1;
            }
            for slot in 0..4 {
                let f = OrientedFacet::new(t, slot);
                let m = surface.mirror(f);
                if !surface.external[m.tet().index()] {
                    continue;
                }
                if !surface.external[t.index()] {
                    surface.add(f);
                    continue;
                }
                // Each facet between two swept tetrahedra once from here;
                // those facing a ghost are met only from this side.
                if tri.is_ghost(m.tet()) || f < m {
                    between_swept += 1;
                    if !surface.violates_gabriel(f) && !surface.violates_gabriel(m) {
                        surface.add(f);
                        surface.add(m);
                        coupled += 1;
                    }
                }
            }
        }
        surface.queue.clear();
        // Every swept tetrahedron was entered through one facet; the other
        // facets between swept ones either stayed coupled or collapsed.
        surface.collapses = between_swept - surface.tets_opened - coupled;
        surface
    }

    pub fn num_facets(&self) -> usize {
        self.facets
    }

    pub fn contains(&self, f: OrientedFacet) -> bool {
        self.on_surface[f.index()]
    }

    /// Whether `f` faces an external tetrahedron (its mirror is on the
    /// surface too).
    pub fn is_coupled(&self, f: OrientedFacet) -> bool {
        self.external[f.tet().index()]
    }

    /// Whether the surface has swept tetrahedron `t` (every ghost is).
    pub fn is_external(&self, t: TetId) -> bool {
        self.external[t.index()]
    }

    /// The same triangle seen from the other side.
    pub fn mirror(&self, f: OrientedFacet) -> OrientedFacet {
        let (t, slot) = self.tri.mirror(f.tet(), f.slot());
        OrientedFacet::new(t, slot)
    }

    /// The facets on the surface now.
    pub fn facets(&self) -> impl Iterator<Item = OrientedFacet> + '_ {
        self.on_surface
            .iter()
            .enumerate()
            .filter(|(_, &on)| on)
            .map(|(i, _)| OrientedFacet(i as u32))
    }

    /// Vertices of `f`, ordered so that its normal `(b − a) × (c − a)`
    /// points into the inside (towards the tetrahedron it faces).
    pub fn vertices(&self, f: OrientedFacet) -> [VertexId; 3] {
        self.tri.facet(f.tet(), f.slot())
    }

    pub fn corners(&self, f: OrientedFacet) -> [DVec3; 3] {
        self.vertices(f).map(|v| self.tri.point(v))
    }

    /// Whether `f` violates the oriented Gabriel property: the vertex of
    /// the tetrahedron it faces lies inside its diametral ball (see
    /// [`crate::gabriel`]). Facets facing the outside of the hull never do.
    pub fn violates_gabriel(&self, f: OrientedFacet) -> bool {
        self.gabriel.violates(f)
    }

    /// Queue every surface facet again (a new test applies).
    pub fn requeue_all(&mut self) {
        let all: Vec<OrientedFacet> = self.facets().collect();
        self.queue.extend(all);
    }

    /// Run the convection until no queued facet is opened by `test`.
    pub fn convect(&mut self, mut test: impl FnMut(&Self, OrientedFacet) -> Option<Opening>) {
        while let Some(f) = self.queue.pop_front() {
            if !self.contains(f) {
                continue;
            }
            if let Some(why) = test(self, f) {
                if why == Opening::Pocket {
                    self.pockets_opened += 1;
                }
                self.open(f);
            }
        }
    }

    /// Push the surface through `f`: replace it by the other three facets
    /// of the tetrahedron it faces, or collapse it with its mirror if that
    /// tetrahedron was already swept.
    pub fn open(&mut self, f: OrientedFacet) {
        let t = f.tet();
        if self.external[t.index()] {
            self.collapse(f);
            return;
        }
        self.remove(f);
        self.external[t.index()] = true;
        self.tets_opened += 1;
        for slot in (0..4).filter(|&s| s != f.slot()) {
            // The neighbour was internal or is now coupled to (t, slot):
            // either way the new facet faces it.
            let outward = self.mirror(OrientedFacet::new(t, slot));
            self.add(outward);
        }
    }

    /// Remove `f` and its coupled mirror.
    fn collapse(&mut self, f: OrientedFacet) {
        let m = self.mirror(f);
        debug_assert!(self.contains(m), "a coupled facet lost its mirror");
        self.remove(f);
        if self.contains(m) {
            self.remove(m);
        }
        self.collapses += 1;
        self.collapsed.push(f);
    }

    fn add(&mut self, f: OrientedFacet) {
        debug_assert!(!self.contains(f));
        self.on_surface[f.index()] = true;
        self.facets += 1;
        self.queue.push_back(f);
    }

    fn remove(&mut self, f: OrientedFacet) {
        self.on_surface[f.index()] = false;
        self.facets -= 1;
    }
}
