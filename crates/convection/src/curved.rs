//! Splitting edges where the surface bends between two points.
//!
//! The convection's triangles span the samples with flat faces: where the
//! sampling is sparse relative to the curvature (the sparse side of a
//! non-uniform sample), a flat triangle cuts across the curved surface by
//! its sagitta. Each such edge `ab` gets a new vertex on a smooth curve
//! through `a` and `b`: the cubic Hermite curve whose tangents at `a` and
//! `b` are the edge projected on their tangent planes, at its middle
//! `(a + b)/2 + ((e·n_b) n_b − (e·n_a) n_a)/8` with `e = b − a` (the
//! mid-edge point of PN triangles; on a circle it lies at the arc's
//! sagitta up to fourth order, and it does not depend on the normals'
//! signs). The faces are then split conformingly (one, two or three split
//! sides give two, three or four faces), so the mesh stays a manifold of
//! the same topology and every input point stays a vertex.
//!
//! Only smooth, bent edges are split. Near a box's or fandisk's sharp
//! edges a vertex normal leans between the faces, and a curve from it
//! would round the edge off (on the harness box, new points up to 0.45 ‰
//! of the diagonal off the faces). So a vertex is smooth when its
//! angle-weighted normal agrees with every face around it within
//! [`MAX_TURN_DEGREES`] (at a crease of more than twice that, the normal
//! is farther than that from both sides), and an edge is split only when
//! every vertex of the faces around both its ends is smooth (two rings
//! away from any crease; no split on the harness box) and the two end
//! normals agree within the same angle. Flat parts, where all normals
//! agree, get no bulge. Then the
//! new point must leave the chord by more than [`MIN_BULGE`] of the
//! median edge length and [`MIN_BULGE_OF_DIAGONAL`] of the diagonal
//! (flat parts and densely sampled ones gain nothing from more faces). Deterministic: edges in the order of their vertex
//! numbers.

use rayon::slice::ParallelSliceMut;
use surfrecon_geom::{DVec3, TriMesh};

/// Largest angle between the normals around an edge that is still split:
/// smooth surfaces turn by a few degrees per edge, creases by far more.
/// (Harness, non-uniform inputs: 15° gives up half the gain on the two
/// tori, 25° lets a few points bulge off the fandisk's faces.)
pub const MAX_TURN_DEGREES: f64 = 20.0;

/// Smallest distance of the new point from the edge's midpoint, as a
/// fraction of the median edge length, for the edge to be split.
pub const MIN_BULGE: f64 = 0.005;

/// ... and as a fraction of the bounding box's diagonal. Dense samples
/// turn by as much per edge as sparse ones where they follow a faceted
/// surface (the Dragon-scale bunny: 322k of 437k points would get a new
/// neighbour, Chamfer 0.0897 → 0.0883 ‰); above this floor 88k do
/// (0.0887 ‰). At 20k points no edge the relative test passes is below it.
pub const MIN_BULGE_OF_DIAGONAL: f64 = 2e-5;

/// No new vertex on this side of a face.
const NONE: u32 = u32::MAX;

/// Splits the bent smooth edges of `mesh` (see the module), appending the
/// new vertices after the existing ones. Returns the number of new
/// vertices.
pub fn split_curved_edges(mesh: &mut TriMesh) -> usize {
    let normals = angle_weighted_normals(&mesh.vertices, &mesh.triangles);
    let face_normals: Vec<DVec3> = (0..mesh.triangles.len())
        .map(|t| face_normal(&mesh.corners(t)))
        .collect();
    let sides = sorted_sides(&mesh.triangles);
    let groups = edge_groups(&sides);
    let median = median_edge_length(&mesh.vertices, &sides, &groups);
    let min_bulge = (MIN_BULGE * median).max(MIN_BULGE_OF_DIAGONAL * mesh.bounds().diagonal());
    let max_turn = MAX_TURN_DEGREES.to_radians().cos();
    let smooth = beside_smooth_vertices(
        &mesh.triangles,
        &smooth_vertices(&mesh.triangles, &normals, &face_normals, max_turn),
    );
    let mut mids = vec![[NONE; 3]; mesh.triangles.len()];
    let old_count = mesh.vertices.len();
    for range in groups {
        let edge = &sides[range];
        // Boundary edges (one face) may be split; pinched ones never.
        if edge.len() > 2 {
            continue;
        }
        let (a, b) = (edge[0].low as usize, edge[0].high as usize);
        if !(smooth[a] && smooth[b] && normals[a].dot(normals[b]) >= max_turn) {
            continue;
        }
        let (pa, pb) = (mesh.vertices[a], mesh.vertices[b]);
        let bulge = hermite_bulge(pa, pb, normals[a], normals[b]);
        // A NaN bulge (degenerate normals) is no bulge either.
        let length = bulge.length();
        if length.is_nan() || length <= min_bulge {
            continue;
        }
        let index = mesh.vertices.len() as u32;
        mesh.vertices.push((pa + pb) * 0.5 + bulge);
        if let Some(n) = mesh.normals.as_mut() {
            n.push((normals[a] + normals[b]).normalize_or_zero());
        }
        for s in edge {
            mids[s.face as usize][s.side as usize] = index;
        }
    }
    let added = mesh.vertices.len() - old_count;
    if added > 0 {
        mesh.triangles = split_faces(&mesh.vertices, &mesh.triangles, &mids);
    }
    added
}

