//! Dynamic correction (the paper's §4.1): insert and remove points and
//! update the converged pseudo-surface locally, without restarting the
//! convection from the convex hull.
//!
//! The Gabriel convection's result depends only on the triangulation: the
//! swept (*external*) tetrahedra are exactly those reached from the ghosts
//! through oriented facets violating the oriented Gabriel property (opening
//! is monotone, so the order of the breadth-first traversal does not
//! matter), and a facet between two swept tetrahedra stays as a coupled
//! pair exactly when neither orientation violates the property (otherwise
//! it was opened or collapsed). [`DynamicSurface`] keeps the swept flags and
//! the *discovering forest* (each swept tetrahedron points to the one it
//! was opened from; ghosts are the roots). An edit of the triangulation
//! replaces the tetrahedra of its conflict region: the swept tetrahedra
//! discovered through a replaced one (the orphans, with everything
//! discovered from them) lose their justification and become internal
//! again, the new tetrahedra start internal (new ghosts swept), and the
//! convection restarts from the facets between the still-justified swept
//! tetrahedra and those. Every tetrahedron left swept is still reached from
//! a ghost through unchanged facets, and the convection from there reaches
//! all the rest, so the result is the one a run from scratch gives.
//!
//! The paper re-attaches orphans to neighbouring swept cells where it can
//! instead of sweeping them again; re-sweeping is simpler and costs the
//! size of the orphaned subtrees. Pockets (which need normals and the
//! sampling spacing of all points) are not part of the dynamic update.

use crate::decimate::{redecimate_region, Decimation};
use crate::error::{ConvectionError, Result};
use crate::gabriel::in_diametral_ball;
use std::collections::VecDeque;
use surfrecon_delaunay::{DelaunayError, Location, TetId, Triangulation, VertexId};
use surfrecon_geom::DVec3;

const NONE: u32 = u32::MAX;

/// Work of the last update, to show it stays local.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UpdateStats {
    /// Tetrahedra the triangulation replaced.
    pub replaced: usize,
    /// Swept tetrahedra made internal again (orphaned subtrees).
    pub orphaned: usize,
    /// Tetrahedra swept by the restarted convection.
    pub swept: usize,
}

/// A triangulation with its converged pseudo-surface, edited in place.
pub struct DynamicSurface {
    tri: Triangulation,
    external: Vec<bool>,
    parent: Vec<u32>,
    first_child: Vec<u32>,
    next_sibling: Vec<u32>,
    prev_sibling: Vec<u32>,
    last: UpdateStats,
}

impl DynamicSurface {
    /// Triangulate `points` and run the Gabriel convection to convergence.
    pub fn new(points: &[DVec3]) -> Result<Self> {
        let mut tri = Triangulation::bulk_load(points)?;
        tri.track_changes(true);
        let slots = tri.tet_slots();
        let mut surface = DynamicSurface {
            tri,
            external: vec![false; slots],
            parent: vec![NONE; slots],
            first_child: vec![NONE; slots],
            next_sibling: vec![NONE; slots],
            prev_sibling: vec![NONE; slots],
            last: UpdateStats::default(),
        };
        let ghosts: Vec<TetId> = surface.tri.ghost_tets().collect();
        for &g in &ghosts {
            surface.external[g.index()] = true;
        }
        // The infinite vertex is in slot 3: that facet is the hull facet.
        let queue = ghosts.into_iter().map(|g| (g, 3)).collect();
        surface.last.swept = surface.convect(queue);
        Ok(surface)
    }

    pub fn triangulation(&self) -> &Triangulation {
        &self.tri
    }

    /// Whether each tetrahedron slot is swept by the surface (every ghost
    /// is), by [`TetId::index`].
    pub fn swept(&self) -> &[bool] {
        &self.external
    }

    /// What the last [`DynamicSurface::insert`] or [`DynamicSurface::remove`] did.
    pub fn last_update(&self) -> UpdateStats {
        self.last
    }

