//! Further feature points for sculpted cells (`.udf` version 2's side
//! table, [`UnifiedField::cell_points`]).
//!
//! The rules of [`super::sculpt_udf`] give a cell one feature point (two
//! where the repair adds a second). Where the tool's own sharp edge (a
//! cylinder's cap rim, a box's edge) crosses the object's surface, the
//! result has a corner that none of them offers: the new corners there
//! are where the *object's* edges pierce the tool. And an old edge's
//! point is dropped where its cell keeps a point on the new edge. Both
//! are offered here, after the repair, as further points of the cells
//! around them, kept where the surface of the block around the cell then
//! lies nearer the exact result. Last, where a cell holds several of the
//! result's corners, all of them and the samples' sides are offered
//! together ([`add_corner_sets`]).

use super::{bisect, result_features, result_points, Combined, Tool};
use crate::extract::{corner_nodes, crosses};
use crate::features::{cell_of, CellFeatures};
use crate::offset::node_position;
use crate::query::{lattice_points, MeshQuery};
use crate::unified::{farthest_from, local_surface, UnifiedField};
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use surfrecon_geom::{DVec3, TriMesh};

/// A sharp edge of a tool: a box's edge, or a cylinder's cap rim.
enum ToolEdge {
    Segment(DVec3, DVec3),
    Circle {
        centre: DVec3,
        u: DVec3,
        v: DVec3,
        radius: f64,
    },
}

impl ToolEdge {
    /// The point at parameter `t` in [0, 1] along the edge.
    fn at(&self, t: f64) -> DVec3 {
        match *self {
            ToolEdge::Segment(a, b) => a.lerp(b, t),
            ToolEdge::Circle {
                centre,
                u,
                v,
                radius,
            } => {
                let angle = std::f64::consts::TAU * t;
                centre + (u * angle.cos() + v * angle.sin()) * radius
            }
        }
    }

    /// The point of the edge nearest `p`.
    fn closest(&self, p: DVec3) -> DVec3 {
        match *self {
            ToolEdge::Segment(a, b) => crate::features::closest_on_segment(p, a, b),
            ToolEdge::Circle {
                centre,
                u,
                v,
                radius,
            } => {
                let (x, y) = ((p - centre).dot(u), (p - centre).dot(v));
                let angle = if x == 0.0 && y == 0.0 {
                    0.0
                } else {
                    y.atan2(x)
                };
                centre + (u * angle.cos() + v * angle.sin()) * radius
            }
        }
    }

    fn length(&self) -> f64 {
        match *self {
            ToolEdge::Segment(a, b) => a.distance(b),
            ToolEdge::Circle { radius, .. } => std::f64::consts::TAU * radius,
        }
    }

    /// Points along the edge at most `step` apart, as parameters.
    fn parameters(&self, step: f64) -> impl Iterator<Item = f64> {
        let n = (self.length() / step).ceil().max(1.0) as usize;
        (0..=n).map(move |k| k as f64 / n as f64)
    }
}

/// The tool's sharp edges (a sphere and a closed surface have none that
/// are known exactly).
fn tool_edges(tool: &Tool) -> Vec<ToolEdge> {
    match *tool {
        Tool::Box { min, max } => (0..3)
            .flat_map(|axis| {
                (0..4).map(move |k| {
                    let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
                    let mut from = min;
                    from[b] = if k & 1 == 0 { min[b] } else { max[b] };
                    from[c] = if k & 2 == 0 { min[c] } else { max[c] };
                    let mut to = from;
                    to[axis] = max[axis];
                    ToolEdge::Segment(from, to)
                })
            })
            .collect(),
        Tool::Cylinder { a, b, radius } => {
            let axis = (b - a).normalize();
            let u = axis.any_orthonormal_vector();
            let v = axis.cross(u);
            [a, b]
                .into_iter()
                .map(|centre| ToolEdge::Circle {
                    centre,
                    u,
                    v,
                    radius,
                })
                .collect()
        }
        Tool::Sphere { .. } | Tool::Surface(_) => Vec::new(),
    }
}

