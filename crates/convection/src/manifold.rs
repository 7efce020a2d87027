//! Turning the converged pseudo-surface into a manifold triangle mesh.
//!
//! The pseudo-surface is a combinatorial manifold, but its geometric image
//! can pinch: different parts meeting at one edge or one vertex. With the
//! vertices fixed to the input points such places cannot be written as a
//! manifold mesh, so [`make_manifold`] removes the faces there; the rims
//! they leave are boundary edges, of which [`fill_small_holes`] closes the
//! short loops by ear clipping through their own vertices.

use std::collections::{HashMap, HashSet};
use surfrecon_geom::DVec3;

fn directed_edges(&[a, b, c]: &[u32; 3]) -> [(u32, u32); 3] {
    [(a, b), (b, c), (c, a)]
}

/// How many faces run along each directed edge.
fn directed_counts(triangles: &[[u32; 3]]) -> HashMap<(u32, u32), u32> {
    let mut counts = HashMap::with_capacity(triangles.len() * 3);
    for t in triangles {
        for e in directed_edges(t) {
            *counts.entry(e).or_insert(0) += 1;
        }
    }
    counts
}

/// Remove faces until every edge has at most two faces running it in
/// opposite directions and the faces around every vertex form one fan (the
/// largest fan is kept). Returns the number of faces removed.
pub fn make_manifold(triangles: &mut Vec<[u32; 3]>) -> usize {
    let before = triangles.len();
    loop {
        let removed = remove_bad_edge_faces(triangles) + remove_extra_fans(triangles);
        if removed == 0 {
            return before - triangles.len();
        }
    }
}

fn remove_bad_edge_faces(triangles: &mut Vec<[u32; 3]>) -> usize {
    let counts = directed_counts(triangles);
    let uses = |a, b| counts.get(&(a, b)).copied().unwrap_or(0);
    let bad = |&(a, b): &(u32, u32)| uses(a, b) > 1 || uses(a, b) + uses(b, a) > 2;
    let before = triangles.len();
    triangles.retain(|t| !directed_edges(t).iter().any(bad));
    before - triangles.len()
}

/// Faces around each vertex in compressed rows.
fn vertex_faces(triangles: &[[u32; 3]]) -> (Vec<usize>, Vec<u32>) {
    let n = triangles
        .iter()
        .flatten()
        .max()
        .map_or(0, |&v| v as usize + 1);
    let mut offsets = vec![0usize; n + 1];
    for &v in triangles.iter().flatten() {
        offsets[v as usize + 1] += 1;
    }
    for i in 0..n {
        offsets[i + 1] += offsets[i];
    }
    let mut fill = offsets.clone();
    let mut faces = vec![0u32; offsets[n]];
    for (f, t) in triangles.iter().enumerate() {
        for &v in t {
            faces[fill[v as usize]] = f as u32;
            fill[v as usize] += 1;
        }
    }
    (offsets, faces)
}

fn remove_extra_fans(triangles: &mut Vec<[u32; 3]>) -> usize {
    let (offsets, faces) = vertex_faces(triangles);
    let mut doomed = vec![false; triangles.len()];
    for v in 0..offsets.len() - 1 {
        let around = &faces[offsets[v]..offsets[v + 1]];
        if around.len() > 1 {
            mark_minor_fans(v as u32, around, triangles, &mut doomed);
        }
    }
    let before = triangles.len();
    let mut index = 0;
    triangles.retain(|_| {
        index += 1;
        !doomed[index - 1]
    });
    before - triangles.len()
}

/// Group the faces at `v` into fans (joined through edges at `v`) and mark
/// all but the largest.
fn mark_minor_fans(v: u32, around: &[u32], triangles: &[[u32; 3]], doomed: &mut [bool]) {
    let mut group: Vec<usize> = (0..around.len()).collect();
    fn root(group: &mut [usize], mut i: usize) -> usize {
        while group[i] != i {
            group[i] = group[group[i]];
            i = group[i];
        }
        i
    }
    let mut first_at: HashMap<u32, usize> = HashMap::new();
    for (i, &f) in around.iter().enumerate() {
        for &w in triangles[f as usize].iter().filter(|&&w| w != v) {
            if let Some(&j) = first_at.get(&w) {
                let (a, b) = (root(&mut group, i), root(&mut group, j));
                group[a] = b;
            } else {
                first_at.insert(w, i);
            }
        }
    }
    let roots: Vec<usize> = (0..around.len()).map(|i| root(&mut group, i)).collect();
    let mut sizes: HashMap<usize, usize> = HashMap::new();
    for &r in &roots {
        *sizes.entry(r).or_insert(0) += 1;
    }
    if sizes.len() < 2 {
        return;
    }
    // Largest fan, ties to the smallest root so the result is reproducible.
    let keep = sizes
        .iter()
        .max_by_key(|(&r, &s)| (s, std::cmp::Reverse(r)))
        .map(|(&r, _)| r);
    for (i, &f) in around.iter().enumerate() {
        if Some(roots[i]) != keep {
            doomed[f as usize] = true;
        }
    }
}

/// Edges with exactly one face.
pub fn boundary_edges(triangles: &[[u32; 3]]) -> usize {
    let counts = directed_counts(triangles);
    counts
        .keys()
        .filter(|&&(a, b)| !counts.contains_key(&(b, a)))
        .count()
}