    /// Insert a point (a duplicate returns the existing vertex and changes
    /// nothing) and update the surface.
    pub fn insert(&mut self, p: DVec3) -> Result<VertexId> {
        let v = self.tri.insert(p)?;
        self.update();
        Ok(v)
    }

    /// Remove a vertex and update the surface.
    pub fn remove(&mut self, v: VertexId) -> Result<()> {
        self.tri.remove(v)?;
        self.update();
        Ok(())
    }

    /// Remove the vertex at exactly `p` and update the surface.
    pub fn remove_point(&mut self, p: DVec3) -> Result<()> {
        let v =
            self.vertex_at(p)
                .ok_or(ConvectionError::Delaunay(DelaunayError::UnknownVertex(
                    u32::MAX,
                )))?;
        self.remove(v)
    }

    /// The vertex at exactly `p`: the located tetrahedron has it as a
    /// corner (no vertex lies inside a Delaunay tetrahedron), or one of its
    /// neighbours does when `p` is on a shared facet.
    fn vertex_at(&self, p: DVec3) -> Option<VertexId> {
        let t = match self.tri.locate(p).ok()? {
            Location::Inside(t) | Location::Outside(t) => t,
        };
        std::iter::once(t)
            .chain(self.tri.neighbors(t))
            .flat_map(|u| self.tri.tet_vertices(u))
            .find(|&v| !v.is_infinite() && self.tri.point(v) == p)
    }

    /// The converged pseudo-surface: every oriented facet, vertices ordered
    /// so that `(b − a) × (c − a)` points inside (coupled pairs give both).
    pub fn facets(&self) -> Vec<[VertexId; 3]> {
        let mut out = Vec::new();
        for t in self.tri.finite_tets() {
            for slot in 0..4 {
                // The facet facing into t, seen from the tetrahedron behind.
                let (u, _) = self.tri.mirror(t, slot);
                if !self.external[u.index()] {
                    continue;
                }
                let on_surface = !self.external[t.index()]
                    || (!self.violates(t, slot) && !self.violates_behind(t, slot));
                if on_surface {
                    out.push(self.tri.facet(t, slot));
                }
            }
        }
        // Coupled facets facing ghosts (hull sheets).
        for g in self.tri.ghost_tets() {
            let (t, slot) = self.tri.mirror(g, 3);
            if self.external[t.index()] && !self.violates(t, slot) {
                out.push(self.tri.facet(g, 3));
            }
        }
        out
    }

    /// The surface triangles without the coupled sheets: facets between a
    /// swept and an unswept tetrahedron, ordered so that `(b − a) × (c − a)`
    /// points inside.
    pub fn boundary_facets(&self) -> Vec<[VertexId; 3]> {
        let mut out = Vec::new();
        for t in self.tri.finite_tets() {
            if self.external[t.index()] {
                continue;
            }
            for slot in 0..4 {
                let (u, _) = self.tri.mirror(t, slot);
                if self.external[u.index()] {
                    out.push(self.tri.facet(t, slot));
                }
            }
        }
        out
    }

    /// Whether the facet `slot` of `t`, facing into `t`, violates the
    /// oriented Gabriel property (never for a ghost).
    fn violates(&self, t: TetId, slot: usize) -> bool {
        if self.tri.is_ghost(t) {
            return false;
        }
        let [a, b, c] = self.tri.facet(t, slot).map(|v| self.tri.point(v));
        let apex = self.tri.tet_vertices(t)[slot];
        in_diametral_ball(a, b, c, self.tri.point(apex))
    }

    /// The same facet facing the other way.
    fn violates_behind(&self, t: TetId, slot: usize) -> bool {
        let (u, s) = self.tri.mirror(t, slot);
        self.violates(u, s)
    }

