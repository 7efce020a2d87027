//! Marching-cubes case tables, generated (not transcribed) once at start-up.
//!
//! Cube corners are numbered `c = x + 2y + 4z`. Edge `e` runs along axis
//! `e / 4` and its lower corner has the two other coordinates given by the
//! bits of `e % 4` (see [`EDGE_CORNERS`]). A corner is *positive* when its
//! value is `>= iso`.
//!
//! How a case is built: on each of the six faces the edge crossings are
//! paired into segments. A face with two crossings has one way to do it; an
//! ambiguous face (positive corners on one diagonal, negative on the other)
//! has two, chosen by a bit: 1 = the positive corners are connected across
//! the face, 0 = they are separated. The caller decides that bit from the
//! four face values alone (asymptotic decider), so both cubes sharing the
//! face pair its crossings the same way: the mesh is watertight.
//! The segments are oriented (positive side on the left, seen from outside
//! the cube, so triangles face the positive side) and chained into closed loops; each loop is triangulated as a
//! disk (interior ambiguities are always resolved as separate disks, never
//! as a tunnel). Triangulations never use a diagonal between two crossings
//! of one face, because the neighbouring cube might use the same edge:
//! every mesh edge therefore lies in exactly two triangles (edge-manifold).
//! The few large loops that cannot be triangulated under that rule get a
//! fan around an extra vertex at the loop's centre (triangle corner ids
//! `12 + k` name the centre of the case's k-th such loop).

use std::sync::OnceLock;

/// Most loop-centre vertices any case needs (checked by a test).
pub const MAX_LOOP_CENTRES: usize = 4;

/// The two corners of each edge, lower corner first.
pub const EDGE_CORNERS: [[u8; 2]; 12] = edge_corners();

const fn edge_corners() -> [[u8; 2]; 12] {
    let mut out = [[0u8; 2]; 12];
    let mut e = 0;
    while e < 12 {
        let axis = e / 4;
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let lo = (((e % 4) & 1) << u) | (((e % 4) >> 1) << v);
        out[e] = [lo as u8, (lo | (1 << axis)) as u8];
        e += 1;
    }
    out
}

/// Corners of each face, counter-clockwise seen from outside the cube.
/// Face `f` is perpendicular to axis `f / 2`, on side `f % 2`.
pub const FACE_CORNERS: [[u8; 4]; 6] = face_corners();

const fn face_corners() -> [[u8; 4]; 6] {
    let mut out = [[0u8; 4]; 6];
    let mut f = 0;
    while f < 6 {
        let axis = f / 2;
        let side = f % 2;
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let base = side << axis;
        // (u, v, axis) is right-handed, so (0,0),(1,0),(1,1),(0,1) in (u, v)
        // is counter-clockwise around +axis; the low face looks along -axis.
        let ccw = [
            base,
            base | (1 << u),
            base | (1 << u) | (1 << v),
            base | (1 << v),
        ];
        let mut i = 0;
        while i < 4 {
            out[f][i] = if side == 1 {
                ccw[i] as u8
            } else {
                ccw[(4 - i) % 4] as u8
            };
            i += 1;
        }
        f += 1;
    }
    out
}

/// The edge joining two corners.
fn edge_between(a: u8, b: u8) -> u8 {
    let (lo, hi) = (a.min(b), a.max(b));
    let axis = (hi ^ lo).trailing_zeros() as usize;
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let code = ((lo >> u) & 1) | (((lo >> v) & 1) << 1);
    (axis * 4) as u8 + code
}

/// Whether face `f` is ambiguous for corner signs `config` (bit c = corner c positive).
pub fn face_is_ambiguous(config: u8, f: usize) -> bool {
    let s = FACE_CORNERS[f].map(|c| (config >> c) & 1);
    s[0] == s[2] && s[1] == s[3] && s[0] != s[1]
}

/// Case table: for every corner configuration and every choice on its
/// ambiguous faces, the triangles as triples of edge numbers.
pub struct CubeTable {
    /// Bit f set when face f of the configuration is ambiguous.
    pub ambiguous_faces: [u8; 256],
    offsets: Vec<u32>,
    edges: Vec<[u8; 3]>,
    /// Per case, the loops (edge lists) whose centre is an extra vertex.
    centres: Vec<Vec<Vec<u8>>>,
}

impl CubeTable {
    /// Triangles of `config` with face choices `face_bits` (bits of
    /// non-ambiguous faces must be zero).
    #[inline]
    pub fn triangles(&self, config: u8, face_bits: u8) -> &[[u8; 3]] {
        let k = (config as usize) << 6 | face_bits as usize;
        &self.edges[self.offsets[k] as usize..self.offsets[k + 1] as usize]
    }

    /// The loops whose centre vertex is triangle corner id `12 + k`.
    #[inline]
    pub fn loop_centres(&self, config: u8, face_bits: u8) -> &[Vec<u8>] {
        &self.centres[(config as usize) << 6 | face_bits as usize]
    }
}