/// Steps (spacings) along a tool's edge when looking for where it crosses
/// the object.
const EDGE_STEP: f64 = 0.125;

/// Where the tool's sharp edges cross the object's surface (`object`):
/// corners of the result that [`super::new_corners`] (the object's edges
/// through the tool) does not find. A cylinder's rim passing under
/// fandisk's side face makes one.
pub(super) fn tool_corners(tool: &Tool, object: &MeshQuery, h: f64) -> Vec<DVec3> {
    let mut corners = Vec::new();
    for edge in tool_edges(tool) {
        let ts: Vec<f64> = edge.parameters(EDGE_STEP * h).collect();
        for pair in ts.windows(2) {
            let side = |t: f64| object.signed_distance(edge.at(t)) < 0.0;
            if side(pair[0]) != side(pair[1]) {
                corners.push(edge.at(bisect(pair[0], pair[1], side)));
            }
        }
    }
    corners
}

/// Points along the tool's sharp edges where they lie on the result, at
/// most `step` apart: the reference for the error around a rim.
fn tool_edge_points(combined: &Combined, h: f64) -> Vec<DVec3> {
    tool_edges(combined.tool)
        .iter()
        .flat_map(|edge| edge.parameters(EDGE_STEP * h).map(|t| edge.at(t)))
        .filter(|&p| combined.signed_distance(p).abs() < 1e-6 * h)
        .collect()
}

/// The stretches of the tool's sharp edges that lie on the result, as
/// segments at most [`EDGE_STEP`] spacings long (both ends on it): sharp
/// edges of the result as much as the new edge where tool and object
/// meet (a box's edges inside the object, a cylinder's rim).
pub(super) fn tool_edge_segments(combined: &Combined, h: f64) -> Vec<[DVec3; 2]> {
    let on_result = |p: DVec3| combined.signed_distance(p).abs() < 1e-6 * h;
    let mut segments = Vec::new();
    for edge in tool_edges(combined.tool) {
        let points: Vec<DVec3> = edge.parameters(EDGE_STEP * h).map(|t| edge.at(t)).collect();
        for pair in points.windows(2) {
            if on_result(pair[0]) && on_result(pair[1]) {
                segments.push([pair[0], pair[1]]);
            }
        }
    }
    segments
}

/// How far (spacings) outside a cell's box a point may lie to be offered
/// to it: the corner where fandisk − cylinder's rim passes under the side
/// face lies 0.015 h below the cell whose sheet it bounds.
const OFFER_MARGIN: f64 = 0.25;

/// Steps (spacings) along a tool's edge when looking for its stretch
/// through a cell (a rim may clip a cell's corner over 0.15 h).
const STRETCH_STEP: f64 = 1.0 / 32.0;

/// How far (spacings) outside a cell's box the edge's stretch through it
/// is followed.
const STRETCH_MARGIN: f64 = 0.02;

/// A point already kept by a cell within this many spacings is not
/// offered again.
const SAME_POINT: f64 = 0.05;

/// A further point must lower the block's summed excess by this part of
/// it ...
const EXCESS_GAIN: f64 = 0.1;

/// ... and may raise neither way's largest error by more than this many
/// spacings.
const FURTHER_SLACK: f64 = 0.001;

/// The error of the surface around a cell against the exact result, each
/// way: the largest distance of the surface's points (within a cell of
/// the cell) from the result, and of the result's points (`reference`,
/// within a cell of the cell) from the surface.
#[derive(Debug, Clone, Copy)]
struct LocalError {
    out: f64,
    back: f64,
    /// The summed excess over [`EXCESS_FLOOR`] of all those distances:
    /// a further point may lower one place while the block's largest
    /// error, at another, stays.
    excess: f64,
}

/// Distances (spacings) below this count nothing in [`LocalError`]'s
/// excess.
const EXCESS_FLOOR: f64 = 0.1;

/// Cells (per axis) from a cell whose crop [`local_error`] extracts: a
/// point kept in one changes the error measured around the others.
const CROP_REACH: usize = 4;

