//! Sides of nodes of a closed, consistently oriented mesh by counting the
//! surface's crossings along grid rows.
//!
//! Along a line, the winding number of a closed oriented surface starts
//! at 0 far away and changes by ±1 where the line passes through a
//! triangle: +1 entering (the triangle's normal against the line), −1
//! leaving. So a node's winding number is the signed count of the
//! triangles its row (along +x) passes through before it — exact, where
//! the hierarchical winding number at a node next to the surface sums
//! hundreds of solid angles.
//!
//! A row passing exactly through an edge or a vertex of the projected
//! triangles is decided as if it were moved by an infinitesimal
//! (ε, ε²) in (y, z) (simulation of simplicity), and each edge's test is
//! computed from its endpoints in one fixed order, so the triangles
//! sharing the edge agree and the row passes through exactly one of them
//! (or, where the surface folds over in projection, through both or
//! neither, whose counts cancel).

use crate::GridSpec;
use rayon::prelude::*;

/// Whether every edge of `triangles` is used once in each direction: the
/// surface is closed and consistently oriented, so its winding number is
/// an integer and the crossing count is exact. Triangles collapsed onto
/// an edge or a point (a repeated vertex) cover nothing and are left out.
pub(super) fn closed_and_oriented(triangles: &[[u32; 3]]) -> bool {
    let mut edges: Vec<(u32, u32)> = triangles
        .iter()
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[2] != t[0])
        .flat_map(|t| (0..3).map(move |k| (t[k], t[(k + 1) % 3])))
        .collect();
    edges.par_sort_unstable();
    let directed_once = edges.windows(2).all(|w| w[0] != w[1]);
    directed_once
        && edges
            .par_iter()
            .all(|&(a, b)| a != b && edges.binary_search(&(b, a)).is_ok())
}

/// Inside (winding number at least 1) for each node of `nodes`
/// (ascending), by the signed crossings of the rows through them.
pub(super) fn row_sides(
    spec: &GridSpec<3>,
    triangles: &[[[f64; 3]; 3]],
    nodes: &[u32],
) -> Vec<bool> {
    let [nx, ny, nz] = spec.dims;
    // Rows (y + ny z) holding nodes to decide, and where their nodes start.
    let mut rows: Vec<(usize, usize)> = Vec::new();
    for (k, &l) in nodes.iter().enumerate() {
        let row = l as usize / nx;
        if rows.last().is_none_or(|r| r.0 != row) {
            rows.push((row, k));
        }
    }
    let mut wanted = vec![u32::MAX; ny * nz];
    for (r, &(row, _)) in rows.iter().enumerate() {
        wanted[row] = r as u32;
    }
    // Triangles by the wanted rows their (y, z) box may meet (a row more
    // on each side: rounding of node positions), in triangle order.
    let mut by_row: Vec<Vec<u32>> = vec![Vec::new(); rows.len()];
    let range = |lo: f64, hi: f64, a: usize, n: usize| {
        let g = |v: f64| (v - spec.origin[a]) / spec.spacing;
        let first = (g(lo).floor() - 1.0).max(0.0);
        let end = (g(hi).ceil() + 2.0).min(n as f64).max(first);
        first as usize..end as usize
    };
    for (t, tri) in triangles.iter().enumerate() {
        let (ylo, yhi) = extent(tri, 1);
        let (zlo, zhi) = extent(tri, 2);
        for k in range(zlo, zhi, 2, nz) {
            for j in range(ylo, yhi, 1, ny) {
                let r = wanted[j + ny * k];
                if r != u32::MAX {
                    by_row[r as usize].push(t as u32);
                }
            }
        }
    }
    let ends: Vec<usize> = rows
        .iter()
        .skip(1)
        .map(|r| r.1)
        .chain([nodes.len()])
        .collect();
    rows.par_iter()
        .zip(&ends)
        .zip(&by_row)
        .flat_map_iter(|((&(row, start), &end), tris)| {
            let (j, k) = (row % ny, row / ny);
            let p = spec.position([0, j, k]);
            let mut crossings: Vec<(f64, i32)> = tris
                .iter()
                .filter_map(|&t| crossing(&triangles[t as usize], p[1], p[2]))
                .collect();
            crossings.sort_by(|a, b| a.0.total_cmp(&b.0));
            nodes[start..end].iter().map(move |&l| {
                let x = spec.position([l as usize % nx, j, k])[0];
                let winding: i32 = crossings.iter().take_while(|c| c.0 < x).map(|c| c.1).sum();
                winding > 0
            })
        })
        .collect()
}

fn extent(tri: &[[f64; 3]; 3], axis: usize) -> (f64, f64) {
    let v = tri.map(|p| p[axis]);
    (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]))
}

