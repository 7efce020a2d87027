//! Self-intersections of triangle meshes: pairs of faces that meet
//! anywhere but at the corners and edge they share.
//!
//! A reconstruction that moves vertices off the samples (new points on
//! curved edges, smoothing) can fold a face through a nearby sheet; a
//! Chamfer distance does not see that, a renderer hides it. The test is
//! exact: every decision is the sign of Shewchuk's adaptive `orient3d` or
//! `orient2d` (the `robust` crate) on the input coordinates, so touching
//! counts as meeting and nothing depends on a tolerance.
//!
//! Faces are adjacent when they share a vertex *position* (vertices are
//! welded by exact coordinates first, so a mesh with split seams is judged
//! by its geometry). Adjacent faces are reported only when they meet
//! beyond what they share: faces on one edge, when they fold onto each
//! other (coplanar, on the same side of the edge); faces on one corner,
//! when the edge opposite the corner in one of them meets the other (the
//! faces' common part is a convex set containing the corner, so if it
//! holds a second point, the segment towards it leaves one face through
//! that opposite edge inside the other). Two faces on the same three
//! corners always overlap. Degenerate faces (collinear corners) are tested
//! as their edges against the other face when they share no corner with it;
//! pairs of two degenerate faces, and degenerate faces against faces they
//! share a corner with, are not tested.
//!
//! Candidates come from a uniform grid over the faces' boxes (cells near
//! the median face size, grown until the boxes cover at most a few cells
//! each), each pair considered in one cell only.

use crate::{Aabb, DVec3, TriMesh};
use rayon::prelude::*;
use robust::{Coord, Coord3D};
use std::ops::Range;

/// Pairs `[f, g]` (`f < g`, sorted) of faces of `mesh` that meet beyond
/// their shared corners and edge (see the module for the exact rule).
/// A closed manifold without self-intersections gives none.
pub fn self_intersections(mesh: &TriMesh) -> Vec<[u32; 2]> {
    let faces = Faces::new(mesh);
    let boxes: Vec<Aabb> = (0..faces.corners.len()).map(|f| faces.aabb(f)).collect();
    let grid = Grid::new(&boxes);
    let entries = grid.entries(&boxes);
    let mut pairs: Vec<[u32; 2]> = cell_ranges(&entries)
        .into_par_iter()
        .flat_map_iter(|cell| {
            let key = entries[cell.start].0;
            let members: Vec<u32> = entries[cell].iter().map(|e| e.1).collect();
            let mut found = Vec::new();
            for (i, &f) in members.iter().enumerate() {
                for &g in &members[i + 1..] {
                    let (bf, bg) = (&boxes[f as usize], &boxes[g as usize]);
                    // Each overlapping pair once: in the cell holding the
                    // low corner of the boxes' overlap.
                    if bf.overlaps(bg)
                        && grid.key(bf.min.max(bg.min)) == key
                        && faces.meet(f as usize, g as usize)
                    {
                        found.push([f.min(g), f.max(g)]);
                    }
                }
            }
            found
        })
        .collect();
    pairs.par_sort_unstable();
    pairs
}