/// Lattice points per triangle side for the surface's points.
const SURFACE_LATTICE: usize = 4;

/// [`LocalError`] of the surface extracted from a crop of 8³ samples
/// around `cell` (so fans, merges and flips count), or `None` if the cell
/// lies less than 3 cells inside the grid.
fn local_error(
    field: &UnifiedField,
    combined: &Combined,
    cell: usize,
    reference: &[DVec3],
) -> Option<LocalError> {
    let spec = &field.spec;
    let h = spec.spacing;
    let idx = spec.unlinear(cell);
    if (0..3).any(|a| idx[a] < 3 || idx[a] + 5 > spec.dims[a]) {
        return None;
    }
    let lo = node_position(spec, cell) - DVec3::splat(h);
    let hi = lo + DVec3::splat(3.0 * h);
    let near = |p: DVec3| p.cmpge(lo).all() && p.cmple(hi).all();
    let triangles = local_surface(field, idx.map(|i| i - 3), 8);
    let out: Vec<f64> = (triangles.iter())
        .filter(|&&[a, b, c]| near((a + b + c) / 3.0))
        .flat_map(|&t| lattice_points(t, SURFACE_LATTICE))
        .map(|p| combined.signed_distance(p).abs() / h)
        .collect();
    let back: Vec<f64> = (reference.iter())
        .filter(|&&p| near(p))
        .map(|&p| farthest_from(&triangles, &[p]) / h)
        .collect();
    let largest = |d: &[f64]| d.iter().copied().fold(0.0, f64::max);
    let excess = (out.iter().chain(&back))
        .map(|d| (d - EXCESS_FLOOR).max(0.0))
        .sum();
    Some(LocalError {
        out: largest(&out),
        back: largest(&back),
        excess,
    })
}

/// How much `after` is better than `before`: the summed excess's drop,
/// where no largest error rises by more than [`FURTHER_SLACK`] and the
/// excess drops by [`EXCESS_GAIN`] of itself.
fn gain(before: LocalError, after: LocalError) -> Option<f64> {
    let loss = (after.out - before.out).max(after.back - before.back);
    let drop = before.excess - after.excess;
    (loss <= FURTHER_SLACK && drop >= EXCESS_GAIN * before.excess && drop > 0.0).then_some(drop)
}

/// The crossed cells whose box grown by [`OFFER_MARGIN`] holds `p`.
fn cells_near(field: &UnifiedField, p: DVec3) -> Vec<usize> {
    cells_within(field, p, OFFER_MARGIN * field.spec.spacing)
}

/// The crossed cells whose box grown by `margin` holds `p`.
fn cells_within(field: &UnifiedField, p: DVec3, margin: f64) -> Vec<usize> {
    let spec = &field.spec;
    let mut cells: BTreeSet<usize> = BTreeSet::new();
    for k in 0..8 {
        let corner = DVec3::new(
            if k & 1 == 0 { -margin } else { margin },
            if k & 2 == 0 { -margin } else { margin },
            if k & 4 == 0 { -margin } else { margin },
        );
        cells.extend(cell_of(spec, p + corner));
    }
    cells
        .into_iter()
        .filter(|&c| crosses(spec, &field.values, c))
        .collect()
}

/// The points `cell` keeps: its first, second and further points.
fn kept_points(field: &UnifiedField, cell: usize) -> Vec<DVec3> {
    let spec = &field.spec;
    let owned =
        corner_nodes(spec, cell)
            .into_iter()
            .filter_map(|n| match field.extras.get(&(n as u32)) {
                Some(&crate::unified::Extra::FeaturePoint(p))
                    if crate::sharp::owner_cell(spec, n, p) == Some(cell) =>
                {
                    Some(p)
                }
                _ => None,
            });
    let further = field.cell_points.get(&(cell as u32)).into_iter().flatten();
    owned.chain(further.copied()).collect()
}

