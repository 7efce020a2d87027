//! Edge flips that lower the surface's bending, vertices unchanged.
//!
//! The convection's surface is the boundary of a union of Delaunay
//! tetrahedra. Where two sampled faces of an object meet at a sharp edge,
//! or where the sampling is uneven, that boundary keeps triangles across
//! the edge (bevels) that no smooth surface through the same points would
//! have. [`flip_to_lower_bending`] flips an edge shared by two faces
//! `abc`, `bad` into `cd` when that lowers the sum of the dihedral angles
//! at the edge and its four neighbours (a data-dependent triangulation;
//! the mesh still interpolates every point).
//!
//! A flip swaps the two faces of one tetrahedron `abcd` for its other two:
//! it adds that tetrahedron to the solid or takes it away. Flips are only
//! made across tetrahedra of the Delaunay triangulation (the cells): the
//! faces then stay Delaunay facets, which meet only along shared edges and
//! vertices, so no flip can fold the surface or make it cross itself.

use crate::manifold::rows;
use rayon::prelude::*;
use std::collections::VecDeque;
use surfrecon_delaunay::hilbert_index;
use surfrecon_geom::DVec3;

/// A half-edge `3f + k` runs from corner `k` of face `f` to corner `k + 1`.
const NONE: u32 = u32::MAX;

/// A flip must lower the bending by more than this (radians): on flat
/// faces the angles are rounding noise and no edge is worth flipping.
const MIN_GAIN: f64 = 1e-6;

/// The twin of each half-edge (`NONE` on the boundary) of a manifold mesh,
/// read from rows of half-edges by start vertex (short rows, no search).
fn twins(triangles: &[[u32; 3]]) -> Vec<u32> {
    let end = |h: usize| triangles[h / 3][(h + 1) % 3];
    let (offsets, leaving) = rows(triangles, |f, &[a, b, c]| {
        [(a, 3 * f), (b, 3 * f + 1), (c, 3 * f + 2)]
    });
    (0..3 * triangles.len())
        .into_par_iter()
        .map(|h| {
            let (a, b) = (triangles[h / 3][h % 3], end(h) as usize);
            let row = &leaving[offsets[b]..offsets[b + 1]];
            row.iter()
                .copied()
                .find(|&g| end(g as usize) == a)
                .unwrap_or(NONE)
        })
        .collect()
}

/// The mesh as faces and half-edge twins, changed in place by flips.
struct FlipMesh<'a> {
    triangles: &'a mut [[u32; 3]],
    twin: Vec<u32>,
    /// Each face's normal, length twice its area (kept up to date).
    normals: Vec<DVec3>,
    /// A half-edge leaving each vertex (kept up to date).
    leaving: Vec<u32>,
    /// The dihedral angle at each half-edge's edge (0 on the boundary; kept
    /// up to date).
    bend: Vec<f64>,
    points: &'a [DVec3],
}