/// The pairs of [`self_intersections`] that hold one of `faces` (any
/// order, repeats allowed): after a few vertices moved, only their faces
/// need the test again. Each of `faces` is tested against every face whose
/// box meets its own, found through a grid over `faces`' boxes alone, so
/// the cost is one pass over the mesh's faces plus the tests near `faces`.
pub fn intersections_of(mesh: &TriMesh, faces: &[u32]) -> Vec<[u32; 2]> {
    if faces.is_empty() {
        return Vec::new();
    }
    let corners = |f: u32| mesh.corners(f as usize);
    // In the order `self_intersections` tests them (lower face first).
    let meet_by_position = |f: u32, g: u32| positions_meet(&corners(f), &corners(g));
    let boxes: Vec<Aabb> = faces
        .iter()
        .map(|&f| Aabb::from_points(&corners(f)))
        .collect();
    let extent = boxes.iter().fold(Aabb::EMPTY, |b, f| b.union(*f));
    // Cells as large as the largest box: each of `faces` covers at most
    // two cells per axis.
    let size = boxes
        .iter()
        .map(|b| b.size().max_element())
        .fold(f64::MIN_POSITIVE, f64::max);
    let grid = Grid {
        origin: extent.min,
        size,
    };
    let mut cells: std::collections::HashMap<u64, Vec<u32>> = std::collections::HashMap::new();
    for (k, b) in boxes.iter().enumerate() {
        for key in grid.keys(b, &extent) {
            cells.entry(key).or_default().push(k as u32);
        }
    }
    let mut pairs: Vec<[u32; 2]> = (0..mesh.triangles.len() as u32)
        .into_par_iter()
        .flat_map_iter(|g| {
            let pg = corners(g);
            let bg = Aabb::from_points(&pg);
            let mut found = Vec::new();
            if !bg.overlaps(&extent) {
                return found;
            }
            for key in grid.keys(&bg, &extent) {
                for &k in cells.get(&key).map_or(&[][..], |v| v.as_slice()) {
                    let (f, bf) = (faces[k as usize], &boxes[k as usize]);
                    // Each overlapping pair once per face of `faces`: in
                    // the cell holding the low corner of the overlap.
                    if f != g
                        && bf.overlaps(&bg)
                        && grid.key(bf.min.max(bg.min)) == key
                        && meet_by_position(f.min(g), f.max(g))
                    {
                        found.push([f.min(g), f.max(g)]);
                    }
                }
            }
            found
        })
        .collect();
    pairs.par_sort_unstable();
    pairs.dedup();
    pairs
}

/// [`faces_meet`] with corners shared where their positions are exactly
/// equal, as welding numbers them.
fn positions_meet(pf: &[DVec3; 3], pg: &[DVec3; 3]) -> bool {
    let all = [pf[0], pf[1], pf[2], pg[0], pg[1], pg[2]];
    let bits = |p: DVec3| p.to_array().map(f64::to_bits);
    let id = |i: usize| (0..=i).find(|&j| bits(all[j]) == bits(all[i])).unwrap() as u32;
    faces_meet([0, 1, 2].map(id), pf, [3, 4, 5].map(id), pg)
}

/// The faces' corners by welded vertex number and position.
struct Faces {
    corners: Vec<[u32; 3]>,
    positions: Vec<[DVec3; 3]>,
}

impl Faces {
    fn new(mesh: &TriMesh) -> Faces {
        let welded = weld(&mesh.vertices);
        let corners: Vec<[u32; 3]> = mesh
            .triangles
            .iter()
            .map(|t| t.map(|v| welded[v as usize]))
            .collect();
        let positions: Vec<[DVec3; 3]> =
            (0..mesh.triangles.len()).map(|t| mesh.corners(t)).collect();
        Faces { corners, positions }
    }

    fn aabb(&self, f: usize) -> Aabb {
        Aabb::from_points(&self.positions[f])
    }

    fn meet(&self, f: usize, g: usize) -> bool {
        faces_meet(
            self.corners[f],
            &self.positions[f],
            self.corners[g],
            &self.positions[g],
        )
    }
}

/// Whether two faces meet beyond the corners they share (see the module):
/// corners `cf` at positions `pf`, corners `cg` at `pg`; equal vertex
/// numbers are shared corners (their positions must be equal too).
pub fn faces_meet(cf: [u32; 3], pf: &[DVec3; 3], cg: [u32; 3], pg: &[DVec3; 3]) -> bool {
    let shared_in_f: Vec<usize> = (0..3).filter(|&k| cg.contains(&cf[k])).collect();
    match (is_degenerate(pf), is_degenerate(pg)) {
        (true, true) => return false,
        (true, false) => return shared_in_f.is_empty() && edges_meet_triangle(pf, pg),
        (false, true) => return shared_in_f.is_empty() && edges_meet_triangle(pg, pf),
        (false, false) => {}
    }
    match shared_in_f.len() {
        0 => edges_meet_triangle(pf, pg) || edges_meet_triangle(pg, pf),
        1 => {
            let k = shared_in_f[0];
            let m = (0..3).find(|&m| cg[m] == cf[k]).unwrap();
            segment_meets_triangle(pf[(k + 1) % 3], pf[(k + 2) % 3], pg)
                || segment_meets_triangle(pg[(m + 1) % 3], pg[(m + 2) % 3], pf)
        }
        2 => {
            let own = (0..3).find(|k| !shared_in_f.contains(k)).unwrap();
            let other = (0..3).find(|&m| !cf.contains(&cg[m])).unwrap();
            let (a, b) = (pf[shared_in_f[0]], pf[shared_in_f[1]]);
            folded_onto(a, b, pf[own], pg[other], pf)
        }
        _ => true,
    }
}