/// What may become further points, in order: groups of (cell, point)
/// alternatives of which at most one is kept. The corners where the
/// tool's edges cross the object, offered to the crossed cells around
/// each; per crossed cell along a tool's edge where the result keeps it
/// (a rim under a thin roof, whose cell's point keeps the roof's edge),
/// the edge's point nearest the cell's centre; then `displaced`, old
/// edges' points whose cells took a point on the new edge.
pub(super) fn offers(
    field: &UnifiedField,
    combined: &Combined,
    corners: &[DVec3],
    displaced: &[DVec3],
) -> Vec<Vec<(usize, DVec3)>> {
    let spec = &field.spec;
    let h = spec.spacing;
    let around = |p: DVec3| {
        cells_near(field, p)
            .into_iter()
            .map(move |c| (c, p))
            .collect()
    };
    let mut groups: Vec<Vec<(usize, DVec3)>> = corners.iter().map(|&p| around(p)).collect();
    for edge in tool_edges(combined.tool) {
        // The edge's stretch through each crossed cell, in order along it.
        let mut stretches: BTreeMap<usize, Vec<DVec3>> = BTreeMap::new();
        let mut order = Vec::new();
        for t in edge.parameters(STRETCH_STEP * h) {
            let p = edge.at(t);
            if combined.signed_distance(p).abs() >= 1e-6 * h {
                continue;
            }
            for c in cells_within(field, p, STRETCH_MARGIN * h) {
                let stretch = stretches.entry(c).or_default();
                if stretch.is_empty() {
                    order.push(c);
                }
                stretch.push(p);
            }
        }
        for c in order {
            let stretch = &stretches[&c];
            let middle = stretch[stretch.len() / 2];
            let centre = node_position(spec, c) + DVec3::splat(0.5 * h);
            let nearest = edge.closest(centre);
            let mut group = vec![(c, middle)];
            let in_reach = (nearest - centre).abs().max_element() <= (0.5 + OFFER_MARGIN) * h;
            if in_reach
                && nearest.distance(middle) > SAME_POINT * h
                && combined.signed_distance(nearest).abs() < 1e-6 * h
            {
                group.push((c, nearest));
            }
            groups.push(group);
        }
    }
    groups.extend(displaced.iter().map(|&p| around(p)));
    groups
}

/// Offers each group of [`offers`] (in order), keeping at most one of its
/// (cell, point) alternatives as a further point of its cell: the one
/// whose block's error drops most (see [`gain`]). Points a cell
/// already keeps (within [`SAME_POINT`]) are not offered again. Returns
/// the number kept.
pub(super) fn add_further_points(
    field: &mut UnifiedField,
    combined: &Combined,
    surface: &TriMesh,
    groups: &[Vec<(usize, DVec3)>],
    old_features: &BTreeMap<usize, CellFeatures>,
    corners: &[DVec3],
) -> usize {
    let spec = field.spec;
    let h = spec.spacing;
    let mut kept = 0;
    // Each cell's error before an offer, until a point kept nearby.
    let mut errors: HashMap<usize, Option<LocalError>> = HashMap::new();
    let region: BTreeSet<usize> = (groups.iter().flatten())
        .flat_map(|&(c, _)| crate::refine::block(&spec, c, 1))
        .collect();
    let mut reference = result_points(&spec, combined, surface, &region);
    reference.par_extend(
        region
            .par_iter()
            .flat_map_iter(|&c| result_features(&spec, combined, c, old_features.get(&c), corners)),
    );
    reference.extend(tool_edge_points(combined, h));
    for group in groups {
        let group: Vec<(usize, DVec3)> = (group.iter().copied())
            .filter(|&(c, p)| {
                (kept_points(field, c).iter()).all(|q| q.distance(p) > SAME_POINT * h)
            })
            .collect();
        if group.is_empty() {
            continue;
        }
        let mut best: Option<(f64, usize, DVec3)> = None;
        for &(c, p) in &group {
            let measured = *errors
                .entry(c)
                .or_insert_with(|| local_error(field, combined, c, &reference));
            let Some(before) = measured else {
                continue;
            };
            let key = c as u32;
            field.cell_points.entry(key).or_default().push(p);
            let after = local_error(field, combined, c, &reference);
            remove_last(field, key);
            if let Some(gain) = after.and_then(|a| gain(before, a)) {
                if best.is_none_or(|(g, _, _)| gain > g) {
                    best = Some((gain, c, p));
                }
            }
        }
        if let Some((_, c, p)) = best {
            field.cell_points.entry(c as u32).or_default().push(p);
            kept += 1;
            // The errors measured on crops that hold the cell are stale.
            let at = spec.unlinear(c);
            errors.retain(|&d, _| {
                let other = spec.unlinear(d);
                (0..3).any(|a| at[a].abs_diff(other[a]) > CROP_REACH)
            });
        }
    }
    kept
}

