//! An exact check of every invariant of the triangulation, for tests and
//! for users who edit it.

use crate::predicates::{insphere, orient3d};
use crate::triangulation::{Triangulation, FACET, INF, NONE};

impl Triangulation {
    /// Check exactly: vertex references, neighbour symmetry (each facet
    /// shared by two tetrahedra in opposite orientations), positive
    /// orientation of every finite tetrahedron, outward hull facets with a
    /// locally convex hull, and the empty-sphere property of every facet
    /// (no neighbour's opposite vertex strictly inside the circumsphere;
    /// coplanar hull facets empty-circle). Locally Delaunay everywhere
    /// implies globally Delaunay. Returns the first violation found.
    pub fn validate(&self) -> Result<(), String> {
        let (mut finite, mut ghosts) = (0, 0);
        for t in 0..self.cells.len() {
            if self.cells[t].v[0] == NONE {
                continue;
            }
            self.check_vertices(t)?;
            if self.cells[t].v[3] == INF {
                ghosts += 1;
            } else {
                finite += 1;
                let [a, b, c, d] = self.cells[t].v.map(|v| self.points[v as usize]);
                if orient3d(a, b, c, d) <= 0.0 {
                    return Err(format!(
                        "tet {t} {:?} is not positively oriented",
                        self.cells[t].v
                    ));
                }
            }
            for i in 0..4 {
                self.check_neighbor(t, i)?;
                self.check_empty_sphere(t, i)?;
            }
        }
        if (finite, ghosts) != (self.finite_tets, self.ghost_tets) {
            return Err(format!(
                "counted {finite} finite and {ghosts} ghost tets, recorded {} and {}",
                self.finite_tets, self.ghost_tets
            ));
        }
        self.check_vertex_tets()
    }

    fn check_vertices(&self, t: usize) -> Result<(), String> {
        let tv = self.cells[t].v;
        for (s, &x) in tv.iter().enumerate() {
            let bad = if x == INF {
                s != 3
            } else {
                x as usize >= self.points.len() || self.vertex_tet[x as usize] == NONE
            };
            if bad || tv[..s].contains(&x) {
                return Err(format!("tet {t} has bad vertex {x} in slot {s}: {tv:?}"));
            }
        }
        Ok(())
    }

    fn check_neighbor(&self, t: usize, i: usize) -> Result<(), String> {
        let a = self.cells[t].n[i];
        let (n, j) = ((a >> 2) as usize, (a & 3) as usize);
        if n >= self.cells.len() || self.cells[n].v[0] == NONE {
            return Err(format!(
                "tet {t} facet {i}: neighbour {n} is not a live tet"
            ));
        }
        if self.cells[n].n[j] != (t * 4 + i) as u32 {
            return Err(format!(
                "tet {t} facet {i}: neighbour {n} does not point back"
            ));
        }
        let f = FACET[i].map(|s| self.cells[t].v[s]);
        let g = FACET[j].map(|s| self.cells[n].v[s]);
        let reversed = [g[0], g[2], g[1]];
        let opposite =
            (0..3).any(|r| f == [reversed[r], reversed[(r + 1) % 3], reversed[(r + 2) % 3]]);
        if !opposite {
            return Err(format!(
                "tets {t} and {n} share no facet in opposite orientations: {f:?} / {g:?}"
            ));
        }
        Ok(())
    }

    fn check_empty_sphere(&self, t: usize, i: usize) -> Result<(), String> {
        let a = self.cells[t].n[i];
        let (n, j) = ((a >> 2) as usize, (a & 3) as usize);
        let apex = self.cells[n].v[j];
        let tv = self.cells[t].v;
        let p = |v: u32| self.points[v as usize];
        if tv[3] != INF {
            if apex != INF && insphere(p(tv[0]), p(tv[1]), p(tv[2]), p(tv[3]), p(apex)) > 0.0 {
                return Err(format!(
                    "tet {t} {tv:?}: vertex {apex} of neighbour {n} is inside its circumsphere"
                ));
            }
            return Ok(());
        }
        if i == 3 {
            return Ok(());
        }
        // Two ghosts across a hull edge: the hull must be convex there.
        let o = orient3d(p(tv[0]), p(tv[1]), p(tv[2]), p(apex));
        if o > 0.0 {
            return Err(format!(
                "hull facet {:?} sees hull vertex {apex}: not convex",
                &tv[..3]
            ));
        }
        if o == 0.0 {
            // Coplanar hull facets: apex outside the facet's circumcircle,
            // tested through the finite tetrahedron behind the facet.
            let behind = self.cells[(self.cells[t].n[3] >> 2) as usize].v;
            let [q0, q1, q2, q3] = behind.map(p);
            if insphere(q0, q1, q2, q3, p(apex)) > 0.0 {
                return Err(format!(
                    "coplanar hull facets {:?} and ghost {n}: not Delaunay in their plane",
                    &tv[..3]
                ));
            }
        }
        Ok(())
    }

    fn check_vertex_tets(&self) -> Result<(), String> {
        let mut live = 0;
        for (v, &t) in self.vertex_tet.iter().enumerate() {
            if t == NONE {
                continue;
            }
            live += 1;
            let tv = self.cells.get(t as usize).map_or([NONE; 4], |c| c.v);
            if tv[0] == NONE || !tv.contains(&(v as u32)) {
                return Err(format!("vertex {v}: its tet {t} does not contain it"));
            }
        }
        if live != self.live_vertices {
            return Err(format!(
                "{live} live vertices, recorded {}",
                self.live_vertices
            ));
        }
        Ok(())
    }
}