impl FlipMesh<'_> {
    fn start(&self, h: u32) -> u32 {
        self.triangles[h as usize / 3][h as usize % 3]
    }

    fn next(h: u32) -> u32 {
        3 * (h / 3) + (h + 1) % 3
    }

    fn prev(h: u32) -> u32 {
        3 * (h / 3) + (h + 2) % 3
    }

    fn normal(&self, face: usize) -> DVec3 {
        self.normals[face]
    }

    /// The normal of the face across half-edge `h` (`None` on the boundary).
    fn normal_across(&self, h: u32) -> Option<DVec3> {
        let t = self.twin[h as usize];
        (t != NONE).then(|| self.normal(t as usize / 3))
    }

    /// The first half-edge leaving `start(h)` for which `pick` holds,
    /// turning around that vertex from `h` one way, then (when a boundary
    /// stops the turn) the other.
    fn find_around(&self, h: u32, pick: impl Fn(u32) -> bool) -> Option<u32> {
        let turn = |g: u32, forward: bool| match forward {
            true => Some(self.twin[g as usize])
                .filter(|&t| t != NONE)
                .map(Self::next),
            false => Some(self.twin[Self::prev(g) as usize]).filter(|&t| t != NONE),
        };
        for forward in [true, false] {
            let mut g = h;
            loop {
                if pick(g) {
                    return Some(g);
                }
                match turn(g, forward) {
                    None => break,
                    Some(n) if n == h => return None,
                    Some(n) => g = n,
                }
            }
        }
        None
    }

    fn end(&self, h: u32) -> u32 {
        self.start(Self::next(h))
    }

    /// Whether an edge joins `start(h)` to `d`.
    fn has_edge(&self, h: u32, d: u32) -> bool {
        let touches = |g: u32| self.end(g) == d || self.start(Self::prev(g)) == d;
        self.find_around(h, touches).is_some()
    }

    /// The half-edge `a → b`, if the mesh has it.
    fn half_edge(&self, (a, b): (u32, u32)) -> Option<u32> {
        self.find_around(self.leaving[a as usize], |g| self.end(g) == b)
    }

    /// An edge's key: its ends, lower first. Vertices are numbered in
    /// [`SpatialOrder`], so flips are tried in an order of the points'
    /// positions, whatever their input numbering.
    fn edge_key(&self, h: u32) -> (u32, u32) {
        let (p, q) = (self.start(h), self.end(h));
        (p.min(q), p.max(q))
    }

    fn face_normal(&self, face: [u32; 3]) -> DVec3 {
        face_normal(self.points, face)
    }

    /// Stores the dihedral angle at `h` (on both halves of its edge).
    fn bend_at(&mut self, h: u32) {
        let angle = angle(self.normal(h as usize / 3), self.normal_across(h));
        self.bend[h as usize] = angle;
        let t = self.twin[h as usize];
        if t != NONE {
            self.bend[t as usize] = angle;
        }
    }

    fn link(&mut self, h: u32, t: u32) {
        self.twin[h as usize] = t;
        if t != NONE {
            self.twin[t as usize] = h;
        }
    }
}

/// The mesh renumbered along a Hilbert curve through its vertices (ties
/// by coordinates), and its faces sorted by their renumbered corners: an
/// order of the points' positions alone, and one in which neighbours sit
/// close in memory (input points come in any order).
struct SpatialOrder {
    /// The input vertex of each new one.
    vertex: Vec<u32>,
    /// The input face of each new one.
    face: Vec<u32>,
    points: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
}

impl SpatialOrder {
    fn new(points: &[DVec3], triangles: &[[u32; 3]]) -> Self {
        let mut used = vec![false; points.len()];
        for &v in triangles.iter().flatten() {
            used[v as usize] = true;
        }
        let mut vertex: Vec<u32> = (0..points.len() as u32)
            .filter(|&v| used[v as usize])
            .collect();
        let (lo, hi) = vertex.iter().fold(
            (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN)),
            |(lo, hi), &v| (lo.min(points[v as usize]), hi.max(points[v as usize])),
        );
        let scale =
            f64::from((1u32 << CURVE_BITS) - 1) / (hi - lo).max_element().max(f64::MIN_POSITIVE);
        let key = |v: u32| {
            let p = points[v as usize];
            let cell = ((p - lo) * scale).to_array().map(|c| c as u32);
            let bits = p.to_array().map(|c| c.to_bits());
            (hilbert_index(cell, CURVE_BITS), bits)
        };
        vertex.par_sort_by_cached_key(|&v| key(v));
        let mut new_of = vec![NONE; points.len()];
        for (new, &v) in vertex.iter().enumerate() {
            new_of[v as usize] = new as u32;
        }
        let renumbered: Vec<[u32; 3]> = triangles
            .iter()
            .map(|t| t.map(|v| new_of[v as usize]))
            .collect();
        let mut face: Vec<u32> = (0..triangles.len() as u32).collect();
        face.par_sort_unstable_by_key(|&f| rotated_to_lowest(renumbered[f as usize]));
        SpatialOrder {
            points: vertex.iter().map(|&v| points[v as usize]).collect(),
            triangles: face.iter().map(|&f| renumbered[f as usize]).collect(),
            vertex,
            face,
        }
    }
}