/// Undo the last push onto `cell`'s further points.
fn remove_last(field: &mut UnifiedField, cell: u32) {
    if let Some(points) = field.cell_points.get_mut(&cell) {
        points.pop();
        if points.is_empty() {
            field.cell_points.remove(&cell);
        }
    }
}

/// The result's corners in each crossed cell's box: old corners the tool
/// left, and `corners` (where old edges pierce the tool, where its own
/// edges cross the object), each once.
fn corners_by_cell(
    field: &UnifiedField,
    combined: &Combined,
    old_features: &BTreeMap<usize, CellFeatures>,
    corners: &[DVec3],
) -> BTreeMap<usize, Vec<DVec3>> {
    let spec = &field.spec;
    let h = spec.spacing;
    let old = (old_features.values())
        .flat_map(|f| f.corners.iter().copied())
        .filter(|&p| !combined.changes(p, 1e-6 * h));
    let mut by_cell: BTreeMap<usize, Vec<DVec3>> = BTreeMap::new();
    for p in corners.iter().copied().chain(old) {
        let Some(c) = cell_of(spec, p).filter(|&c| crosses(spec, &field.values, c)) else {
            continue;
        };
        let points = by_cell.entry(c).or_default();
        if points.iter().all(|q| q.distance(p) > SAME_POINT * h) {
            points.push(p);
        }
    }
    by_cell
}

/// Give each cell of `group` the corners in its box: as first point the
/// one nearest its present first point, the others as further points
/// (besides further points it keeps elsewhere). False if a first point
/// finds no sample to store it.
fn give_corners(field: &mut UnifiedField, group: &[(usize, Vec<DVec3>)]) -> bool {
    let spec = field.spec;
    let h = spec.spacing;
    for (cell, points) in group {
        let present = owned_points(field, *cell);
        let first = (points.iter().copied())
            .min_by(|a, b| {
                let d = |p: &DVec3| {
                    present
                        .iter()
                        .map(|q| q.distance(*p))
                        .fold(f64::INFINITY, f64::min)
                };
                d(a).total_cmp(&d(b))
            })
            .expect("a group's cell has corners");
        for n in corner_nodes(&spec, *cell) {
            if let Some(&crate::unified::Extra::FeaturePoint(p)) = field.extras.get(&(n as u32)) {
                if crate::sharp::owner_cell(&spec, n, p) == Some(*cell) {
                    field.extras.remove(&(n as u32));
                }
            }
        }
        let Some(n) = crate::unified::storage_for(field, *cell, first) else {
            return false;
        };
        field
            .extras
            .insert(n, crate::unified::Extra::FeaturePoint(first));
        let key = *cell as u32;
        let mut further: Vec<DVec3> = (field.cell_points.remove(&key).into_iter().flatten())
            .filter(|q| points.iter().all(|p| p.distance(*q) > SAME_POINT * h))
            .collect();
        further.extend(points.iter().copied().filter(|&p| p != first));
        if !further.is_empty() {
            field.cell_points.insert(key, further);
        }
    }
    true
}

/// The feature points `cell` owns (stored at its samples).
fn owned_points(field: &UnifiedField, cell: usize) -> Vec<DVec3> {
    let spec = &field.spec;
    (corner_nodes(spec, cell).into_iter())
        .filter_map(|n| match field.extras.get(&(n as u32)) {
            Some(&crate::unified::Extra::FeaturePoint(p))
                if crate::sharp::owner_cell(spec, n, p) == Some(cell) =>
            {
                Some(p)
            }
            _ => None,
        })
        .collect()
}