/// One side of a face: the edge `low < high` (vertex numbers), its face
/// and the side's number `k` (from corner `k` to corner `k + 1`).
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Side {
    low: u32,
    high: u32,
    face: u32,
    side: u8,
}

/// Every face side, sorted by edge then face: the sides of one edge are
/// consecutive, and the order depends on the numbering only.
fn sorted_sides(triangles: &[[u32; 3]]) -> Vec<Side> {
    let mut sides = Vec::with_capacity(3 * triangles.len());
    for (f, t) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            sides.push(Side {
                low: a.min(b),
                high: a.max(b),
                face: f as u32,
                side: k as u8,
            });
        }
    }
    // Distinct keys (each face side once): the order is unique, so the
    // parallel sort is as deterministic as a sequential one.
    sides.par_sort_unstable();
    sides
}

/// Index ranges of `sides` sharing one edge.
fn edge_groups(sides: &[Side]) -> Vec<std::ops::Range<usize>> {
    let mut groups = Vec::new();
    let mut start = 0;
    for i in 1..=sides.len() {
        let ends = i == sides.len()
            || (sides[i].low, sides[i].high) != (sides[start].low, sides[start].high);
        if ends {
            groups.push(start..i);
            start = i;
        }
    }
    groups
}

fn median_edge_length(
    vertices: &[DVec3],
    sides: &[Side],
    groups: &[std::ops::Range<usize>],
) -> f64 {
    let mut lengths: Vec<f64> = groups
        .iter()
        .map(|r| {
            let s = sides[r.start];
            vertices[s.low as usize].distance(vertices[s.high as usize])
        })
        .collect();
    if lengths.is_empty() {
        return 0.0;
    }
    let middle = lengths.len() / 2;
    *lengths.select_nth_unstable_by(middle, f64::total_cmp).1
}

/// Vertices whose normal agrees with every face around them within the
/// cosine `max_turn` (zero normals, of degenerate faces, never do).
fn smooth_vertices(
    triangles: &[[u32; 3]],
    normals: &[DVec3],
    face_normals: &[DVec3],
    max_turn: f64,
) -> Vec<bool> {
    let mut smooth = vec![true; normals.len()];
    for (t, f) in triangles.iter().zip(face_normals) {
        for &v in t {
            let v = v as usize;
            smooth[v] &= f.dot(normals[v]) >= max_turn;
        }
    }
    smooth
}

/// Vertices whose faces have only `smooth` corners (themselves included).
fn beside_smooth_vertices(triangles: &[[u32; 3]], smooth: &[bool]) -> Vec<bool> {
    let mut beside = smooth.to_vec();
    for t in triangles {
        if !t.iter().all(|&v| smooth[v as usize]) {
            for &v in t {
                beside[v as usize] = false;
            }
        }
    }
    beside
}

/// Offset of the cubic Hermite curve's middle from the chord's middle
/// (tangents: the chord projected on each end's tangent plane).
fn hermite_bulge(a: DVec3, b: DVec3, na: DVec3, nb: DVec3) -> DVec3 {
    let e = b - a;
    (nb * e.dot(nb) - na * e.dot(na)) / 8.0
}

fn face_normal(c: &[DVec3; 3]) -> DVec3 {
    (c[1] - c[0]).cross(c[2] - c[0]).normalize_or_zero()
}

/// Unit vertex normals, each face's normal weighted by its angle at the
/// vertex (independent of how finely the faces around a vertex are cut).
fn angle_weighted_normals(vertices: &[DVec3], triangles: &[[u32; 3]]) -> Vec<DVec3> {
    let mut sums = vec![DVec3::ZERO; vertices.len()];
    for t in triangles {
        let c = t.map(|v| vertices[v as usize]);
        let n = face_normal(&c);
        for k in 0..3 {
            let u = c[(k + 1) % 3] - c[k];
            let w = c[(k + 2) % 3] - c[k];
            let angle = u.cross(w).length().atan2(u.dot(w));
            sums[t[k] as usize] += n * angle;
        }
    }
    sums.into_iter().map(DVec3::normalize_or_zero).collect()
}