    /// Breadth-first convection from `queue`: (swept tetrahedron, slot of
    /// the facet to push through). Returns the tetrahedra swept.
    fn convect(&mut self, mut queue: VecDeque<(TetId, usize)>) -> usize {
        let mut swept = 0;
        while let Some((t, slot)) = queue.pop_front() {
            let (u, s) = self.tri.mirror(t, slot);
            if self.external[u.index()] || !self.violates(u, s) {
                continue;
            }
            self.external[u.index()] = true;
            self.link(u, t);
            swept += 1;
            queue.extend((0..4).filter(|&k| k != s).map(|k| (u, k)));
        }
        swept
    }

    /// Restore the invariants after an edit of the triangulation.
    fn update(&mut self) {
        let changes = self.tri.take_changes();
        let slots = self.tri.tet_slots();
        for table in [
            &mut self.parent,
            &mut self.first_child,
            &mut self.next_sibling,
            &mut self.prev_sibling,
        ] {
            table.resize(slots, NONE);
        }
        self.external.resize(slots, false);
        // Orphans: everything discovered through a replaced tetrahedron.
        let mut orphans = Vec::new();
        let mut stack: Vec<u32> = changes
            .freed
            .iter()
            .filter(|t| self.external[t.index()])
            .map(|t| t.0)
            .collect();
        for &t in &stack {
            self.external[t as usize] = false;
        }
        while let Some(t) = stack.pop() {
            orphans.push(TetId(t));
            let mut c = self.first_child[t as usize];
            while c != NONE {
                if self.external[c as usize] {
                    self.external[c as usize] = false;
                    stack.push(c);
                }
                c = self.next_sibling[c as usize];
            }
        }
        for &t in &orphans {
            self.unlink(t);
        }
        for &t in &orphans {
            self.first_child[t.index()] = NONE;
        }
        for &t in &changes.created {
            self.unlink(t);
            self.first_child[t.index()] = NONE;
            self.external[t.index()] = self.tri.is_ghost(t);
        }
        // Restart from the swept side of every facet around what changed.
        let mut queue = VecDeque::new();
        for &u in orphans.iter().chain(&changes.created) {
            if !self.tri.is_live(u) {
                continue;
            }
            if self.external[u.index()] {
                queue.push_back((u, 3)); // a new ghost: its hull facet
                continue;
            }
            for slot in 0..4 {
                let (t, s) = self.tri.mirror(u, slot);
                if self.external[t.index()] {
                    queue.push_back((t, s));
                }
            }
        }
        let replaced = changes.freed.len();
        let orphaned = orphans
            .iter()
            .filter(|t| !changes.freed.contains(t))
            .count();
        let swept = self.convect(queue);
        self.last = UpdateStats {
            replaced,
            orphaned,
            swept,
        };
    }

    fn link(&mut self, child: TetId, parent: TetId) {
        let (c, p) = (child.index(), parent.0);
        self.parent[c] = p;
        self.prev_sibling[c] = NONE;
        self.next_sibling[c] = self.first_child[p as usize];
        if let Some(&first) = self.first_child.get(p as usize).filter(|&&f| f != NONE) {
            self.prev_sibling[first as usize] = child.0;
        }
        self.first_child[p as usize] = child.0;
    }

    fn unlink(&mut self, child: TetId) {
        let c = child.index();
        let p = self.parent[c];
        if p != NONE {
            let (prev, next) = (self.prev_sibling[c], self.next_sibling[c]);
            if prev != NONE {
                self.next_sibling[prev as usize] = next;
            } else {
                self.first_child[p as usize] = next;
            }
            if next != NONE {
                self.prev_sibling[next as usize] = prev;
            }
        }
        self.parent[c] = NONE;
        self.prev_sibling[c] = NONE;
        self.next_sibling[c] = NONE;
    }
}

