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
    let oriented = stack.slices.iter().all(Input::is_oriented);
    let lean = if oriented { 1.0 + MAX_SLOPE } else { 1.0 };
    let alone = (lean * stack.gap()).max(NEAR_CELLS * h);
    let depths = depths(field, &pieces);
    let mut joins: Vec<Join> = (0..pieces.sizes.len() as u32)
        .filter(|&p| p != largest)
        .filter_map(|p| {
            let reach = if shown_by[p as usize] <= 1 {
                alone
            } else {
                NEAR_CELLS * h
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
        if join.distance > NEAR_CELLS * h {
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
