//! Parts of a stack the blend leaves as pieces of their own.
//!
//! The blend decides each node from the two slices around it, so a part
//! that only one slice shows (a cone's tip cut by one plane, its section
//! beside the next slice's body) or that a slice cuts lengthwise thinner
//! than a cell (a fin's rim, a cone's flank) can come out as a separate
//! piece beside the body, although the sections of one object make one
//! solid (the bench's sliced spikes: 4 pieces). Such a piece is joined to
//! the nearest other piece by a path of nodes set just inside (so marching
//! cubes keeps the join) when
//! - it lies within [`NEAR_CELLS`] cells of it (no grid tells such a gap
//!   from a thin neck), or
//! - at most one slice shows it (no two slices say it is a body of its
//!   own) and it lies within a slice gap of it, or with normals within
//!   `1 + MAX_SLOPE` gaps: the blend lets a part lean up to
//!   [`MAX_SLOPE`](super::MAX_SLOPE) gaps across per gap, so the root of a
//!   leaning tip (the sliced spikes' cone along y) can lie that far aside.
//!   Such a join is also given the piece's own thickness: a round tube
//!   (the data say no more about the part between the slices).
//!
//! A piece that two or more slices show stays apart unless it nearly
//! touches: it is a body of its own (two bones of one scan).

use super::{SliceStack, MAX_SLOPE};
use crate::reconstruct::Input;
use surfrecon_geom::disjoint_sets::DisjointSets;
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::DVec3;
use surfrecon_grid::pieces::{inside_pieces, node_path, InsidePieces};
use surfrecon_grid::Field;

/// Pieces this many cells apart or nearer are always joined.
const NEAR_CELLS: f64 = 2.0;
/// Depth (in cells) of the nodes of a join's path that were outside.
const JOIN_DEPTH: f64 = 0.25;

/// The shortest join found for one piece.
#[derive(Clone, Copy, Debug)]
struct Join {
    distance: f64,
    from: (u32, usize),
    to: (u32, usize),
}

/// Join the pieces of `field`'s inside (interpolated over `stack`) that
/// belong to the body (see the module doc). Returns how many joins were
/// made.
pub(crate) fn join_lost_parts(field: &mut Field<3>, stack: &SliceStack) -> usize {
    let pieces = inside_pieces(field, 0.0);
    let Some(largest) = pieces.largest() else {
        return 0;
    };
    if pieces.sizes.len() == 1 {
        return 0;
    }
    let boundary = boundary_nodes(field, &pieces);
    let positions: Vec<DVec3> = boundary.iter().map(|&l| position(field, l)).collect();
    let tree = KdTree::new(&positions);
    let mut by_piece = vec![Vec::new(); pieces.sizes.len()];
    for (i, &l) in boundary.iter().enumerate() {
        by_piece[pieces.labels[l] as usize].push(i);
    }
    let shown_by = slices_showing(field, &pieces, &stack.levels, stack.axis);
    let h = field.spec.spacing;
    // Node distances come in exact multiples of h; rounding must not
    // decide.
    let near = NEAR_CELLS * h * (1.0 + 1e-9);
    let oriented = stack.slices.iter().all(Input::is_oriented);
    let lean = if oriented { 1.0 + MAX_SLOPE } else { 1.0 };
    let alone = (lean * stack.gap()).max(near);
    let depths = depths(field, &pieces);
    let mut joins: Vec<Join> = (0..pieces.sizes.len() as u32)
        .filter(|&p| p != largest)
        .filter_map(|p| {
            let reach = if shown_by[p as usize] <= 1 {
                alone
            } else {
                near
            };
            nearest_other_piece(
                &pieces,
                &boundary,
                &positions,
                &tree,
                &by_piece[p as usize],
                reach,
            )
        })
        .collect();
    joins.sort_by(|a, b| a.distance.total_cmp(&b.distance));
    let mut joined = DisjointSets::new(pieces.sizes.len());
    let mut made = 0;
    for join in joins {
        let (a, b) = (join.from.0 as usize, join.to.0 as usize);
        if joined.find(a) == joined.find(b) {
            continue;
        }
        joined.union(a, b);
        set_path_inside(field, join.from.1, join.to.1, JOIN_DEPTH * h);
        if join.distance > near {
            let radius = depths[a].min(depths[b]);
            add_tube(
                field,
                position(field, join.from.1),
                position(field, join.to.1),
                radius,
            );
        }
        made += 1;
    }
    made
}

