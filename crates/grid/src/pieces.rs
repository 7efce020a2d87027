//! The inside of a dense field as separate pieces, and straight node paths
//! that join two of them.
//!
//! Marching cubes makes one surface per face-connected piece of inside
//! nodes (it may also join two pieces across an ambiguous face, never
//! split one), so a method that knows its pieces belong together can join
//! them on the grid before extraction.

use crate::{Field, GridSpec};

/// The face-connected pieces of the nodes below an iso value.
#[derive(Clone, Debug)]
pub struct InsidePieces {
    /// The piece of each node (linear index), or [`Self::OUTSIDE`].
    pub labels: Vec<u32>,
    /// Node count of each piece; pieces are numbered in the order of their
    /// first node.
    pub sizes: Vec<usize>,
}

impl InsidePieces {
    /// The label of nodes at or above the iso value.
    pub const OUTSIDE: u32 = u32::MAX;

    /// The piece with the most nodes (the first of equals), if any.
    pub fn largest(&self) -> Option<u32> {
        (0..self.sizes.len() as u32).max_by_key(|&p| (self.sizes[p as usize], std::cmp::Reverse(p)))
    }
}

/// Label the face-connected pieces of the nodes of `field` below `iso`.
pub fn inside_pieces<const D: usize>(field: &Field<D>, iso: f64) -> InsidePieces {
    let spec: &GridSpec<D> = &field.spec;
    let strides = spec.strides();
    let mut labels = vec![InsidePieces::OUTSIDE; spec.node_count()];
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    for seed in 0..labels.len() {
        if labels[seed] != InsidePieces::OUTSIDE || field.values[seed] >= iso {
            continue;
        }
        let piece = sizes.len() as u32;
        let mut size = 0;
        labels[seed] = piece;
        stack.push(seed);
        while let Some(l) = stack.pop() {
            size += 1;
            let idx = spec.unlinear(l);
            for m in spec.axis_neighbours(l, &idx, &strides) {
                if labels[m] == InsidePieces::OUTSIDE && field.values[m] < iso {
                    labels[m] = piece;
                    stack.push(m);
                }
            }
        }
        sizes.push(size);
    }
    InsidePieces { labels, sizes }
}

/// The nodes from `a` to `b`, each a face neighbour of the one before,
/// whose cells (the unit cubes centred on them) the straight segment
/// between them crosses, in order (where it crosses an edge or corner, the
/// lower axis steps first): setting them inside joins the pieces at
/// either end by a tube along the segment that marching cubes keeps.
pub fn node_path(a: [i64; 3], b: [i64; 3]) -> Vec<[i64; 3]> {
    let delta: [i64; 3] = std::array::from_fn(|k| b[k] - a[k]);
    // Steps taken along each axis; the segment leaves the current cell
    // along axis k at parameter (2 taken + 1) / (2 |delta|).
    let mut taken = [0i64; 3];
    let mut out = vec![a];
    let mut at = a;
    while at != b {
        let next = |k: usize| (2 * taken[k] + 1) as f64 / (2 * delta[k].abs()) as f64;
        let axis = (0..3)
            .filter(|&k| taken[k] < delta[k].abs())
            .min_by(|&i, &j| next(i).total_cmp(&next(j)))
            .unwrap_or(0);
        taken[axis] += 1;
        at[axis] += delta[axis].signum();
        out.push(at);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_are_face_connected_and_follow_the_segment() {
        for (a, b) in [
            ([0, 0, 0], [3, -2, 1]),
            ([5, 1, -4], [-7, 9, 2]),
            ([2, 2, 2], [2, 2, 2]),
        ] {
            let path = node_path(a, b);
            assert_eq!((path.first(), path.last()), (Some(&a), Some(&b)));
            let steps: i64 = (0..3).map(|k| (b[k] - a[k]).abs()).sum();
            assert_eq!(path.len() as i64, steps + 1);
            for w in path.windows(2) {
                let step: i64 = (0..3).map(|k| (w[1][k] - w[0][k]).abs()).sum();
                assert_eq!(step, 1);
            }
            // Every node's cell meets the segment: the node lies within
            // half a cell (max norm) of it.
            let (pa, pb) = (a.map(|v| v as f64), b.map(|v| v as f64));
            for n in &path {
                let off = (0..=1000)
                    .map(|i| {
                        let t = i as f64 / 1000.0;
                        (0..3)
                            .map(|k| (pa[k] + t * (pb[k] - pa[k]) - n[k] as f64).abs())
                            .fold(0.0, f64::max)
                    })
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    off <= 0.5 + 1e-3,
                    "{n:?} is {off} off the segment {a:?}-{b:?}"
                );
            }
        }
    }

    #[test]
    fn pieces_are_face_connected_runs_of_inside_nodes() {
        // Inside: a 2x2 block, a lone node touching it only diagonally,
        // and a row of three.
        let spec = GridSpec::<2> {
            origin: [0.0; 2],
            spacing: 1.0,
            dims: [6, 5],
        };
        let mut field = Field::<2>::filled(spec, 1.0);
        for idx in [
            [0, 0],
            [1, 0],
            [0, 1],
            [1, 1],
            [2, 2],
            [0, 4],
            [1, 4],
            [2, 4],
        ] {
            field.values[spec.linear(idx)] = -1.0;
        }
        let pieces = inside_pieces(&field, 0.0);
        assert_eq!(pieces.sizes, vec![4, 1, 3]);
        assert_eq!(pieces.largest(), Some(0));
        assert_eq!(pieces.labels[spec.linear([2, 2])], 1);
        assert_eq!(pieces.labels[spec.linear([3, 3])], InsidePieces::OUTSIDE);
    }
}