fn is_degenerate(t: &[DVec3; 3]) -> bool {
    projection_axis(t).is_none()
}

/// Each vertex's number replaced by the first vertex at the same exact
/// position.
fn weld(vertices: &[DVec3]) -> Vec<u32> {
    let bits = |v: u32| vertices[v as usize].to_array().map(f64::to_bits);
    let mut order: Vec<u32> = (0..vertices.len() as u32).collect();
    order.par_sort_unstable_by_key(|&v| (bits(v), v));
    let mut welded: Vec<u32> = (0..vertices.len() as u32).collect();
    for pair in order.windows(2) {
        if bits(pair[0]) == bits(pair[1]) {
            welded[pair[1] as usize] = welded[pair[0] as usize];
        }
    }
    welded
}

/// Faces on the edge `ab` with third corners `c` (of the face `abc`, not
/// degenerate) and `d`: they overlap beyond the edge only when `d` lies in
/// their plane on the same side of `ab` as `c`.
fn folded_onto(a: DVec3, b: DVec3, c: DVec3, d: DVec3, abc: &[DVec3; 3]) -> bool {
    if orient3d(a, b, c, d) != 0.0 {
        return false;
    }
    let axis = projection_axis(abc).expect("a face that is not degenerate");
    let (sc, sd) = (
        orient2d(axis, a, b, c).signum(),
        orient2d(axis, a, b, d).signum(),
    );
    sd != 0.0 && sc == sd
}

/// Whether an edge of the face with corners `p` meets the triangle `t`
/// (not degenerate).
fn edges_meet_triangle(p: &[DVec3; 3], t: &[DVec3; 3]) -> bool {
    (0..3).any(|k| segment_meets_triangle(p[k], p[(k + 1) % 3], t))
}

/// Whether the closed segment `pq` meets the closed triangle `t` (not
/// degenerate).
fn segment_meets_triangle(p: DVec3, q: DVec3, t: &[DVec3; 3]) -> bool {
    let [a, b, c] = *t;
    let (sp, sq) = (orient3d(a, b, c, p), orient3d(a, b, c, q));
    if sp * sq > 0.0 {
        return false;
    }
    if sp == 0.0 && sq == 0.0 {
        let axis = projection_axis(t).expect("a face that is not degenerate");
        return segment_meets_triangle_2d(axis, p, q, t);
    }
    // The segment crosses the plane at one point: inside the triangle when
    // the line turns the same way (or not at all) about its three edges.
    let turns = [
        orient3d(p, q, a, b),
        orient3d(p, q, b, c),
        orient3d(p, q, c, a),
    ];
    same_signs(&turns)
}

/// The closed segment `pq` against the closed triangle `t`, both in one
/// plane, seen along the coordinate `axis`.
fn segment_meets_triangle_2d(axis: usize, p: DVec3, q: DVec3, t: &[DVec3; 3]) -> bool {
    let inside = |x: DVec3| same_signs(&[0, 1, 2].map(|k| orient2d(axis, t[k], t[(k + 1) % 3], x)));
    inside(p) || inside(q) || (0..3).any(|k| segments_meet_2d(axis, p, q, t[k], t[(k + 1) % 3]))
}

/// Whether the closed segments `pq` and `rs` meet, seen along `axis`.
fn segments_meet_2d(axis: usize, p: DVec3, q: DVec3, r: DVec3, s: DVec3) -> bool {
    let (d1, d2) = (orient2d(axis, r, s, p), orient2d(axis, r, s, q));
    let (d3, d4) = (orient2d(axis, p, q, r), orient2d(axis, p, q, s));
    if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return true;
    }
    // Touching: an endpoint on the other segment's line, within its box.
    let within = |x: DVec3, u: DVec3, v: DVec3| {
        let (i, j) = plane_axes(axis);
        x[i] >= u[i].min(v[i])
            && x[i] <= u[i].max(v[i])
            && x[j] >= u[j].min(v[j])
            && x[j] <= u[j].max(v[j])
    };
    (d1 == 0.0 && within(p, r, s))
        || (d2 == 0.0 && within(q, r, s))
        || (d3 == 0.0 && within(r, p, q))
        || (d4 == 0.0 && within(s, p, q))
}

