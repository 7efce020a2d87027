//! Marching squares over a 2D field, segments chained into polylines.

use super::cubes::crossing_fraction;
use super::tables::square_segments;
use crate::Field2;
use surfrecon_geom::{DVec3, Polylines};

const NONE: u32 = u32::MAX;

/// Extract the `iso` level set of a 2D field as polylines (z = 0).
///
/// One vertex per sign-changing grid edge (a node is on the positive side
/// when its value is `>= iso`), placed by linear interpolation. Saddle cells
/// are resolved by the asymptotic decider. Curves keep values below `iso`
/// on their left, so a closed curve runs counter-clockwise around a low
/// region; closed curves repeat their first index at the end. Curves that
/// reach the grid boundary stay open there.
pub fn marching_squares(field: &Field2, iso: f64) -> Polylines {
    let [nx, ny] = field.spec.dims;
    if nx < 2 || ny < 2 || field.values.len() != field.spec.node_count() {
        return Polylines::default();
    }
    let (vertices, edge_ids) = edge_crossings(field, iso);
    let mut next = vec![NONE; vertices.len()];
    let mut has_prev = vec![false; vertices.len()];
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            for (a, b) in cell_segments(field, iso, &edge_ids, i, j) {
                next[a as usize] = b;
                has_prev[b as usize] = true;
            }
        }
    }
    Polylines {
        vertices,
        lines: chain(&next, &has_prev),
    }
}

/// Vertices on sign-changing edges and, per node, the ids of its +x and +y
/// edge crossings.
fn edge_crossings(field: &Field2, iso: f64) -> (Vec<DVec3>, Vec<[u32; 2]>) {
    let spec = &field.spec;
    let mut vertices = Vec::new();
    let mut ids = vec![[NONE; 2]; spec.node_count()];
    for (l, node_ids) in ids.iter_mut().enumerate() {
        let idx = spec.unlinear(l);
        for axis in 0..2 {
            if idx[axis] + 1 >= spec.dims[axis] {
                continue;
            }
            let mut hi = idx;
            hi[axis] += 1;
            let (a, b) = (field.values[l], field.get(hi));
            if (a >= iso) != (b >= iso) {
                let mut p = spec.position(idx);
                p[axis] += crossing_fraction(a, b, iso) * spec.spacing;
                node_ids[axis] = vertices.len() as u32;
                vertices.push(DVec3::new(p[0], p[1], 0.0));
            }
        }
    }
    (vertices, ids)
}

/// Oriented segments of cell (i, j) as vertex-id pairs.
fn cell_segments<'a>(
    field: &'a Field2,
    iso: f64,
    ids: &'a [[u32; 2]],
    i: usize,
    j: usize,
) -> impl Iterator<Item = (u32, u32)> + 'a {
    let spec = &field.spec;
    let v: [f64; 4] = std::array::from_fn(|c| field.get([i + (c & 1), j + (c >> 1)]));
    let config = (0..4).fold(0u8, |m, c| m | (((v[c] >= iso) as u8) << c));
    // Saddle: positive corners on one diagonal. Connected when the bilinear
    // saddle value is >= iso (product of the positive diagonal's offsets is
    // at least the negative one's).
    let d = v.map(|x| x - iso);
    let (diag_a, diag_b) = (d[0] * d[3], d[1] * d[2]);
    let connect = if d[0] >= 0.0 {
        diag_a >= diag_b
    } else {
        diag_b >= diag_a
    };
    let (segs, n) = square_segments(config, connect);
    // Square edges counter-clockwise: y=0, x=1, y=1, x=0.
    let edge_vertex = move |e: u8| match e {
        0 => ids[spec.linear([i, j])][0],
        1 => ids[spec.linear([i + 1, j])][1],
        2 => ids[spec.linear([i, j + 1])][0],
        _ => ids[spec.linear([i, j])][1],
    };
    segs.into_iter()
        .take(n)
        .map(move |(a, b)| (edge_vertex(a), edge_vertex(b)))
}

/// Follow `next` links into polylines: open chains first (starting where no
/// segment arrives, i.e. on the grid boundary), then closed loops, each in
/// order of its smallest starting vertex id.
fn chain(next: &[u32], has_prev: &[bool]) -> Vec<Vec<u32>> {
    let mut used = vec![false; next.len()];
    let mut lines = Vec::new();
    let follow = |start: usize, used: &mut Vec<bool>| {
        let mut line = vec![start as u32];
        used[start] = true;
        let mut v = next[start];
        while v != NONE {
            line.push(v);
            if used[v as usize] {
                break;
            }
            used[v as usize] = true;
            v = next[v as usize];
        }
        line
    };
    for s in 0..next.len() {
        if !has_prev[s] && next[s] != NONE {
            lines.push(follow(s, &mut used));
        }
    }
    for s in 0..next.len() {
        if !used[s] && next[s] != NONE {
            lines.push(follow(s, &mut used));
        }
    }
    lines
}