/// Linear indices of the inside nodes with an outside face neighbour: a
/// piece's nearest node to another piece is one of them.
fn boundary_nodes(field: &Field<3>, pieces: &InsidePieces) -> Vec<usize> {
    let spec = &field.spec;
    let strides = spec.strides();
    (0..spec.node_count())
        .filter(|&l| {
            pieces.labels[l] != InsidePieces::OUTSIDE && {
                let idx = spec.unlinear(l);
                let outside = spec
                    .axis_neighbours(l, &idx, &strides)
                    .any(|m| pieces.labels[m] == InsidePieces::OUTSIDE);
                outside
            }
        })
        .collect()
}

/// The deepest inside value of each piece (-φ at its deepest node).
fn depths(field: &Field<3>, pieces: &InsidePieces) -> Vec<f64> {
    let mut depth = vec![0.0f64; pieces.sizes.len()];
    for (&p, &v) in pieces.labels.iter().zip(&field.values) {
        if p != InsidePieces::OUTSIDE {
            depth[p as usize] = depth[p as usize].max(-v);
        }
    }
    depth
}

fn position(field: &Field<3>, l: usize) -> DVec3 {
    DVec3::from_array(field.spec.position(field.spec.unlinear(l)))
}

/// For each piece, how many slice planes pass through its extent along
/// `axis` (widened by half a cell: a section's own nodes lie around it).
fn slices_showing(
    field: &Field<3>,
    pieces: &InsidePieces,
    levels: &[f64],
    axis: usize,
) -> Vec<usize> {
    let spec = &field.spec;
    let mut extent = vec![(usize::MAX, 0usize); pieces.sizes.len()];
    for (l, &p) in pieces.labels.iter().enumerate() {
        if p != InsidePieces::OUTSIDE {
            let k = spec.unlinear(l)[axis];
            let e = &mut extent[p as usize];
            *e = (e.0.min(k), e.1.max(k));
        }
    }
    let coordinate = |k: usize| spec.origin[axis] + k as f64 * spec.spacing;
    extent
        .iter()
        .map(|&(lo, hi)| {
            let (lo, hi) = (
                coordinate(lo) - 0.5 * spec.spacing,
                coordinate(hi) + 0.5 * spec.spacing,
            );
            levels.iter().filter(|&&s| s >= lo && s <= hi).count()
        })
        .collect()
}

/// The shortest segment within `reach` from one of a piece's boundary
/// nodes (`own`, indices into `boundary`) to one of another piece.
fn nearest_other_piece(
    pieces: &InsidePieces,
    boundary: &[usize],
    positions: &[DVec3],
    tree: &KdTree,
    own: &[usize],
    reach: f64,
) -> Option<Join> {
    let label = |i: usize| pieces.labels[boundary[i]];
    let piece = label(own[0]);
    own.iter()
        .filter_map(|&i| {
            tree.within(positions[i], reach)
                .into_iter()
                .filter(|n| label(n.index) != piece)
                .min_by(|a, b| a.distance.total_cmp(&b.distance))
                .map(|n| Join {
                    distance: n.distance,
                    from: (piece, boundary[i]),
                    to: (label(n.index), boundary[n.index]),
                })
        })
        .min_by(|a, b| a.distance.total_cmp(&b.distance))
}

/// Set the outside nodes on the path between nodes `a` and `b` (linear
/// indices) to `-depth`.
fn set_path_inside(field: &mut Field<3>, a: usize, b: usize, depth: f64) {
    let spec = field.spec;
    let node = |l: usize| spec.unlinear(l).map(|v| v as i64);
    for n in node_path(node(a), node(b)) {
        let l = spec.linear(n.map(|v| v as usize));
        if field.values[l] >= 0.0 {
            field.values[l] = -depth;
        }
    }
}