/// Where a cell holds several of the result's corners (fandisk's corner
/// and the two where its edges pierce a box, in a wedge thinner than a
/// cell), no single change helps: each corner needs the cell's fan, and
/// the sample the repair turned to make a loop there may sit on the
/// wrong side of it. Offered together as one alternative: every crossed
/// cell of the 3³ block around such a cell takes the corners in its box
/// (see [`give_corners`]); with it, the block's samples the repair
/// turned (on the surface, on the other side than the exact result)
/// turned back or not, and one sample near the surface on the outside
/// turned or none. The alternative whose block lies nearest the result
/// ([`gain`]) is kept. Returns the number of blocks changed.
pub(super) fn add_corner_sets(
    field: &mut UnifiedField,
    combined: &Combined,
    surface: &TriMesh,
    old_features: &BTreeMap<usize, CellFeatures>,
    corners: &[DVec3],
) -> usize {
    let spec = field.spec;
    let h = spec.spacing;
    let by_cell = corners_by_cell(field, combined, old_features, corners);
    // A place: a cell with a new corner and another corner or its own
    // point in its box; it also takes the new edge's ends in it.
    let places: Vec<(usize, Vec<DVec3>)> = (by_cell.iter())
        .filter(|(_, points)| points.iter().any(|p| corners.contains(p)))
        .filter_map(|(&c, points)| {
            let mut all = points.clone();
            let lo = node_position(&spec, c);
            let in_box = |p: &DVec3| (*p - lo).min_element() >= 0.0 && (*p - lo).max_element() < h;
            for p in owned_points(field, c).into_iter().filter(in_box) {
                if all.iter().all(|q| q.distance(p) > SAME_POINT * h) {
                    all.push(p);
                }
            }
            if all.len() < 2 {
                return None;
            }
            for p in edge_exits(&spec, combined, c) {
                if all.iter().all(|q| q.distance(p) > SAME_POINT * h) {
                    all.push(p);
                }
            }
            Some((c, all))
        })
        .collect();
    if places.is_empty() {
        return 0;
    }
    let region: BTreeSet<usize> = (places.iter())
        .flat_map(|&(c, _)| crate::refine::block(&spec, c, 1))
        .collect();
    let mut reference = result_points(&spec, combined, surface, &region);
    reference.extend(
        (region.iter())
            .flat_map(|&c| result_features(&spec, combined, c, old_features.get(&c), corners)),
    );
    reference.extend(tool_edge_points(combined, h));
    let mut changed = 0;
    for (place, points) in places {
        let Some(before) = local_error(field, combined, place, &reference) else {
            continue;
        };
        let mut group: Vec<(usize, Vec<DVec3>)> = vec![(place, points)];
        group.extend(
            crate::refine::block(&spec, place, 1)
                .filter(|&c| c != place && crosses(&spec, &field.values, c))
                .filter_map(|c| by_cell.get(&c).map(|points| (c, points.clone()))),
        );
        let nodes: BTreeSet<usize> = (group.iter())
            .flat_map(|(c, _)| corner_nodes(&spec, *c))
            .collect();
        let exact = |n: usize| combined.signed_distance(node_position(&spec, n));
        let turned_by_repair: Vec<usize> = (nodes.iter().copied())
            .filter(|&n| field.values[n].abs() <= 1e-9 * h)
            .filter(|&n| (exact(n) < 0.0) != (field.values[n] < 0.0))
            .collect();
        let outside: Vec<usize> = (nodes.iter().copied())
            .filter(|&n| field.values[n] > 0.0 && !turned_by_repair.contains(&n))
            .collect();
        let mut best: Option<(f64, UnifiedField)> = None;
        for revert in [false, true] {
            if revert && turned_by_repair.is_empty() {
                continue;
            }
            for turn in std::iter::once(None).chain(outside.iter().map(Some)) {
                let mut trial = field.clone();
                if revert && !revert_turns(&mut trial, &turned_by_repair, exact) {
                    continue;
                }
                if let Some(&n) = turn {
                    if !crate::refine::may_turn(&trial, n) {
                        continue;
                    }
                    trial.values[n] = crate::refine::turned(trial.values[n], h);
                }
                if !give_corners(&mut trial, &group) {
                    continue;
                }
                let after = local_error(&trial, combined, place, &reference);
                if let Some(g) = after.and_then(|a| gain(before, a)) {
                    if best.as_ref().is_none_or(|(b, _)| g > *b) {
                        best = Some((g, trial));
                    }
                }
            }
        }
        if let Some((_, trial)) = best {
            *field = trial;
            changed += 1;
        }
    }
    changed
}