/// Close every boundary loop of at most `max_edges` edges by ear clipping
/// (shortest new diagonal first, never an edge the mesh already has), so a
/// manifold mesh stays manifold. Returns the number of loops closed.
pub fn fill_small_holes(
    triangles: &mut Vec<[u32; 3]>,
    points: &[DVec3],
    max_edges: usize,
) -> usize {
    if max_edges < 3 {
        return 0;
    }
    let counts = directed_counts(triangles);
    let mut edges: HashSet<(u32, u32)> =
        counts.keys().map(|&(a, b)| (a.min(b), a.max(b))).collect();
    // A hole runs against its rim faces: rim edge a → b gives hole edge b → a.
    let mut next: HashMap<u32, u32> = HashMap::new();
    for &(a, b) in counts.keys() {
        if !counts.contains_key(&(b, a)) {
            next.insert(b, a);
        }
    }
    let mut starts: Vec<u32> = next.keys().copied().collect();
    starts.sort_unstable();
    let mut filled = 0;
    for start in starts {
        let Some(hole) = take_loop(&mut next, start, max_edges) else {
            continue;
        };
        if clip_ears(hole, points, &mut edges, triangles) {
            filled += 1;
        }
    }
    filled
}

/// The hole loop through `start` (removed from `next`), if it closes within
/// `max_edges` edges.
fn take_loop(next: &mut HashMap<u32, u32>, start: u32, max_edges: usize) -> Option<Vec<u32>> {
    let mut hole = vec![start];
    let mut v = *next.get(&start)?;
    while v != start {
        if hole.len() >= max_edges {
            return None;
        }
        hole.push(v);
        v = *next.get(&v)?;
    }
    for v in &hole {
        next.remove(v);
    }
    (hole.len() >= 3).then_some(hole)
}

/// Triangulate one hole; false if it had to stop early (no valid ear).
fn clip_ears(
    mut hole: Vec<u32>,
    points: &[DVec3],
    edges: &mut HashSet<(u32, u32)>,
    triangles: &mut Vec<[u32; 3]>,
) -> bool {
    while hole.len() > 3 {
        let n = hole.len();
        let ear = (0..n)
            .filter(|&i| {
                let (p, q) = (hole[(i + n - 1) % n], hole[(i + 1) % n]);
                !edges.contains(&(p.min(q), p.max(q)))
            })
            .min_by(|&i, &j| {
                let diagonal = |i: usize| {
                    points[hole[(i + n - 1) % n] as usize]
                        .distance(points[hole[(i + 1) % n] as usize])
                };
                diagonal(i).total_cmp(&diagonal(j))
            });
        let Some(i) = ear else {
            return false;
        };
        let (p, v, q) = (hole[(i + n - 1) % n], hole[i], hole[(i + 1) % n]);
        triangles.push([p, v, q]);
        edges.insert((p.min(q), p.max(q)));
        hole.remove(i);
    }
    triangles.push([hole[0], hole[1], hole[2]]);
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    fn octahedron() -> Vec<[u32; 3]> {
        // Vertices 0..6: ±x, ±y, ±z; outward faces.
        vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ]
    }

    fn octahedron_points() -> Vec<DVec3> {
        vec![
            DVec3::X,
            -DVec3::X,
            DVec3::Y,
            -DVec3::Y,
            DVec3::Z,
            -DVec3::Z,
        ]
    }

    #[test]
    fn closed_manifold_is_untouched() {
        let mut t = octahedron();
        assert_eq!(make_manifold(&mut t), 0);
        assert_eq!(t.len(), 8);
        assert_eq!(boundary_edges(&t), 0);
    }

    #[test]
    fn two_octahedra_sharing_a_vertex_keep_one_fan() {
        let mut t = octahedron();
        // A second octahedron with its vertex 0 glued to vertex 0.
        let shift = |v: u32| if v == 0 { 0 } else { v + 10 };
        t.extend(octahedron().iter().map(|f| f.map(shift)));
        let removed = make_manifold(&mut t);
        assert_eq!(removed, 4, "the minor fan at the pinch vertex goes");
        assert_eq!(boundary_edges(&t), 4);
    }

    #[test]
    fn fin_on_an_edge_is_removed() {
        let mut t = octahedron();
        // A fin along edge 0-2 makes it non-manifold (three faces).
        t.push([0, 2, 9]);
        make_manifold(&mut t);
        assert!(t.iter().all(|f| !f.contains(&9)));
        assert_eq!(boundary_edges(&t), 4, "both faces at the edge went too");
    }

    #[test]
    fn small_holes_are_closed_and_stay_manifold() {
        let mut t = octahedron();
        t.retain(|f| !f.contains(&4)); // remove the top cap: a 4-edge hole
        assert_eq!(boundary_edges(&t), 4);
        assert_eq!(fill_small_holes(&mut t, &octahedron_points(), 3), 0);
        assert_eq!(fill_small_holes(&mut t, &octahedron_points(), 4), 1);
        assert_eq!(boundary_edges(&t), 0);
        assert_eq!(t.len(), 6);
        assert_eq!(make_manifold(&mut t), 0);
    }
}