/// Bits per axis of the Hilbert curve's grid.
const CURVE_BITS: u32 = 20;

fn rotated_to_lowest([a, b, c]: [u32; 3]) -> [u32; 3] {
    match a.min(b).min(c) {
        m if m == a => [a, b, c],
        m if m == b => [b, c, a],
        _ => [c, a, b],
    }
}

/// The face's normal, computed from its lowest-numbered corner: the same
/// bits however the face's corners are rotated.
fn face_normal(points: &[DVec3], face: [u32; 3]) -> DVec3 {
    let [a, b, c] = rotated_to_lowest(face).map(|v| points[v as usize]);
    (b - a).cross(c - a)
}

/// Sum of angles, added smallest first: the same bits in any order.
fn sum_of(mut angles: [f64; 5]) -> f64 {
    angles.sort_by(f64::total_cmp);
    angles.iter().sum()
}

/// Angle between two face normals; `atan2` stays exact near 0, where the
/// flat faces' angles are.
fn angle(n: DVec3, m: Option<DVec3>) -> f64 {
    m.map_or(0.0, |m| n.cross(m).length().atan2(n.dot(m)))
}

/// One edge `ab` with its faces `abc` (half-edge `h`) and `bad` (its twin).
struct Quad {
    h: u32,
    g: u32,
    corners: [u32; 4],
}

impl FlipMesh<'_> {
    fn quad(&self, h: u32) -> Option<Quad> {
        let g = self.twin[h as usize];
        if g == NONE {
            return None;
        }
        let a = self.start(h);
        let b = self.start(g);
        let c = self.start(Self::prev(h));
        let d = self.start(Self::prev(g));
        (c != d).then_some(Quad {
            h,
            g,
            corners: [a, b, c, d],
        })
    }

    /// Whether flipping `q` lowers the sum of the dihedral angles at its
    /// edge and the four around it by more than [`MIN_GAIN`].
    fn lowers_bending(&self, q: &Quad) -> bool {
        let [a, b, c, d] = q.corners;
        let (h, g) = (q.h, q.g);
        let (m1, m2) = (self.face_normal([a, d, c]), self.face_normal([d, b, c]));
        let [n_bc, n_ca] = [Self::next(h), Self::prev(h)].map(|e| self.normal_across(e));
        let [n_ad, n_db] = [Self::next(g), Self::prev(g)].map(|e| self.normal_across(e));
        let around = [
            h,
            Self::next(h),
            Self::prev(h),
            Self::next(g),
            Self::prev(g),
        ];
        let bound = sum_of(around.map(|e| self.bend[e as usize])) - MIN_GAIN;
        // The new edge's angle alone is a lower bound of the sum after
        // (non-negative terms never lower a float sum): most edges stop here.
        let across = angle(m1, Some(m2));
        across < bound
            && sum_of([
                across,
                angle(m1, n_ad),
                angle(m1, n_ca),
                angle(m2, n_db),
                angle(m2, n_bc),
            ]) < bound
    }

    /// Faces `abc`, `bad` become `adc`, `dbc`; returns the half-edges of
    /// the four edges around the new edge `cd`.
    fn flip(&mut self, q: &Quad) -> [u32; 4] {
        let [a, b, c, d] = q.corners;
        let (f1, f2) = (q.h / 3, q.g / 3);
        let outer = |e: u32| self.twin[e as usize];
        let (o_bc, o_ca) = (outer(Self::next(q.h)), outer(Self::prev(q.h)));
        let (o_ad, o_db) = (outer(Self::next(q.g)), outer(Self::prev(q.g)));
        self.triangles[f1 as usize] = [a, d, c];
        self.triangles[f2 as usize] = [d, b, c];
        self.normals[f1 as usize] = self.face_normal([a, d, c]);
        self.normals[f2 as usize] = self.face_normal([d, b, c]);
        let (e1, e2) = (3 * f1, 3 * f2);
        for (v, h) in [(a, e1), (d, e1 + 1), (c, e1 + 2), (b, e2 + 1)] {
            self.leaving[v as usize] = h;
        }
        self.link(e1, o_ad);
        self.link(e1 + 1, e2 + 2);
        self.link(e1 + 2, o_ca);
        self.link(e2, o_db);
        self.link(e2 + 1, o_bc);
        for h in [e1, e1 + 1, e1 + 2, e2, e2 + 1] {
            self.bend_at(h);
        }
        [e1, e1 + 2, e2, e2 + 1]
    }
}