/// No two of the values have strictly opposite signs.
fn same_signs(values: &[f64]) -> bool {
    !(values.iter().any(|&v| v > 0.0) && values.iter().any(|&v| v < 0.0))
}

/// The coordinate to drop so that the face keeps the largest area in the
/// other two (exactly not zero), or `None` when its corners are collinear.
fn projection_axis(t: &[DVec3; 3]) -> Option<usize> {
    let areas = [0, 1, 2].map(|axis| orient2d(axis, t[0], t[1], t[2]).abs());
    let axis = (0..3)
        .max_by(|&i, &j| areas[i].total_cmp(&areas[j]))
        .unwrap();
    (areas[axis] > 0.0).then_some(axis)
}

/// The two coordinates left when `axis` is dropped, in cyclic order (so a
/// face's orientation about `+axis` is kept).
fn plane_axes(axis: usize) -> (usize, usize) {
    ((axis + 1) % 3, (axis + 2) % 3)
}

fn orient2d(axis: usize, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (i, j) = plane_axes(axis);
    let coord = |v: DVec3| Coord { x: v[i], y: v[j] };
    robust::orient2d(coord(a), coord(b), coord(c))
}

fn orient3d(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    let coord = |v: DVec3| Coord3D {
        x: v.x,
        y: v.y,
        z: v.z,
    };
    robust::orient3d(coord(a), coord(b), coord(c), coord(d))
}

/// A uniform grid of cubes over the boxes' extent.
struct Grid {
    origin: DVec3,
    size: f64,
}

/// Cells per axis at most 2^21, so three cell numbers pack in a `u64`.
const CELL_BITS: u32 = 21;

/// Grid entries per face at most (on average) before the cells grow.
const ENTRIES_PER_FACE: usize = 8;

impl Grid {
    /// Cells the size of the median box's longest side, doubled while the
    /// boxes would cover more than [`ENTRIES_PER_FACE`] cells each on
    /// average (a few large faces among small ones) or the extent more
    /// than 2^21 cells.
    fn new(boxes: &[Aabb]) -> Grid {
        let extent = boxes.iter().fold(Aabb::EMPTY, |b, f| b.union(*f));
        let mut sides: Vec<f64> = boxes.iter().map(|b| b.size().max_element()).collect();
        let median = match sides.len() {
            0 => 1.0,
            n => *sides.select_nth_unstable_by(n / 2, f64::total_cmp).1,
        };
        let largest = extent.size().max_element();
        let floor = largest / (1u64 << (CELL_BITS - 1)) as f64;
        let mut grid = Grid {
            origin: extent.min,
            size: [median, floor, f64::MIN_POSITIVE]
                .into_iter()
                .fold(0.0, f64::max),
        };
        while grid.size.is_finite()
            && boxes
                .iter()
                .fold(0usize, |n, b| n.saturating_add(grid.cell_count(b)))
                > ENTRIES_PER_FACE * boxes.len().max(1)
        {
            grid.size *= 2.0;
        }
        grid
    }

    fn cell(&self, p: DVec3) -> [u64; 3] {
        let max = ((1u64 << CELL_BITS) - 1) as f64;
        ((p - self.origin) / self.size)
            .floor()
            .clamp(DVec3::ZERO, DVec3::splat(max))
            .to_array()
            .map(|c| c as u64)
    }

    fn key(&self, p: DVec3) -> u64 {
        let [x, y, z] = self.cell(p);
        (x << (2 * CELL_BITS)) | (y << CELL_BITS) | z
    }

    /// Keys of the cells `b` covers within `extent` (boxes overlapping).
    fn keys(&self, b: &Aabb, extent: &Aabb) -> impl Iterator<Item = u64> {
        let lo = self.cell(b.min.max(extent.min));
        let hi = self.cell(b.max.min(extent.max));
        (lo[0]..=hi[0]).flat_map(move |x| {
            (lo[1]..=hi[1]).flat_map(move |y| {
                (lo[2]..=hi[2]).map(move |z| (x << (2 * CELL_BITS)) | (y << CELL_BITS) | z)
            })
        })
    }