/// Each face cut along its split sides (`mids[f][k]`: the new vertex on
/// side `k`, or [`NONE`]), orientation kept.
fn split_faces(vertices: &[DVec3], triangles: &[[u32; 3]], mids: &[[u32; 3]]) -> Vec<[u32; 3]> {
    let mut out = Vec::with_capacity(triangles.len() * 2);
    for (t, m) in triangles.iter().zip(mids) {
        let split = m.iter().filter(|&&v| v != NONE).count();
        match split {
            0 => out.push(*t),
            1 => {
                // Rotate so side 0 (corners 0 to 1) is the split one.
                let k = (0..3).find(|&k| m[k] != NONE).unwrap();
                let [a, b, c] = rotate(t, k);
                out.extend([[a, m[k], c], [m[k], b, c]]);
            }
            2 => {
                // Rotate so side 0 is the one left whole.
                let k = (0..3).find(|&k| m[k] == NONE).unwrap();
                let [a, b, c] = rotate(t, k);
                let (bc, ca) = (m[(k + 1) % 3], m[(k + 2) % 3]);
                out.push([c, ca, bc]);
                // The quad a, b, bc, ca: cut along its shorter diagonal.
                let d = |p: u32, q: u32| vertices[p as usize].distance(vertices[q as usize]);
                match d(a, bc) <= d(b, ca) {
                    true => out.extend([[a, b, bc], [a, bc, ca]]),
                    false => out.extend([[a, b, ca], [b, bc, ca]]),
                }
            }
            _ => {
                let [a, b, c] = *t;
                let [ab, bc, ca] = *m;
                out.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
            }
        }
    }
    out
}

/// The face's corners starting at corner `k`.
fn rotate(t: &[u32; 3], k: usize) -> [u32; 3] {
    [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a circle of radius 1, the Hermite middle of a chord lies on the
    /// arc up to fourth order in the chord's angle (the chord's own middle
    /// misses it by second order), whatever the normals' signs.
    #[test]
    fn hermite_middle_lies_on_the_arc() {
        for degrees in [5.0f64, 15.0, 30.0] {
            let half = degrees.to_radians() / 2.0;
            let (na, nb) = (
                DVec3::new(-half.sin(), half.cos(), 0.0),
                DVec3::new(half.sin(), half.cos(), 0.0),
            );
            let (a, b) = (na, nb);
            let mid = (a + b) * 0.5 + hermite_bulge(a, b, na, -nb);
            let chord_error = 1.0 - half.cos();
            let error = (mid.length() - 1.0).abs();
            assert!(
                error < 0.06 * chord_error,
                "{degrees}°: {error} vs chord {chord_error}"
            );
        }
    }

    /// A flat fan is left alone; a bent one gets its bent edges split and
    /// stays a consistently oriented fan around the same centre.
    #[test]
    fn only_bent_edges_are_split() {
        let ring = |z: f64| -> TriMesh {
            let mut vertices = vec![DVec3::ZERO];
            for i in 0..6 {
                let a = i as f64 * std::f64::consts::TAU / 6.0;
                let (x, y) = (a.cos(), a.sin());
                vertices.push(DVec3::new(x, y, z));
            }
            let triangles = (0..6u32).map(|i| [0, 1 + i, 1 + (i + 1) % 6]).collect();
            TriMesh {
                vertices,
                triangles,
                normals: None,
            }
        };
        let mut flat = ring(0.0);
        assert_eq!(split_curved_edges(&mut flat), 0);
        assert_eq!(flat.triangles.len(), 6);

        let mut cap = ring(-0.2);
        let added = split_curved_edges(&mut cap);
        // The six spokes bend (centre normal up, rim normals tilted); the
        // rim edges join rim vertices of the same tilt towards the centre.
        assert!(added >= 6, "{added}");
        assert_eq!(cap.vertices.len(), 7 + added);
        for t in &cap.triangles {
            let n = face_normal(&t.map(|v| cap.vertices[v as usize]));
            assert!(n.z > 0.9, "orientation kept: {n}");
        }
        // Spoke middles (the new points nearer the centre than the rim's
        // middles) bulge upwards, above their chords.
        let spokes = cap.vertices[7..]
            .iter()
            .filter(|v| v.truncate().length() < 0.7);
        assert_eq!(spokes.clone().count(), 6);
        for v in spokes {
            assert!(v.z > -0.2 * v.truncate().length() + 0.01, "{v}");
        }
    }
}