/// Flip edges of the manifold mesh `triangles` over `points` while a flip
/// lowers the sum of the dihedral angles around it by more than
/// [`MIN_GAIN`] and its quad `a, b, c, d` is a cell: `cells[f]` is a cell
/// of which face `f` is a facet (`None`: the face never flips), and
/// `cell_of_quad(t, [a, b, c, d])` is the cell with those corners, if any,
/// given a cell `t` with the facet `abc`. Edges worth a flip are tried in
/// an order of the points' positions ([`SpatialOrder`]), then those around
/// each flip again: the result does not depend on how the vertices are
/// numbered nor on the faces' order. Returns the flips made.
pub fn flip_to_lower_bending<T: Copy>(
    triangles: &mut [[u32; 3]],
    points: &[DVec3],
    cells: &mut [Option<T>],
    cell_of_quad: impl Fn(T, [u32; 4]) -> Option<T>,
) -> usize {
    let mut order = SpatialOrder::new(points, triangles);
    let mut new_cells: Vec<Option<T>> = order.face.iter().map(|&f| cells[f as usize]).collect();
    let input = |quad: [u32; 4]| quad.map(|v| order.vertex[v as usize]);
    let flips = flip_spatially_ordered(
        &mut order.triangles,
        &order.points,
        &mut new_cells,
        |t, quad| cell_of_quad(t, input(quad)),
    );
    for (new, &f) in order.face.iter().enumerate() {
        triangles[f as usize] = order.triangles[new].map(|v| order.vertex[v as usize]);
        cells[f as usize] = new_cells[new];
    }
    flips
}