    fn cell_count(&self, b: &Aabb) -> usize {
        let (lo, hi) = (self.cell(b.min), self.cell(b.max));
        (0..3).map(|a| (hi[a] - lo[a] + 1) as usize).product()
    }

    /// `(cell key, face)` for every cell each face's box covers, sorted.
    fn entries(&self, boxes: &[Aabb]) -> Vec<(u64, u32)> {
        let mut entries: Vec<(u64, u32)> = Vec::with_capacity(ENTRIES_PER_FACE * boxes.len());
        for (f, b) in boxes.iter().enumerate() {
            if b.is_empty() {
                continue;
            }
            let (lo, hi) = (self.cell(b.min), self.cell(b.max));
            for x in lo[0]..=hi[0] {
                for y in lo[1]..=hi[1] {
                    for z in lo[2]..=hi[2] {
                        let key = (x << (2 * CELL_BITS)) | (y << CELL_BITS) | z;
                        entries.push((key, f as u32));
                    }
                }
            }
        }
        entries.par_sort_unstable();
        entries
    }
}

/// Index ranges of `entries` with one cell key.
fn cell_ranges(entries: &[(u64, u32)]) -> Vec<Range<usize>> {
    let mut ranges = Vec::new();
    let mut start = 0;
    for i in 1..=entries.len() {
        if i == entries.len() || entries[i].0 != entries[start].0 {
            ranges.push(start..i);
            start = i;
        }
    }
    ranges
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::{icosphere, torus};
    use rand::{Rng, SeedableRng};

    fn mesh(vertices: &[[f64; 3]], triangles: &[[u32; 3]]) -> TriMesh {
        TriMesh {
            vertices: vertices.iter().map(|&v| DVec3::from_array(v)).collect(),
            triangles: triangles.to_vec(),
            normals: None,
        }
    }

    #[test]
    fn crossing_triangles_are_found() {
        // A horizontal triangle pierced by a vertical one through its middle.
        let m = mesh(
            &[
                [0.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [0.0, 2.0, 0.0],
                [0.5, 0.5, -1.0],
                [0.6, 0.5, 1.0],
                [0.5, 0.6, 1.0],
            ],
            &[[0, 1, 2], [3, 4, 5]],
        );
        assert_eq!(self_intersections(&m), vec![[0, 1]]);
        // Lifted clear of the plane: nothing.
        let mut apart = m.clone();
        for v in &mut apart.vertices[3..] {
            v.z += 1.5;
        }
        assert!(self_intersections(&apart).is_empty());
        // Lowered so one corner just touches the plane inside the face:
        // touching counts (exact).
        let mut touching = m.clone();
        for v in &mut touching.vertices[3..] {
            v.z += 1.0;
        }
        assert_eq!(self_intersections(&touching), vec![[0, 1]]);
    }

    #[test]
    fn closed_meshes_have_none() {
        for subdivisions in [1, 3, 4] {
            let sphere = icosphere(DVec3::new(0.1, -0.2, 0.3), 1.7, subdivisions);
            assert!(self_intersections(&sphere).is_empty(), "{subdivisions}");
        }
        assert!(self_intersections(&torus(1.0, 0.3, 48, 16)).is_empty());
    }

    /// Two spheres overlapping: every crossing pair lies on the circle
    /// where they meet, and there are as many as the circle needs.
    #[test]
    fn overlapping_spheres_meet_along_their_circle() {
        let mut a = icosphere(DVec3::ZERO, 1.0, 3);
        let b = icosphere(DVec3::new(1.0, 0.0, 0.0), 1.0, 3);
        let offset = a.vertices.len() as u32;
        a.vertices.extend(&b.vertices);
        a.triangles
            .extend(b.triangles.iter().map(|t| t.map(|v| v + offset)));
        let pairs = self_intersections(&a);
        let first = a.triangles.len() - b.triangles.len();
        assert!(pairs.len() > 64, "{}", pairs.len());
        for [f, g] in pairs {
            assert!((f as usize) < first && g as usize >= first, "{f} {g}");
            let x = a.corners(f as usize).iter().map(|p| p.x).sum::<f64>() / 3.0;
            assert!((x - 0.5).abs() < 0.2, "face {f} at x = {x}");
        }
    }

    #[test]
    fn faces_touching_at_what_they_share_are_not_reported() {
        let v = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [-1.0, -1.0, 0.0],
            [1.0, 1.0, 1.0],
        ];
        // Edge 0-1: coplanar on the other side, bent upwards; corner 0: a
        // coplanar face in the opposite angle, one leaning over the plane.
        for other in [[1, 0, 3], [1, 0, 4], [0, 5, 3], [0, 4, 6]] {
            let m = mesh(&v, &[[0, 1, 2], other]);
            assert!(self_intersections(&m).is_empty(), "{other:?}");
        }
        // The same corner given twice (a split seam) is still shared.
        let mut seam = v.to_vec();
        seam.push([0.0, 0.0, 0.0]);
        let m = mesh(&seam, &[[0, 1, 2], [1, 7, 4]]);
        assert!(self_intersections(&m).is_empty());
    }

    #[test]
    fn adjacent_faces_that_fold_or_pierce_are_reported() {
        let v = [
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [1.0, 0.5, 0.0],
            [0.5, 0.5, -1.0],
            [0.8, 0.8, 1.0],
            [0.3, 0.3, 0.0],
        ];
        // Folded onto the face across their edge; on one corner, the
        // other's opposite edge piercing the face; on one corner, coplanar
        // and overlapping; on three corners, coincident.
        for other in [[1, 0, 3], [0, 4, 5], [0, 3, 6], [0, 2, 1]] {
            let m = mesh(&v, &[[0, 1, 2], other]);
            assert_eq!(self_intersections(&m), vec![[0, 1]], "{other:?}");
        }
    }

    /// The grid finds exactly the pairs a test of every pair finds, on a
    /// soup of random small and a few large triangles.
    #[test]
    fn the_grid_finds_what_every_pair_finds() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let mut vertices = Vec::new();
        let mut triangles = Vec::new();
        for t in 0..400u32 {
            let centre = DVec3::new(rng.random(), rng.random(), rng.random());
            let size = if t % 50 == 0 { 0.8 } else { 0.15 };
            for _ in 0..3 {
                let d = DVec3::new(rng.random(), rng.random(), rng.random()) - 0.5;
                vertices.push(centre + d * size);
            }
            triangles.push([3 * t, 3 * t + 1, 3 * t + 2]);
        }
        let m = TriMesh {
            vertices,
            triangles,
            normals: None,
        };
        let faces = Faces::new(&m);
        let mut all = Vec::new();
        for f in 0..m.triangles.len() {
            for g in f + 1..m.triangles.len() {
                if faces.meet(f, g) {
                    all.push([f as u32, g as u32]);
                }
            }
        }
        assert!(all.len() > 20, "{}", all.len());
        assert_eq!(self_intersections(&m), all);
    }

    /// The pairs found for a set of faces are exactly those of the whole
    /// mesh that hold one of them, shared corners included: a sphere with
    /// some vertices thrown about (faces fold over their neighbours), one
    /// vertex moved onto another's position (welded by position).
    #[test]
    fn the_pairs_of_some_faces_are_those_of_the_whole_mesh() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let mut m = icosphere(DVec3::ZERO, 1.0, 3);
        for v in (0..m.vertices.len()).step_by(9) {
            let d = DVec3::new(rng.random(), rng.random(), rng.random()) - 0.5;
            m.vertices[v] += d * 0.6;
        }
        m.vertices[5] = m.vertices[40];
        let all = self_intersections(&m);
        assert!(all.len() > 50, "{}", all.len());
        let every = |step: usize| (0..m.triangles.len() as u32).step_by(step).collect();
        let subsets: Vec<Vec<u32>> = vec![every(1), every(3), every(17), vec![all[0][1]]];
        for faces in subsets {
            let want: Vec<[u32; 2]> = (all.iter())
                .filter(|p| p.iter().any(|f| faces.contains(f)))
                .copied()
                .collect();
            assert!(!want.is_empty());
            assert_eq!(intersections_of(&m, &faces), want, "{} faces", faces.len());
        }
        assert!(intersections_of(&m, &[]).is_empty());
    }
}