/// The shared case table (built on first use, a few milliseconds).
pub fn cube_table() -> &'static CubeTable {
    static TABLE: OnceLock<CubeTable> = OnceLock::new();
    TABLE.get_or_init(build_cube_table)
}

fn build_cube_table() -> CubeTable {
    let mut ambiguous_faces = [0u8; 256];
    let mut offsets = Vec::with_capacity(256 * 64 + 1);
    let mut edges = Vec::new();
    let mut centres = Vec::with_capacity(256 * 64);
    for config in 0..=255u8 {
        let amb = (0..6).fold(0u8, |m, f| m | ((face_is_ambiguous(config, f) as u8) << f));
        ambiguous_faces[config as usize] = amb;
        for bits in 0..64u8 {
            offsets.push(edges.len() as u32);
            let mut case_centres = Vec::new();
            if bits & !amb == 0 {
                edges.extend(case_triangles(config, bits, &mut case_centres));
            }
            centres.push(case_centres);
        }
    }
    offsets.push(edges.len() as u32);
    CubeTable {
        ambiguous_faces,
        offsets,
        edges,
        centres,
    }
}

/// Oriented segments (from edge, to edge) of every face.
fn face_segments(config: u8, face_bits: u8) -> Vec<(u8, u8)> {
    let mut segs = Vec::new();
    for (f, &corners) in FACE_CORNERS.iter().enumerate() {
        let positive = |i: usize| (config >> corners[i % 4]) & 1 == 1;
        // Crossings in counter-clockwise order: (edge, entering positive?).
        let crossings: Vec<(u8, bool)> = (0..4)
            .filter(|&i| positive(i) != positive(i + 1))
            .map(|i| {
                (
                    edge_between(corners[i], corners[(i + 1) % 4]),
                    positive(i + 1),
                )
            })
            .collect();
        if crossings.is_empty() {
            continue;
        }
        // Each positive run is entered at crossing `i` and left at `i + 1`.
        // Separating it: the segment goes from its exit to its entry.
        // Connecting positive runs: from an exit to the next entry.
        let connect = (face_bits >> f) & 1 == 1;
        let n = crossings.len();
        for i in 0..n {
            let (edge, entering) = crossings[i];
            if entering {
                continue;
            }
            let exit = edge;
            let entry = if connect {
                crossings[(i + 1) % n].0
            } else {
                crossings[(i + n - 1) % n].0
            };
            segs.push((exit, entry));
        }
    }
    segs
}

/// Faces each edge lies on (two per edge).
fn edge_faces(e: u8) -> [usize; 2] {
    let [a, b] = EDGE_CORNERS[e as usize];
    let mut out = [0; 2];
    let mut n = 0;
    for (f, corners) in FACE_CORNERS.iter().enumerate() {
        if corners.contains(&a) && corners.contains(&b) {
            out[n] = f;
            n += 1;
        }
    }
    out
}

fn share_face(a: u8, b: u8) -> bool {
    let fa = edge_faces(a);
    edge_faces(b).iter().any(|f| fa.contains(f))
}

fn edge_midpoint(e: u8) -> [f64; 3] {
    let [a, b] = EDGE_CORNERS[e as usize];
    std::array::from_fn(|k| 0.5 * (((a >> k) & 1) + ((b >> k) & 1)) as f64)
}

fn case_triangles(config: u8, face_bits: u8, centres: &mut Vec<Vec<u8>>) -> Vec<[u8; 3]> {
    let segs = face_segments(config, face_bits);
    let mut next = [u8::MAX; 12];
    for &(a, b) in &segs {
        debug_assert_eq!(next[a as usize], u8::MAX, "edge leaves twice");
        next[a as usize] = b;
    }
    let mut seen = [false; 12];
    let mut tris = Vec::new();
    for &(start, _) in &segs {
        if seen[start as usize] {
            continue;
        }
        let mut lp = Vec::new();
        let mut e = start;
        while !seen[e as usize] {
            seen[e as usize] = true;
            lp.push(e);
            e = next[e as usize];
        }
        match triangulate_loop(&lp) {
            Some(t) => tris.extend(t),
            None => {
                let centre = 12 + centres.len() as u8;
                tris.extend((0..lp.len()).map(|i| [lp[i], lp[(i + 1) % lp.len()], centre]));
                centres.push(lp);
            }
        }
    }
    tris
}

