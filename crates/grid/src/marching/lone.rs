//! Lone nodes: the one sign configuration marching cubes always turns into
//! a separate speck.

use super::cubes::positive_corners_joined;
use crate::sparse::BlockGrid;

/// Give every lone node of `grid` the side of its neighbours; returns how
/// many changed.
///
/// A node is lone when its six face neighbours all lie on the other side
/// of `iso` and no ambiguous face joins it to a diagonal neighbour on its
/// own side: marching cubes then cuts it off in each of its eight cells,
/// and it becomes a closed octahedron of its own, a piece smaller than a
/// cell that holds nothing (a one-node bubble inside a body, or a crumb
/// outside). Such a node takes the mean of its six neighbours, so no other
/// cell's triangles change. Nodes are settled one at a time in block
/// order, each checked again just before, so two adjacent lone nodes do
/// not swap sides.
pub fn settle_lone_nodes(grid: &mut BlockGrid<3>, iso: f64) -> usize {
    let candidates: Vec<[usize; 3]> = grid
        .iter_nodes()
        .map(|(idx, _)| idx)
        .filter(|&idx| neighbours_mean_if_lone(grid, idx, iso).is_some())
        .collect();
    let mut settled = 0;
    for idx in candidates {
        if let Some(mean) = neighbours_mean_if_lone(grid, idx, iso) {
            grid.set(idx, mean);
            settled += 1;
        }
    }
    settled
}

/// The mean of the six face neighbours of `idx` if it is lone (see
/// [`settle_lone_nodes`]); nodes on the grid's border never are.
fn neighbours_mean_if_lone(grid: &BlockGrid<3>, idx: [usize; 3], iso: f64) -> Option<f64> {
    let dims = grid.spec().dims;
    if (0..3).any(|a| idx[a] == 0 || idx[a] + 1 >= dims[a]) {
        return None;
    }
    let value = grid.get(idx);
    let positive = value >= iso;
    let at = |offset: [isize; 3]| {
        grid.get(std::array::from_fn(|a| {
            idx[a].wrapping_add_signed(offset[a])
        }))
    };
    let step = |axis: usize, sign: isize| -> [isize; 3] {
        std::array::from_fn(|a| if a == axis { sign } else { 0 })
    };
    let mut sum = 0.0;
    for axis in 0..3 {
        for sign in [-1, 1] {
            let v = at(step(axis, sign));
            if (v >= iso) == positive {
                return None;
            }
            sum += v;
        }
    }
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        for (sa, sb) in [(-1, -1), (-1, 1), (1, -1), (1, 1)] {
            let across = step(a, sa);
            let beside = step(b, sb);
            let diagonal = std::array::from_fn(|k| across[k] + beside[k]);
            // The face's corners in cyclic order: this node, a neighbour,
            // the diagonal, the other neighbour.
            let face = [value, at(across), at(diagonal), at(beside)].map(|v| v - iso);
            let diagonal_on_own_side = (face[2] >= 0.0) == positive;
            if diagonal_on_own_side && positive_corners_joined(face) == positive {
                return None;
            }
        }
    }
    Some(sum / 6.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::marching::tests::cube_spec;
    use crate::Field3;

    /// A 9³ grid outside (+1) everywhere but at the given nodes.
    fn grid_with_inside(inside: &[([usize; 3], f64)]) -> BlockGrid<3> {
        let mut field = Field3::filled(cube_spec(9, 0.0, 8.0), 1.0);
        for &(idx, v) in inside {
            field.set(idx, v);
        }
        BlockGrid::from_dense_band(&field, 10.0).unwrap()
    }

    #[test]
    fn a_single_inside_node_is_settled_and_the_mesh_loses_its_speck() {
        let mut grid = grid_with_inside(&[([4, 4, 4], -0.5)]);
        assert_eq!(
            crate::sparse::marching_cubes_sparse(&grid, 0.0)
                .triangles
                .len(),
            8
        );
        assert_eq!(settle_lone_nodes(&mut grid, 0.0), 1);
        assert!(grid.get([4, 4, 4]) >= 0.0);
        assert!(crate::sparse::marching_cubes_sparse(&grid, 0.0)
            .triangles
            .is_empty());
    }

    #[test]
    fn a_node_a_face_joins_to_its_diagonal_is_not_lone() {
        // Two inside nodes diagonal on a face, deep enough that the
        // asymptotic decider joins them through the face: one piece, kept.
        let inside = [([4, 4, 4], -2.0), ([5, 5, 4], -2.0)];
        let mut grid = grid_with_inside(&inside);
        assert_eq!(settle_lone_nodes(&mut grid, 0.0), 0);
        // Shallow ones the decider separates: two specks, both settled.
        let inside = [([4, 4, 4], -0.5), ([5, 5, 4], -0.5)];
        let mut grid = grid_with_inside(&inside);
        assert_eq!(settle_lone_nodes(&mut grid, 0.0), 2);
    }

    #[test]
    fn a_one_node_bubble_inside_a_body_is_filled() {
        let mut field = Field3::filled(cube_spec(9, 0.0, 8.0), 1.0);
        for idx in (2..7).flat_map(|i| (2..7).flat_map(move |j| (2..7).map(move |k| [i, j, k]))) {
            field.set(idx, -1.0);
        }
        field.set([4, 4, 4], 0.25);
        let mut grid = BlockGrid::from_dense_band(&field, 10.0).unwrap();
        assert_eq!(settle_lone_nodes(&mut grid, 0.0), 1);
        assert_eq!(grid.get([4, 4, 4]), -1.0);
    }
}