/// Make inside the round tube of `radius` around the segment `a`-`b`:
/// φ becomes the smaller of itself and the distance to the tube.
fn add_tube(field: &mut Field<3>, a: DVec3, b: DVec3, radius: f64) {
    let spec = field.spec;
    let reach = radius + spec.spacing;
    let corner = |p: DVec3, round: fn(f64) -> f64| -> [usize; 3] {
        let g = spec.to_grid(p.to_array());
        std::array::from_fn(|k| round(g[k]).clamp(0.0, (spec.dims[k] - 1) as f64) as usize)
    };
    let lo = corner(a.min(b) - DVec3::splat(reach), f64::floor);
    let hi = corner(a.max(b) + DVec3::splat(reach), f64::ceil);
    for z in lo[2]..=hi[2] {
        for y in lo[1]..=hi[1] {
            for x in lo[0]..=hi[0] {
                let l = spec.linear([x, y, z]);
                let p = DVec3::from_array(spec.position([x, y, z]));
                let along = (p - a).dot(b - a) / (b - a).length_squared().max(f64::MIN_POSITIVE);
                let off = p.distance(a.lerp(b, along.clamp(0.0, 1.0))) - radius;
                field.values[l] = field.values[l].min(off);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use surfrecon_geom::metrics::topology;
    use surfrecon_grid::marching::marching_cubes;
    use surfrecon_grid::GridSpec;

    /// Slices at z = -1, -0.7, ..., 1.1 (gap 0.3), one point each, with
    /// normals or not (only the planes and the orientation matter here).
    fn stack(oriented: bool) -> SliceStack {
        let levels: Vec<f64> = (0..8).map(|k| -1.0 + 0.3 * k as f64).collect();
        let slice = |_| Input {
            points: vec![DVec3::ZERO],
            normals: if oriented { vec![DVec3::Z] } else { vec![] },
            ..Input::default()
        };
        SliceStack {
            axis: 2,
            slices: levels.iter().map(slice).collect(),
            levels,
        }
    }

    /// The union of a unit ball at the origin and `others` (centre, radius)
    /// as a signed distance on a grid of spacing 0.05.
    fn balls(others: &[(DVec3, f64)]) -> Field<3> {
        let spec = GridSpec::<3> {
            origin: [-2.0; 3],
            spacing: 0.05,
            dims: [81; 3],
        };
        let mut field = Field::filled(spec, f64::INFINITY);
        for l in 0..spec.node_count() {
            let p = DVec3::from_array(spec.position(spec.unlinear(l)));
            field.values[l] = others
                .iter()
                .fold(p.length() - 1.0, |v, &(c, r)| v.min(p.distance(c) - r));
        }
        field
    }

    fn pieces_after_joins(field: &mut Field<3>, stack: &SliceStack) -> (usize, usize) {
        let made = join_lost_parts(field, stack);
        let t = topology(&marching_cubes(field, 0.0));
        assert!(t.watertight && t.edge_manifold);
        (made, t.components)
    }

    #[test]
    fn a_tip_only_one_slice_shows_is_joined_by_a_tube_of_its_thickness() {
        // A ball of radius 0.06 on the slice z = 1.1, 0.5 (1.7 gaps) from
        // the body's surface: a leaning cone's tip.
        let tip = DVec3::new(0.9, 0.0, 1.1);
        let mut field = balls(&[(tip, 0.06)]);
        assert_eq!(pieces_after_joins(&mut field, &stack(true)), (1, 1));
        // The tube runs from the tip towards the body, no thicker than the
        // tip: halfway, inside within 0.06 (and a cell) of the axis only.
        let spec = field.spec;
        let towards = tip - tip.normalize();
        let halfway = tip - 0.5 * towards;
        let inside_off_axis = (0..spec.node_count())
            .filter(|&l| field.values[l] < 0.0)
            .map(|l| DVec3::from_array(spec.position(spec.unlinear(l))))
            .filter(|p| (*p - halfway).dot(towards.normalize()).abs() < 0.03)
            .map(|p| {
                let axis = towards.normalize();
                (p - halfway - (p - halfway).dot(axis) * axis).length()
            })
            .fold(0.0, f64::max);
        assert!(
            inside_off_axis > 0.0 && inside_off_axis < 0.06 + 0.05,
            "{inside_off_axis}"
        );
    }

    #[test]
    fn bodies_that_several_slices_show_or_far_tips_stay_apart() {
        // A second body across three slices, half a gap from the first.
        let mut field = balls(&[(DVec3::new(1.5, 0.0, 0.0), 0.35)]);
        assert_eq!(pieces_after_joins(&mut field, &stack(true)), (0, 2));
        // Without normals a lone tip joins only within one gap.
        let far_tip = [(DVec3::new(0.9, 0.0, 1.1), 0.06)];
        let mut field = balls(&far_tip);
        assert_eq!(pieces_after_joins(&mut field, &stack(false)), (0, 2));
        // A piece whose inside nodes lie two cells from the body's (0.95,
        // 1.05) is joined whatever shows it.
        let mut field = balls(&[(DVec3::new(1.38, 0.0, 0.0), 0.35)]);
        assert_eq!(pieces_after_joins(&mut field, &stack(true)), (1, 1));
    }
}