/// Give the samples in `nodes` their exact values back (the other side
/// again), where topology allows; false where it does not.
fn revert_turns(field: &mut UnifiedField, nodes: &[usize], exact: impl Fn(usize) -> f64) -> bool {
    let cube = surfrecon_grid::topology::Neighbourhood::new(&field.spec.strides());
    for &n in nodes {
        let v = exact(n);
        if !crate::offset::may_take(&cube, n, v, |m| field.values[m]) {
            return false;
        }
        field.values[n] = v;
    }
    true
}

/// How far (spacings) back into the cell along the new edge
/// [`edge_exits`] puts its points: fandisk − box's wedge kept its corner
/// with the exit moved 0.05-0.1 h in (0.145-0.147 h), not on the face
/// (0.329 h: the fan was refused).
const EXIT_INSET: f64 = 0.05;

/// Where the new edge leaves `cell` through a face it crosses at more
/// than [`EXIT_MIN_SLOPE`], moved [`EXIT_INSET`] back in along the edge:
/// the ends of the cell's stretch of the new edge.
fn edge_exits(spec: &surfrecon_grid::GridSpec<3>, combined: &Combined, cell: usize) -> Vec<DVec3> {
    let h = spec.spacing;
    let lo = node_position(spec, cell);
    let points = super::new_edge_points(spec, combined, cell);
    let mut exits: Vec<DVec3> = Vec::new();
    for axis in 0..3 {
        for (side, inward) in [(lo[axis], 1.0), (lo[axis] + h, -1.0)] {
            let gap = |p: &DVec3| (p[axis] - side).abs();
            let Some(&p) = points.iter().min_by(|a, b| gap(a).total_cmp(&gap(b))) else {
                continue;
            };
            let t = edge_tangent(combined, p, h);
            if t[axis].abs() < EXIT_MIN_SLOPE {
                continue;
            }
            let target = side + inward * EXIT_INSET * h * t[axis].abs();
            let start = p + t * ((target - p[axis]) / t[axis]);
            let Some(q) = combined.edge_point(start, 1e-6 * h) else {
                continue;
            };
            let inside = (q - lo).min_element() >= 0.0 && (q - lo).max_element() <= h;
            if inside && exits.iter().all(|e| e.distance(q) > SAME_POINT * h) {
                exits.push(q);
            }
        }
    }
    exits
}

/// The new edge crossing a face more obliquely than this (the axis part
/// of its unit tangent) has no exit there.
const EXIT_MIN_SLOPE: f64 = 0.2;

/// The unit tangent of the new edge at `p`: across both surfaces'
/// gradients (central differences).
fn edge_tangent(combined: &Combined, p: DVec3, h: f64) -> DVec3 {
    let gradient = |f: &dyn Fn(DVec3) -> f64| {
        let e = 1e-3 * h;
        DVec3::new(
            f(p + DVec3::X * e) - f(p - DVec3::X * e),
            f(p + DVec3::Y * e) - f(p - DVec3::Y * e),
            f(p + DVec3::Z * e) - f(p - DVec3::Z * e),
        )
    };
    let object = gradient(&|q| combined.object.signed_distance(q));
    let tool = gradient(&|q| combined.tool.signed_distance(q));
    object.cross(tool).normalize_or_zero()
}