/// Where the line through (·, y, z) along +x passes through `tri`: its
/// x and +1 entering (the triangle faces −x), −1 leaving; `None` if it
/// misses (ties decided as the module docs say).
fn crossing(tri: &[[f64; 3]; 3], y: f64, z: f64) -> Option<(f64, i32)> {
    let e: [(f64, bool); 3] = std::array::from_fn(|i| edge_side(tri[i], tri[(i + 1) % 3], y, z));
    let positive = e.iter().all(|v| v.1);
    if !(positive || e.iter().all(|v| !v.1)) {
        return None;
    }
    // Barycentric weights: each edge's value belongs to the vertex
    // opposite it.
    let sum = e[0].0 + e[1].0 + e[2].0;
    if sum == 0.0 {
        return None; // rounding of a triangle flat in (y, z)
    }
    let x = (e[1].0 * tri[0][0] + e[2].0 * tri[1][0] + e[0].0 * tri[2][0]) / sum;
    // Counter-clockwise in (y, z) means the normal's x is positive:
    // leaving.
    Some((x, if positive { -1 } else { 1 }))
}

/// Which side of the projected edge `a` → `b` the point (y, z) lies on:
/// twice the signed area of (a, b, point) in the (y, z) plane, and
/// whether the point lies to the left (where the area is 0, as if moved
/// by (ε, ε²): see the module docs). Computed with the endpoints in a
/// fixed order, so both triangles of an edge see the same value.
fn edge_side(a: [f64; 3], b: [f64; 3], y: f64, z: f64) -> (f64, bool) {
    let swapped = (a[1], a[2]) > (b[1], b[2]);
    let (a, b) = if swapped { (b, a) } else { (a, b) };
    let (dy, dz) = (b[1] - a[1], b[2] - a[2]);
    let side = dy * (z - a[2]) - dz * (y - a[1]);
    let left = match side {
        0.0 if dz != 0.0 => dz < 0.0,
        0.0 => dy > 0.0,
        _ => side > 0.0,
    };
    if swapped {
        (-side, !left)
    } else {
        (side, left)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_row_through_a_shared_edge_crosses_one_of_its_triangles() {
        // A square split along its diagonal, facing −x; rows through the
        // diagonal, a corner and a side.
        let (a, b, c, d) = (
            [0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 1.0, 1.0],
            [0.0, 0.0, 1.0],
        );
        let square = [[a, c, b], [a, d, c]];
        for (y, z) in [(0.5, 0.5), (0.0, 0.0), (1.0, 1.0), (0.5, 0.0), (0.0, 0.25)] {
            let hits: Vec<_> = square.iter().filter_map(|t| crossing(t, y, z)).collect();
            assert!(hits.len() <= 1, "({y}, {z}): {hits:?}");
        }
        let inner: Vec<_> = square
            .iter()
            .filter_map(|t| crossing(t, 0.5, 0.5))
            .collect();
        assert_eq!(inner.len(), 1);
    }

    #[test]
    fn detects_open_and_flipped_meshes() {
        let tetra = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
        assert!(closed_and_oriented(&tetra));
        assert!(!closed_and_oriented(&tetra[..3]));
        let mut flipped = tetra;
        flipped[0] = [0, 1, 2];
        assert!(!closed_and_oriented(&flipped));
    }
}

#[cfg(test)]
mod torus_tests {
    use super::*;
    use surfrecon_geom::{shapes, DVec3};

    /// Every node of a grid whose rows pass through the vertices and
    /// edges of a torus (its vertices at angle 0 lie on y = 0) is on the
    /// side its winding number gives.
    #[test]
    fn rows_through_vertices_sign_like_winding_numbers() {
        let mesh = shapes::torus(1.0, 0.4, 40, 20);
        let tris: Vec<[[f64; 3]; 3]> = mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| mesh.vertices[i as usize].to_array()))
            .collect();
        let tree = crate::sdf::WindingTree::of_mesh(&mesh);
        let spec =
            GridSpec::from_bounds([-1.5; 3], [1.5; 3], crate::GridSize::Resolution(24), 0).unwrap();
        let nodes: Vec<u32> = (0..spec.node_count() as u32).collect();
        let sides = row_sides(&spec, &tris, &nodes);
        let wrong: Vec<[f64; 3]> = nodes
            .iter()
            .zip(&sides)
            .map(|(&l, &inside)| (spec.position(spec.unlinear(l as usize)), inside))
            .filter(|&(p, inside)| (tree.winding_number(DVec3::from_array(p)) > 0.5) != inside)
            .map(|(p, _)| p)
            .collect();
        assert!(wrong.is_empty(), "{wrong:?}");
        assert!(sides.iter().any(|&s| s));
    }
}