/// [`flip_to_lower_bending`] on a mesh in [`SpatialOrder`].
fn flip_spatially_ordered<T: Copy>(
    triangles: &mut [[u32; 3]],
    points: &[DVec3],
    cells: &mut [Option<T>],
    cell_of_quad: impl Fn(T, [u32; 4]) -> Option<T>,
) -> usize {
    let mut leaving = vec![NONE; points.len()];
    for (h, &v) in triangles.iter().flatten().enumerate() {
        leaving[v as usize] = h as u32;
    }
    let mut mesh = FlipMesh {
        twin: twins(triangles),
        normals: (triangles.par_iter())
            .map(|&t| face_normal(points, t))
            .collect(),
        leaving,
        bend: Vec::new(),
        triangles,
        points,
    };
    mesh.bend = (0..mesh.twin.len())
        .into_par_iter()
        .map(|h| angle(mesh.normal(h / 3), mesh.normal_across(h as u32)))
        .collect();
    let halves = mesh.twin.len() as u32;
    // Edges worth flipping now, found in parallel; the others join the
    // queue when a flip next to them changes their gain. Queued by their
    // ends, as a flip moves edges between half-edge slots.
    let mut start: Vec<u32> = (0..halves)
        .into_par_iter()
        .filter(|&h| h < mesh.twin[h as usize])
        .filter(|&h| mesh.quad(h).is_some_and(|q| mesh.lowers_bending(&q)))
        .collect();
    start.par_sort_unstable_by_key(|&h| mesh.edge_key(h));
    let ends = |mesh: &FlipMesh, h: u32| (mesh.start(h), mesh.end(h));
    let mut queue: VecDeque<(u32, u32)> = start.iter().map(|&h| ends(&mesh, h)).collect();
    let mut flips = 0;
    while let Some(edge) = queue.pop_front() {
        let Some(q) = mesh.half_edge(edge).and_then(|h| mesh.quad(h)) else {
            continue;
        };
        if !mesh.lowers_bending(&q) || mesh.has_edge(FlipMesh::prev(q.h), q.corners[3]) {
            continue;
        }
        let (f1, f2) = (q.h as usize / 3, q.g as usize / 3);
        let [a, b, c, d] = q.corners;
        let crossed = (cells[f1].and_then(|t| cell_of_quad(t, [a, b, c, d])))
            .or_else(|| cells[f2].and_then(|t| cell_of_quad(t, [b, a, d, c])));
        let Some(cell) = crossed else { continue };
        let mut around = mesh.flip(&q);
        around.sort_unstable_by_key(|&h| mesh.edge_key(h));
        queue.extend(around.map(|h| ends(&mesh, h)));
        // Both new faces are facets of the crossed cell.
        cells[f1] = Some(cell);
        cells[f2] = Some(cell);
        flips += 1;
    }
    flips
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;
    use surfrecon_geom::shapes::icosphere;

    /// An icosphere with its vertices pushed in and out, so that some
    /// edges are worth flipping.
    fn bumpy_sphere() -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let sphere = icosphere(DVec3::ZERO, 1.0, 3);
        let bump = |i: usize| 1.0 + 0.08 * ((i * 7919 % 13) as f64 / 13.0 - 0.5);
        let points = sphere
            .vertices
            .iter()
            .enumerate()
            .map(|(i, &p)| p * bump(i));
        (points.collect(), sphere.triangles)
    }

    /// Flips with every quad allowed.
    fn flipped(points: &[DVec3], faces: &[[u32; 3]]) -> (Vec<[u32; 3]>, usize) {
        let mut faces = faces.to_vec();
        let mut cells = vec![Some(()); faces.len()];
        let flips = flip_to_lower_bending(&mut faces, points, &mut cells, |_, _| Some(()));
        (faces, flips)
    }

    fn face_set(faces: &[[u32; 3]]) -> BTreeSet<[u32; 3]> {
        faces.iter().map(|&t| rotated_to_lowest(t)).collect()
    }

    /// Sum of the dihedral angles over all edges of a closed mesh.
    fn bending(points: &[DVec3], faces: &[[u32; 3]]) -> f64 {
        let twin = twins(faces);
        let normal = |h: usize| face_normal(points, faces[h / 3]);
        (0..twin.len())
            .filter(|&h| h < twin[h] as usize)
            .map(|h| angle(normal(h), Some(normal(twin[h] as usize))))
            .sum()
    }

    #[test]
    fn flips_lower_the_bending_and_keep_a_closed_manifold() {
        let (points, faces) = bumpy_sphere();
        let (after, flips) = flipped(&points, &faces);
        assert!(flips > 10, "{flips} flips");
        assert!(bending(&points, &after) < bending(&points, &faces) - flips as f64 * MIN_GAIN);
        // Every half-edge has a twin and no edge is there twice.
        assert!(twins(&after).iter().all(|&t| t != NONE));
        let mut edges: Vec<(u32, u32)> = after
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .collect();
        edges.sort_unstable();
        edges.dedup();
        assert_eq!(edges.len(), 3 * after.len());
        assert_eq!(after.len(), faces.len());
    }

    #[test]
    fn flips_do_not_depend_on_the_numbering_or_the_face_order() {
        let (points, faces) = bumpy_sphere();
        let (after, _) = flipped(&points, &faces);
        // Vertices numbered backwards, faces backwards and rotated.
        let n = points.len() as u32;
        let renumber = |v: u32| n - 1 - v;
        let points2: Vec<DVec3> = points.iter().rev().copied().collect();
        let faces2: Vec<[u32; 3]> = (faces.iter().rev().enumerate())
            .map(|(i, t)| {
                let [a, b, c] = t.map(renumber);
                [[a, b, c], [b, c, a], [c, a, b]][i % 3]
            })
            .collect();
        let (after2, _) = flipped(&points2, &faces2);
        let back: Vec<[u32; 3]> = after2.iter().map(|t| t.map(renumber)).collect();
        assert_eq!(face_set(&back), face_set(&after));
    }
}
