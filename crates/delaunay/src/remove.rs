//! Vertex removal.
//!
//! Removing `v` leaves a hole: the union of its incident tetrahedra, whose
//! boundary (the link of `v`) is kept. The tetrahedra of the new Delaunay
//! triangulation inside the hole are Delaunay for the link's vertices
//! alone, so they are read off a small triangulation of those vertices,
//! built with the same predicates and the same perturbation order (link
//! vertices sorted by id): its tetrahedra on the inner side of the link
//! facets, found by a flood fill that never crosses a link facet.

use crate::error::{DelaunayError, Result};
use crate::triangulation::{Triangulation, VertexId, FACET, INF, NONE};
use std::collections::HashMap;

type Facet = ([u32; 3], u32);

impl Triangulation {
    /// Remove vertex `v`, keeping the triangulation Delaunay. Errors if `v`
    /// is not a vertex, or if the remaining points would all be coplanar.
    pub fn remove(&mut self, v: VertexId) -> Result<()> {
        if v.is_infinite() || !self.contains_vertex(v) {
            return Err(DelaunayError::UnknownVertex(v.0));
        }
        let v = v.0;
        let mut star = Vec::new();
        self.star(v, &mut star);
        let boundary = self.link_facets(v, &star);
        let mut link: Vec<u32> = boundary
            .iter()
            .flat_map(|(f, _)| *f)
            .filter(|&x| x != INF)
            .collect();
        link.sort_unstable();
        link.dedup();
        let local: Vec<_> = link.iter().map(|&x| self.points[x as usize]).collect();
        // Local ids follow global ids, so the perturbation agrees.
        let insertion = crate::order::brio_order(&local);
        match Triangulation::build(local, &insertion) {
            Ok((small, _)) => self.fill_from(&small, &link, &star, &boundary)?,
            Err(DelaunayError::AllCoplanar { .. } | DelaunayError::TooFewPoints { .. }) => {
                self.fill_flat(v, &star, &boundary)?
            }
            Err(e) => return Err(DelaunayError::Internal(format!("link of vertex {v}: {e}"))),
        }
        self.vertex_tet[v as usize] = NONE;
        self.live_vertices -= 1;
        // The walk must start in a live finite tetrahedron.
        let outside = boundary[0].1 >> 2;
        self.hint = if self.cells[outside as usize].v[3] == INF {
            self.cells[outside as usize].n[3] >> 2
        } else {
            outside
        };
        Ok(())
    }

    /// The facets opposite `v` in its star, ordered with `v` (the hole) on
    /// their positive side, each with its neighbour outside the star.
    fn link_facets(&self, v: u32, star: &[u32]) -> Vec<Facet> {
        star.iter()
            .map(|&t| {
                let tv = self.cells[t as usize].v;
                let k = tv.iter().position(|&x| x == v).unwrap_or(0);
                (FACET[k].map(|s| tv[s]), self.cells[t as usize].n[k])
            })
            .collect()
    }

    /// Fill the hole with the tetrahedra of `small` (the triangulation of
    /// the link vertices, local id `i` ↔ `link[i]`) that lie inside it.
    fn fill_from(
        &mut self,
        small: &Triangulation,
        link: &[u32],
        star: &[u32],
        boundary: &[Facet],
    ) -> Result<()> {
        let global = |x: u32| if x == INF { INF } else { link[x as usize] };
        let by_vertices: HashMap<[u32; 3], usize> = boundary
            .iter()
            .enumerate()
            .map(|(i, (f, _))| (sorted(*f), i))
            .collect();
        // matched[4m + i]: the boundary facet that facet i of small tet m is.
        let mut matched = vec![NONE; small.cells.len() * 4];
        let mut in_hole = vec![false; small.cells.len()];
        let mut hole = Vec::new();
        let mut found = 0;
        for m in 0..small.cells.len() {
            if small.cells[m].v[0] == NONE {
                continue;
            }
            for (i, facet) in FACET.iter().enumerate() {
                let f = facet.map(|s| global(small.cells[m].v[s]));
                let Some(&b) = by_vertices.get(&sorted(f)) else {
                    continue;
                };
                // Same cyclic order: m is on the hole's side of the facet.
                if same_cycle(f, boundary[b].0) {
                    matched[4 * m + i] = b as u32;
                    found += 1;
                    if !in_hole[m] {
                        in_hole[m] = true;
                        hole.push(m as u32);
                    }
                }
            }
        }
        if found != boundary.len() {
            return Err(DelaunayError::Internal(format!(
                "{found} of {} link facets found in the link's triangulation",
                boundary.len()
            )));
        }
        let mut next = 0;
        while next < hole.len() {
            let m = hole[next] as usize;
            next += 1;
            for i in 0..4 {
                let n = (small.cells[m].n[i] >> 2) as usize;
                if matched[4 * m + i] == NONE && !in_hole[n] {
                    in_hole[n] = true;
                    hole.push(n as u32);
                }
            }
        }
        for &t in star {
            self.free_tet(t);
        }
        let mut new_id = vec![NONE; small.cells.len()];
        for &m in &hole {
            let verts = small.cells[m as usize].v.map(global);
            let t = self.alloc_tet(verts);
            new_id[m as usize] = t;
            for x in verts {
                if x != INF {
                    self.vertex_tet[x as usize] = t;
                }
            }
        }
        for &m in &hole {
            let m = m as usize;
            for i in 0..4 {
                let here = new_id[m] * 4 + i as u32;
                let b = matched[4 * m + i];
                if b != NONE {
                    self.link(here, boundary[b as usize].1);
                } else {
                    let a = small.cells[m].n[i];
                    self.link(here, new_id[(a >> 2) as usize] * 4 + (a & 3));
                }
            }
        }
        Ok(())
    }

    /// Fill a hole of no volume: `v` was on the hull above a flat link, so
    /// the link's finite facets become hull facets, each capped by a ghost.
    fn fill_flat(&mut self, v: u32, star: &[u32], boundary: &[Facet]) -> Result<()> {
        let finite_in_star = star
            .iter()
            .filter(|&&t| self.cells[t as usize].v[3] != INF)
            .count();
        if finite_in_star == self.finite_tets {
            return Err(DelaunayError::RemovalWouldFlatten(v));
        }
        if finite_in_star == star.len() {
            return Err(DelaunayError::Internal(format!(
                "interior vertex {v} has a flat link"
            )));
        }
        let (seeds, finite): (Vec<Facet>, Vec<Facet>) =
            boundary.iter().partition(|(f, _)| f.contains(&INF));
        for &t in star {
            self.free_tet(t);
        }
        self.scratch.boundary.clear();
        self.scratch.boundary.extend_from_slice(&finite);
        self.cone(INF, &seeds);
        Ok(())
    }
}

fn sorted(mut f: [u32; 3]) -> [u32; 3] {
    f.sort_unstable();
    f
}

/// Whether `g` is a rotation of `f`.
fn same_cycle(f: [u32; 3], g: [u32; 3]) -> bool {
    f == g || f == [g[1], g[2], g[0]] || f == [g[2], g[0], g[1]]
}