/// Minimum-total-diagonal-length triangulation of a loop that never uses a
/// diagonal between two crossings of one face (dynamic programming over
/// sub-polygons; loops have at most 12 vertices). `None` if impossible.
fn triangulate_loop(lp: &[u8]) -> Option<Vec<[u8; 3]>> {
    let n = lp.len();
    let len = |i: usize, j: usize| {
        let (p, q) = (edge_midpoint(lp[i]), edge_midpoint(lp[j]));
        (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt()
    };
    // A chord (i, j) is allowed if it is a loop side or joins crossings on no common face.
    let allowed =
        |i: usize, j: usize| j == i + 1 || (i == 0 && j == n - 1) || !share_face(lp[i], lp[j]);
    let inf = f64::INFINITY;
    let mut cost = vec![vec![inf; n]; n];
    let mut split = vec![vec![usize::MAX; n]; n];
    for i in 0..n - 1 {
        cost[i][i + 1] = 0.0;
    }
    for gap in 2..n {
        for i in 0..n - gap {
            let j = i + gap;
            if !allowed(i, j) {
                continue;
            }
            let chord = if j - i == n - 1 { 0.0 } else { len(i, j) };
            for k in i + 1..j {
                let c = cost[i][k] + cost[k][j] + chord;
                if c < cost[i][j] {
                    cost[i][j] = c;
                    split[i][j] = k;
                }
            }
        }
    }
    if !cost[0][n - 1].is_finite() {
        return None;
    }
    let mut out = Vec::with_capacity(n - 2);
    collect_triangles(lp, &split, 0, n - 1, &mut out);
    Some(out)
}

fn collect_triangles(lp: &[u8], split: &[Vec<usize>], i: usize, j: usize, out: &mut Vec<[u8; 3]>) {
    if j <= i + 1 {
        return;
    }
    let k = split[i][j];
    out.push([lp[i], lp[k], lp[j]]);
    collect_triangles(lp, split, i, k, out);
    collect_triangles(lp, split, k, j, out);
}

/// Marching-squares cases: for each 4-bit configuration (corner `c = x + 2y`)
/// and saddle choice, the oriented segments as (from edge, to edge), edges
/// numbered 0: y=0, 1: x=1, 2: y=1, 3: x=0 (counter-clockwise). Segments
/// keep values below iso on their left, so closed curves run
/// counter-clockwise around low regions.
pub fn square_segments(config: u8, connect_positive: bool) -> ([(u8, u8); 2], usize) {
    // Corners counter-clockwise: (0,0),(1,0),(1,1),(0,1) = bits 0,1,3,2.
    const CCW: [u8; 4] = [0, 1, 3, 2];
    let positive = |i: usize| (config >> CCW[i % 4]) & 1 == 1;
    let crossings: Vec<(u8, bool)> = (0..4)
        .filter(|&i| positive(i) != positive(i + 1))
        .map(|i| (i as u8, positive(i + 1)))
        .collect();
    let mut out = [(0, 0); 2];
    let mut count = 0;
    let n = crossings.len();
    for i in 0..n {
        let (edge, entering) = crossings[i];
        if !entering {
            continue;
        }
        // A low region on the left: from the entry of a positive run to its
        // exit (separated) or to the previous exit (connected runs).
        let exit = if connect_positive {
            crossings[(i + n - 1) % n].0
        } else {
            crossings[(i + 1) % n].0
        };
        out[count] = (edge, exit);
        count += 1;
    }
    (out, count)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edges_and_faces_are_consistent() {
        for (e, [a, b]) in EDGE_CORNERS.iter().enumerate() {
            assert_eq!((a ^ b).count_ones(), 1);
            assert_eq!(edge_between(*a, *b) as usize, e);
        }
        for corners in FACE_CORNERS {
            for i in 0..4 {
                assert_eq!((corners[i] ^ corners[(i + 1) % 4]).count_ones(), 1);
            }
        }
    }

    #[test]
    fn every_case_is_closed_and_each_crossing_used() {
        let t = cube_table();
        for config in 0..=255u8 {
            let amb = t.ambiguous_faces[config as usize];
            for bits in (0..64u8).filter(|b| b & !amb == 0) {
                let tris = t.triangles(config, bits);
                // Every sign-changing edge appears; boundary edges of the
                // patch (each face segment) appear once in each direction
                // across the two cubes, so within a cube each segment once.
                for e in 0..12u8 {
                    let [a, b] = EDGE_CORNERS[e as usize];
                    let crosses = ((config >> a) ^ (config >> b)) & 1 == 1;
                    let used = tris.iter().any(|t| t.contains(&e));
                    assert!(tris
                        .iter()
                        .flatten()
                        .all(|&x| x < 12 + MAX_LOOP_CENTRES as u8));
                    assert_eq!(crosses, used, "config {config} edge {e}");
                }
            }
        }
        let most = (0..256 * 64).map(|k| t.centres[k].len()).max().unwrap();
        assert!(most <= MAX_LOOP_CENTRES, "{most} centres");
        assert!(cube_table().triangles(0, 0).is_empty());
        assert!(cube_table().triangles(255, 0).is_empty());
        assert_eq!(cube_table().triangles(1, 0).len(), 1);
    }
}