/// The paper's interactive refinement (§4.3): decide again the points of
/// `points` within the reach of `settings.brush` with its local radius, and
/// insert or remove them in `surface`, each a local update. `keep` says
/// which of `points` the surface holds, and is updated; `normals` are unit
/// vectors, one per point. Returns (inserted, removed).
pub fn apply_brush(
    surface: &mut DynamicSurface,
    points: &[DVec3],
    normals: &[DVec3],
    keep: &mut [bool],
    settings: &Decimation,
) -> Result<(usize, usize)> {
    if normals.len() != points.len() || keep.len() != points.len() {
        return Err(ConvectionError::NormalCount {
            points: points.len(),
            normals: normals.len().min(keep.len()),
        });
    }
    let next = redecimate_region(points, normals, keep, settings);
    let (mut inserted, mut removed) = (0, 0);
    for i in 0..points.len() {
        match (keep[i], next[i]) {
            (false, true) => {
                surface.insert(points[i])?;
                inserted += 1;
            }
            (true, false) => {
                surface.remove_point(points[i])?;
                removed += 1;
            }
            _ => {}
        }
        keep[i] = next[i];
    }
    Ok((inserted, removed))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::{Opening, PseudoSurface};
    use rand::{Rng, SeedableRng};

    type Key = [[u64; 3]; 3];

    /// Oriented facets by their corner coordinates (vertex ids differ
    /// between runs), rotated to start at the smallest corner.
    fn keyed(tri: &Triangulation, facets: &[[VertexId; 3]]) -> Vec<Key> {
        let mut keys: Vec<Key> = facets
            .iter()
            .map(|f| {
                let k = f.map(|v| tri.point(v).to_array().map(f64::to_bits));
                let i = (0..3).min_by_key(|&i| k[i]).expect("three corners");
                [k[i], k[(i + 1) % 3], k[(i + 2) % 3]]
            })
            .collect();
        keys.sort_unstable();
        keys
    }

    /// Points near a sphere (a surface with an inside), in general position.
    fn shell(n: usize, seed: u64) -> Vec<DVec3> {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let d = DVec3::new(
                    rng.random::<f64>() - 0.5,
                    rng.random::<f64>() - 0.5,
                    rng.random::<f64>() - 0.5,
                );
                d.normalize() * (1.0 + 0.01 * rng.random::<f64>())
            })
            .collect()
    }

    /// The rule behind [`DynamicSurface::facets`] gives what the
    /// convection's own queue-driven process converges to.
    #[test]
    fn facets_match_the_convection() {
        let points = shell(1500, 1);
        let dynamic = DynamicSurface::new(&points).unwrap();
        let tri = Triangulation::bulk_load(&points).unwrap();
        let mut surface = PseudoSurface::from_hull(&tri);
        surface.convect(|s, f| s.violates_gabriel(f).then_some(Opening::Gabriel));
        let scratch: Vec<[VertexId; 3]> = surface.facets().map(|f| surface.vertices(f)).collect();
        assert!(scratch.len() > 2000);
        assert_eq!(
            keyed(&tri, &scratch),
            keyed(dynamic.triangulation(), &dynamic.facets())
        );
    }

    /// Insertions and removals updated locally give the facets of a run
    /// from scratch on the final points, and touch a small part.
    #[test]
    fn local_updates_match_a_run_from_scratch() {
        let all = shell(2400, 2);
        let (start, extra) = all.split_at(2000);
        let mut dynamic = DynamicSurface::new(start).unwrap();
        let mut total_swept = 0;
        for &p in extra {
            dynamic.insert(p).unwrap();
            total_swept += dynamic.last_update().swept;
        }
        // Remove every fifth original point.
        let mut kept: Vec<DVec3> = extra.to_vec();
        for (i, &p) in start.iter().enumerate() {
            if i % 5 == 0 {
                let v = dynamic
                    .triangulation()
                    .vertices()
                    .find(|&v| dynamic.triangulation().point(v) == p)
                    .unwrap();
                dynamic.remove(v).unwrap();
                total_swept += dynamic.last_update().swept;
            } else {
                kept.push(p);
            }
        }
        let scratch = DynamicSurface::new(&kept).unwrap();
        assert_eq!(
            keyed(scratch.triangulation(), &scratch.facets()),
            keyed(dynamic.triangulation(), &dynamic.facets())
        );
        let full = scratch.triangulation().num_tets();
        let edits = extra.len() + start.len() / 5;
        eprintln!("{total_swept} tetrahedra swept over {edits} edits ({full} in all)");
        assert!(
            total_swept < edits * full / 20,
            "updates are not local: {total_swept} swept in {edits} edits of {full}"
        );
    }

    /// A flat-ish sampled sphere with its normals.
    fn sphere_with_normals(n: usize, seed: u64) -> (Vec<DVec3>, Vec<DVec3>) {
        let points = shell(n, seed);
        let normals = points.iter().map(|p| p.normalize()).collect();
        (points, normals)
    }

    /// The paper's decimation criteria with ball radius `radius`.
    fn decimation(radius: f64) -> Decimation {
        Decimation {
            radius,
            geometric: 0.9,
            topological: 0.95,
            brush: None,
        }
    }

    /// The points `keep` marks.
    fn selected(points: &[DVec3], keep: &[bool]) -> Vec<DVec3> {
        (0..points.len())
            .filter(|&i| keep[i])
            .map(|i| points[i])
            .collect()
    }

    /// A refining brush inserts points only within its reach, and the
    /// updated surface is the one a run from scratch on the new kept points
    /// gives; a coarsening brush removes points there.
    #[test]
    fn brush_updates_locally_and_matches_a_run_from_scratch() {
        use crate::decimate::{decimate, Brush};
        let (points, normals) = sphere_with_normals(3000, 3);
        let mut settings = decimation(0.12);
        let mut keep = decimate(&points, &normals, &settings);
        let kept = |keep: &[bool]| selected(&points, keep);
        let mut surface = DynamicSurface::new(&kept(&keep)).unwrap();
        let centre = DVec3::new(0.0, 0.0, 1.0);
        let inside = |i: usize| points[i].distance(centre) < 0.5;
        let count_inside =
            |keep: &[bool]| (0..points.len()).filter(|&i| inside(i) && keep[i]).count();
        for (rho_c, refines) in [(0.03, true), (0.25, false)] {
            settings.brush = Some(Brush {
                centre,
                radius: 0.5,
                rho_centre: rho_c,
                exponent: 2,
            });
            let before = keep.clone();
            let (inserted, removed) =
                apply_brush(&mut surface, &points, &normals, &mut keep, &settings).unwrap();
            eprintln!("rho_c {rho_c}: {inserted} inserted, {removed} removed");
            assert!((0..points.len()).all(|i| inside(i) || keep[i] == before[i]));
            if refines {
                assert!(count_inside(&keep) > count_inside(&before) && inserted > 0);
            } else {
                assert!(count_inside(&keep) < count_inside(&before) && removed > 0);
            }
            let scratch = DynamicSurface::new(&kept(&keep)).unwrap();
            assert_eq!(
                keyed(scratch.triangulation(), &scratch.facets()),
                keyed(surface.triangulation(), &surface.facets())
            );
        }
    }
    /// Triangle-quality refinement of a decimated sphere: afterwards every
    /// surface triangle meets α and γ or has no removed point in its
    /// enclosing ball far enough from the kept points to be inserted
    /// (checked by brute force), fewer triangles fail α, and
    /// the updated surface is the one a run from scratch on the final
    /// points gives.
    #[test]
    fn quality_refinement_meets_the_bound_and_matches_a_run_from_scratch() {
        use crate::decimate::decimate;
        use crate::refine::{refine, Quality, SHORTEST_EDGE_SHARE};
        let (points, normals) = sphere_with_normals(4000, 5);
        let settings = decimation(0.2);
        let mut keep = decimate(&points, &normals, &settings);
        let kept = |keep: &[bool]| selected(&points, keep);
        let quality = Quality {
            alpha: 0.9,
            gamma: 0.5,
        };
        // Brute force: the ratio, the nearest other kept point, the ball.
        let ratio = |[a, b, c]: [DVec3; 3]| {
            let (la, lb, lc) = (b.distance(c), c.distance(a), a.distance(b));
            let area2 = (b - a).cross(c - a).length();
            // R = abc / (4 · area).
            la * lb * lc / (2.0 * area2) / la.min(lb).min(lc)
        };
        let worst = |s: &DynamicSurface| {
            let tri = s.triangulation();
            s.boundary_facets()
                .iter()
                .map(|f| ratio(f.map(|v| tri.point(v))))
                .fold(0.0, f64::max)
        };
        let mut surface = DynamicSurface::new(&kept(&keep)).unwrap();
        let (before, kept_before) = (worst(&surface), kept(&keep).len());
        let (stats, placed) = refine(&mut surface, &points, &mut keep, &quality).unwrap();
        let tri = surface.triangulation();
        assert!(placed.iter().all(|&(v, q)| tri.point(v) == points[q]));
        let after = worst(&surface);
        let final_points = kept(&keep);
        eprintln!(
            "{stats:?}: {kept_before} -> {} points, worst ratio {before:.2} -> {after:.2}",
            final_points.len()
        );
        assert!(stats.inserted > 0 && final_points.len() == kept_before + stats.inserted);
        let spacing = |p: DVec3| {
            final_points
                .iter()
                .map(|q| q.distance(p))
                .filter(|&d| d > 0.0)
                .fold(f64::INFINITY, f64::min)
        };
        let tri = surface.triangulation();
        let mut unmet = 0;
        for f in surface.boundary_facets() {
            let corners = f.map(|v| tri.point(v));
            let radii = corners.map(spacing);
            let lo = radii.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = radii.iter().copied().fold(0.0, f64::max);
            if ratio(corners) < quality.alpha && lo >= quality.gamma * hi {
                continue;
            }
            unmet += 1;
            let (centre, radius) = crate::refine::enclosing_ball(corners);
            assert!(corners
                .iter()
                .all(|c| c.distance(centre) <= radius * (1.0 + 1e-9)));
            let [a, b, c] = corners;
            let shortest = a.distance(b).min(b.distance(c)).min(c.distance(a));
            let nearest_kept = |p: DVec3| {
                final_points
                    .iter()
                    .map(|q| q.distance(p))
                    .fold(f64::INFINITY, f64::min)
            };
            let usable = (0..points.len())
                .filter(|&i| !keep[i] && points[i].distance(centre) < radius)
                .filter(|&i| nearest_kept(points[i]) >= SHORTEST_EDGE_SHARE * shortest)
                .count();
            assert_eq!(usable, 0, "a failing triangle has usable points left");
        }
        assert_eq!(unmet, stats.unmet);
        let bad_share = |s: &DynamicSurface| {
            let tri = s.triangulation();
            let f = s.boundary_facets();
            let bad = f
                .iter()
                .filter(|f| ratio(f.map(|v| tri.point(v))) >= quality.alpha)
                .count();
            bad as f64 / f.len() as f64
        };
        let unrefined =
            DynamicSurface::new(&kept(&decimate(&points, &normals, &settings))).unwrap();
        eprintln!(
            "failing α: {} before, {} after",
            bad_share(&unrefined),
            bad_share(&surface)
        );
        assert!(
            bad_share(&surface) < 0.5 * bad_share(&unrefined),
            "{} vs {}",
            bad_share(&surface),
            bad_share(&unrefined)
        );
        let scratch = DynamicSurface::new(&final_points).unwrap();
        assert_eq!(
            keyed(scratch.triangulation(), &scratch.facets()),
            keyed(surface.triangulation(), &surface.facets())
        );
    }
}
