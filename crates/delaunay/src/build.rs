//! Building a triangulation from a point set: checks, the first
//! tetrahedron, then insertion in BRIO order.

use crate::error::{DelaunayError, Result};
use crate::insert::Scratch;
use crate::order::brio_order;
use crate::predicates::{orient3d, StaticFilter};
use crate::triangulation::{Triangulation, FACET, INF, MAX_TETS, MAX_VERTICES, NONE};
use glam::DVec3;

impl Triangulation {
    /// The Delaunay tetrahedralization of `points`. Exact duplicates are
    /// merged into one vertex. Vertices are numbered in insertion order
    /// (spatially coherent, which keeps the build cache-friendly), not in
    /// input order: [`Triangulation::vertex_of_input`] and
    /// [`Triangulation::input_of_vertex`] translate.
    /// Errors on non-finite coordinates, fewer than 4 points, or points that
    /// span no tetrahedron (all identical, collinear or coplanar).
    pub fn bulk_load(points: &[DVec3]) -> Result<Triangulation> {
        if let Some(index) = points.iter().position(|p| !p.is_finite()) {
            return Err(DelaunayError::NonFinite { index });
        }
        if points.len() < 4 {
            return Err(DelaunayError::TooFewPoints {
                count: points.len(),
            });
        }
        if points.len() >= MAX_VERTICES || points.len().saturating_mul(8) > MAX_TETS {
            return Err(DelaunayError::TooLarge);
        }
        let order = brio_order(points);
        let sorted: Vec<DVec3> = order.iter().map(|&i| points[i as usize]).collect();
        let identity: Vec<u32> = (0..points.len() as u32).collect();
        let (mut tri, duplicates) = Triangulation::build(sorted, &identity)?;
        tri.input_vertex = vec![NONE; points.len()];
        for (v, &i) in order.iter().enumerate() {
            tri.input_vertex[i as usize] = v as u32;
        }
        for (copy, kept) in duplicates {
            tri.input_vertex[order[copy as usize] as usize] = kept;
        }
        tri.vertex_input = order;
        Ok(tri)
    }

    /// The triangulation of `points` (vertex `i` is `points[i]`, which also
    /// fixes the symbolic perturbation order), inserted in `insertion`
    /// order. Returns it with the (duplicate, kept vertex) pairs.
    pub(crate) fn build(
        points: Vec<DVec3>,
        insertion: &[u32],
    ) -> Result<(Triangulation, Vec<(u32, u32)>)> {
        let first = first_tetrahedron(&points, insertion)?;
        let mut tri = Triangulation::with_first_tet(points, first);
        let mut duplicates = Vec::new();
        for &v in insertion {
            if first.contains(&v) {
                continue;
            }
            if let Some(kept) = tri.insert_vertex(v)? {
                duplicates.push((v, kept));
            }
        }
        tri.merged = duplicates.len();
        tri.set_vertex_tets();
        Ok((tri, duplicates))
    }

    /// Point every vertex at one of its tetrahedra, then keep that current.
    fn set_vertex_tets(&mut self) {
        for (t, cell) in self.cells.iter().enumerate() {
            if cell.v[0] == NONE {
                continue;
            }
            for &x in &cell.v {
                if x != INF {
                    self.vertex_tet[x as usize] = t as u32;
                }
            }
        }
        self.track_vertex_tets = true;
    }

    /// A triangulation of one positively oriented tetrahedron of `points`
    /// and its four ghosts.
    fn with_first_tet(points: Vec<DVec3>, first: [u32; 4]) -> Triangulation {
        let expected_tets = points.len() * 7 + 16;
        let lo = points.iter().fold(DVec3::INFINITY, |lo, &p| lo.min(p));
        let hi = points.iter().fold(DVec3::NEG_INFINITY, |hi, &p| hi.max(p));
        let mut tri = Triangulation {
            bounds: [lo, hi],
            filter: StaticFilter::for_box(lo, hi),
            vertex_tet: vec![NONE; points.len()],
            points,
            cells: Vec::with_capacity(expected_tets),
            free: Vec::new(),
            merged: 0,
            input_vertex: Vec::new(),
            vertex_input: Vec::new(),
            live_vertices: 4,
            finite_tets: 0,
            ghost_tets: 0,
            track_vertex_tets: false,
            changes: None,
            hint: 0,
            scratch: Scratch::default(),
        };
        let t = tri.alloc_tet(first);
        // The ghosts are the cone from infinity over the tetrahedron's
        // facets, each reversed so that infinity is on its positive side.
        tri.scratch.boundary.clear();
        for (i, facet) in FACET.iter().enumerate() {
            let [a, b, c] = facet.map(|s| first[s]);
            tri.scratch.boundary.push(([a, c, b], t * 4 + i as u32));
        }
        tri.cone(INF, &[]);
        for v in first {
            tri.vertex_tet[v as usize] = t;
        }
        tri.hint = t;
        tri
    }
}

/// Four points spanning a positively oriented tetrahedron, taken early in
/// `order` so the walk starts where insertion starts.
fn first_tetrahedron(points: &[DVec3], order: &[u32]) -> Result<[u32; 4]> {
    let count = points.len();
    let p = |i: u32| points[i as usize];
    let a = order[0];
    let b = *order
        .iter()
        .find(|&&i| p(i) != p(a))
        .ok_or(DelaunayError::AllIdentical { count })?;
    let c = *order
        .iter()
        .find(|&&i| !collinear(p(a), p(b), p(i)))
        .ok_or(DelaunayError::AllCollinear { count })?;
    let d = *order
        .iter()
        .find(|&&i| orient3d(p(a), p(b), p(c), p(i)) != 0.0)
        .ok_or(match collinear_to_rounding(points) {
            true => DelaunayError::AllCollinear { count },
            false => DelaunayError::AllCoplanar { count },
        })?;
    Ok(if orient3d(p(a), p(b), p(c), p(d)) > 0.0 {
        [a, b, c, d]
    } else {
        [b, a, c, d]
    })
}

/// Points off a line by at most this share of their extent are collinear
/// but for the rounding of their coordinates (`t·(0.1, 0.2, 0.3)` for a
/// decimal `t` lie exactly on a plane, but not exactly on a line).
const COLLINEAR_TO_ROUNDING: f64 = 1e-9;

/// Whether every point lies within [`COLLINEAR_TO_ROUNDING`] of their
/// extent from the line through the first point and the point farthest
/// from it.
fn collinear_to_rounding(points: &[DVec3]) -> bool {
    let a = points[0];
    let b = points
        .iter()
        .copied()
        .max_by(|p, q| p.distance_squared(a).total_cmp(&q.distance_squared(a)))
        .unwrap_or(a);
    let length = a.distance(b);
    if length == 0.0 {
        return true;
    }
    let direction = (b - a) / length;
    let off_line = |p: DVec3| (p - a).cross(direction).length();
    points
        .iter()
        .all(|&p| off_line(p) <= COLLINEAR_TO_ROUNDING * length)
}

/// Exact collinearity: the cross product (b − a) × (c − a) vanishes iff its
/// three components, the 2D orientations of the projections, all vanish.
fn collinear(a: DVec3, b: DVec3, c: DVec3) -> bool {
    let o = |i: usize, j: usize| {
        let q = |v: DVec3| robust::Coord { x: v[i], y: v[j] };
        robust::orient2d(q(a), q(b), q(c))
    };
    o(0, 1) == 0.0 && o(1, 2) == 0.0 && o(0, 2) == 0.0
}
