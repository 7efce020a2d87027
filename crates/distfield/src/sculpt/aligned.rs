//! Sculpting an offset field: the samples whose boxes the new sharp edge
//! passes through are re-placed onto it, as construction aligns samples
//! with a mesh's feature edges ([`crate::offset`]), so that marching
//! cubes on the offset grid runs the surface through the edge instead of
//! cutting it off by up to a cell.

use super::{bisect, kept_pieces, result_points, Combined, Tool};
use crate::extract::corner_nodes;
use crate::features::{cell_of, clip_to_cells, CellFeatures};
use crate::offset::{
    add_cells_beside, cells_around, keeps_topology, least_corner_volume, line_targets,
    node_position, on_outer_layer, on_surface_values, repair_samples, solid_fraction, stays_convex,
    AlignTarget, MeshPoints, OffsetField, Search, Truth, Weights, DEFAULT_ITERATIONS,
    MIN_CORNER_VOLUME,
};
use crate::refine::block;
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet};
use surfrecon_geom::{DVec3, TriMesh};

/// The new edge as segments: where the tool's surface crosses each
/// triangle of `surface` (the object as its field represents it), from
/// one crossed triangle edge to the other. Both ends lie exactly on the
/// object's triangle and on the tool (bisection); the edge is where
/// object and tool meet, so for every operation it lies on the result.
pub(super) fn new_edge_segments(surface: &TriMesh, tool: &Tool) -> Vec<[DVec3; 2]> {
    let inside: Vec<bool> = (surface.vertices.par_iter())
        .map(|&v| tool.signed_distance(v) < 0.0)
        .collect();
    surface
        .triangles
        .par_iter()
        .filter_map(|t| {
            let ends: Vec<DVec3> = (0..3)
                .filter_map(|k| {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    // Lower index first: both triangles of an edge find
                    // the same point, so the segments join exactly.
                    let (a, b) = (a.min(b) as usize, a.max(b) as usize);
                    (inside[a] != inside[b])
                        .then(|| tool_root(tool, surface.vertices[a], surface.vertices[b]))
                })
                .collect();
            (ends.len() == 2).then(|| [ends[0], ends[1]])
        })
        .collect()
}

/// Where the tool's surface crosses segment `a`-`b` (bisection; the
/// ends lie on different sides).
fn tool_root(tool: &Tool, a: DVec3, b: DVec3) -> DVec3 {
    a.lerp(
        b,
        bisect(0.0, 1.0, |t| tool.signed_distance(a.lerp(b, t)) < 0.0),
    )
}

/// What [`align_to_new_edge`] did: samples offered a place on the new
/// edge or a new corner, and those moved there.
pub(super) struct Aligned {
    pub offered: usize,
    pub moved: Vec<usize>,
}

/// Put the samples whose boxes the new edge (`segments`) or a new corner
/// passes through onto it, corners first, as construction does with a
/// mesh's features ([`line_targets`]): each goes onto the surface on the
/// outside of a convex edge or the inside of a concave one (the other
/// side where that is not legal), when it stays in its box, its cells
/// stay convex and the surface keeps its topology. A sample holding an
/// old feature the tool leaves in place stays there, except for a new
/// corner (which lies on that old feature too).
pub(super) fn align_to_new_edge(
    field: &mut OffsetField,
    combined: &Combined,
    segments: &[[DVec3; 2]],
    corners: &[DVec3],
) -> Aligned {
    let spec = field.spec;
    let h = spec.spacing;
    let targets = line_targets(&spec, segments.iter().copied(), corners.iter().copied());
    let reach = 0.5 * h * (1.0 - 1e-9);
    let (first, rest): (Vec<_>, Vec<_>) = targets.iter().partition(|(_, t)| t.corner);
    let mut moved = Vec::new();
    for (&node, target) in first.into_iter().chain(rest) {
        if on_outer_layer(&spec, node)
            || (!target.corner && holds_old_feature(field, combined, node))
        {
            continue;
        }
        let home = node_position(&spec, node);
        let convex = |p: &DVec3, field: &OffsetField| {
            stays_convex(&spec, node, *p, |m| field.position_of(m))
        };
        let mut places = places_along(target)
            .map(|p| on_both(combined, p, target.corner, home, reach))
            .filter(|p| (*p - home).abs().max_element() <= reach);
        let p = match places.find(|p| convex(p, field)) {
            Some(p) => p,
            // A corner is worth a neighbour sent home (the fit moves it
            // again); an edge sample is not.
            None if target.corner && make_room(field, combined, node, target.point, &moved) => {
                target.point
            }
            None if target.corner && shift_block(field, combined, node, target.point) => {
                target.point
            }
            None => continue,
        };
        let outside_first = solid_fraction(p, 0.25 * h, |q| combined.signed_distance(q)) < 0.5;
        let sides = if outside_first {
            [0.0, -1e-9 * h]
        } else {
            [-1e-9 * h, 0.0]
        };
        let legal = sides
            .into_iter()
            .find_map(|v| keeps_topology(&spec, node, v, |m| field.values[m]));
        if let Some(v) = legal {
            field.values[node] = v;
            field.moved.insert(node as u32, p);
            moved.push(node);
        }
    }
    Aligned {
        offered: targets.len(),
        moved,
    }
}

/// A moved neighbour of `node` put back on its own node (legally, with
/// the result's distance there) so that `node` may go to `p` keeping
/// every cell convex, if one does: neighbours holding an old feature
/// last, those just put on the new edge (`placed`) never. Returns
/// whether one was.
fn make_room(
    field: &mut OffsetField,
    combined: &Combined,
    node: usize,
    p: DVec3,
    placed: &[usize],
) -> bool {
    let spec = field.spec;
    let h = spec.spacing;
    let mut neighbours: Vec<usize> = cells_around(&spec, node)
        .flat_map(|c| corner_nodes(&spec, c))
        .filter(|&m| m != node && !on_outer_layer(&spec, m) && !placed.contains(&m))
        .filter(|m| field.moved.contains_key(&(*m as u32)))
        .collect::<BTreeSet<usize>>()
        .into_iter()
        .collect();
    neighbours.sort_by_key(|&m| holds_old_feature(field, combined, m));
    for m in neighbours {
        let home = node_position(&spec, m);
        if !stays_convex(&spec, m, home, |k| field.position_of(k)) {
            continue;
        }
        let value = on_surface_values(combined.signed_distance(home), h)
            .into_iter()
            .find_map(|v| keeps_topology(&spec, m, v, |k| field.values[k]));
        let Some(value) = value else { continue };
        let position = |k: usize| {
            if k == m {
                home
            } else {
                field.position_of(k)
            }
        };
        if stays_convex(&spec, node, p, position) {
            field.values[m] = value;
            field.moved.remove(&(m as u32));
            return true;
        }
    }
    false
}

/// Fractions of a corner sample's move that [`shift_block`] tries for
/// its neighbours, smallest first.
const SHIFTS: [f64; 3] = [0.25, 0.5, 0.75];

/// Let sample `node` reach corner `p` by shifting its 26 neighbours part
/// of the way with it (each as far as its own box allows), the smallest
/// fraction of [`SHIFTS`] that keeps every cell around them convex. A
/// corner near a cell's centre lies in one sample's box only, and that
/// sample alone cannot reach it (its corner of that cell turns inside
/// out: fandisk − sphere's corner where the new edge meets the old 91°
/// edge); the shifted neighbours carry the grid along. They take the
/// result's distance at their new places (the search and repair that
/// follow fit them again), each where that keeps the surface's topology;
/// else nothing moves. Returns whether `node` may go to `p` now.
fn shift_block(field: &mut OffsetField, combined: &Combined, node: usize, p: DVec3) -> bool {
    let spec = field.spec;
    let h = spec.spacing;
    let reach = 0.5 * h * (1.0 - 1e-9);
    let least = MIN_CORNER_VOLUME * h.powi(3);
    let neighbours: Vec<usize> = cells_around(&spec, node)
        .flat_map(|c| corner_nodes(&spec, c))
        .filter(|&m| m != node && !on_outer_layer(&spec, m))
        .collect::<BTreeSet<usize>>()
        .into_iter()
        .collect();
    let shift = p - node_position(&spec, node);
    let shifted = |f: f64| -> BTreeMap<usize, DVec3> {
        (neighbours.iter())
            .map(|&m| {
                let home = node_position(&spec, m);
                let q = field.position_of(m) + shift * f;
                let box_ = DVec3::splat(reach);
                (m, home + (q - home).clamp(-box_, box_))
            })
            .collect()
    };
    let convex = |moves: &BTreeMap<usize, DVec3>| {
        let position = |k: usize| match moves.get(&k) {
            _ if k == node => p,
            Some(&q) => q,
            None => field.position_of(k),
        };
        (moves.iter())
            .map(|(&k, &q)| least_corner_volume(&spec, k, q, position))
            .fold(least_corner_volume(&spec, node, p, position), f64::min)
            > least
    };
    let Some(moves) = SHIFTS.iter().map(|&f| shifted(f)).find(|m| convex(m)) else {
        return false;
    };
    let saved = field.clone();
    for (&m, &q) in &moves {
        let value = on_surface_values(combined.signed_distance(q), h)
            .into_iter()
            .find_map(|v| keeps_topology(&spec, m, v, |k| field.values[k]));
        let Some(value) = value else {
            *field = saved;
            return false;
        };
        field.values[m] = value;
        field.moved.insert(m as u32, q);
    }
    true
}

/// Where on its piece of the new edge a sample may go, best first: the
/// piece's middle (which spreads the samples along the line, as in
/// construction), then points towards either end. A sample whose
/// neighbour already sits near the shared box face cannot go to the
/// middle when that flattens a cell between them; further along it can.
fn places_along(target: &AlignTarget) -> impl Iterator<Item = DVec3> + '_ {
    let [a, b] = target.piece;
    PLACES.iter().map(move |&t| a.lerp(b, t))
}

/// Fractions along a piece of the new edge tried by [`places_along`].
const PLACES: [f64; 7] = [0.5, 0.35, 0.65, 0.2, 0.8, 0.05, 0.95];

/// `p` (on a piece of the new edge) moved onto both surfaces (a chord's
/// middle lies off a curved tool), if that stays in the sample's box;
/// else `p`. Corners are exact already.
fn on_both(combined: &Combined, p: DVec3, corner: bool, home: DVec3, reach: f64) -> DVec3 {
    if corner {
        return p;
    }
    let h = 2.0 * reach;
    combined
        .edge_point(p, 1e-6 * h)
        .filter(|q| (*q - home).abs().max_element() <= reach && q.distance(p) < 0.1 * h)
        .unwrap_or(p)
}

/// Whether sample `node` sits off its node on the surface where the tool
/// left it (on an old feature edge or corner the result keeps).
fn holds_old_feature(field: &OffsetField, combined: &Combined, node: usize) -> bool {
    let h = field.spec.spacing;
    field
        .moved
        .get(&(node as u32))
        .is_some_and(|&p| field.values[node].abs() <= 1e-6 * h && !combined.changes(p, 1e-6 * h))
}

/// The exact result of a sculpting step (object and tool combined), as
/// the truth the samples around the new edge are fitted to.
struct ResultTruth<'c, 'a> {
    combined: &'c Combined<'a>,
    h: f64,
}

/// A point counts as on the result within this many spacings.
const ON_RESULT: f64 = 1e-6;
/// Steps per search length in [`ResultTruth::hit_along`] (a sign change
/// is then located by bisection; the result's sheets lie farther apart
/// than a quarter cell wherever the field can tell them apart).
const HIT_STEPS: usize = 8;

impl Truth for ResultTruth<'_, '_> {
    fn signed_distance(&self, p: DVec3) -> f64 {
        self.combined.signed_distance(p)
    }

    /// The nearer of the object's and the tool's closest points that lie
    /// on the result, else a point on the new edge near `p`.
    fn closest_point(&self, p: DVec3) -> DVec3 {
        let c = self.combined;
        let on_result = |q: &DVec3| c.signed_distance(*q).abs() <= ON_RESULT * self.h;
        [c.object.closest_point(p), c.tool.closest_point(p)]
            .into_iter()
            .filter(on_result)
            .min_by(|a, b| a.distance(p).total_cmp(&b.distance(p)))
            .or_else(|| c.edge_point(p, ON_RESULT * self.h))
            .unwrap_or_else(|| c.object.closest_point(p))
    }

    fn hit_along(&self, p: DVec3, axis: usize, max: f64) -> Option<f64> {
        let at = |t: f64| {
            let mut q = p;
            q[axis] += t;
            self.combined.signed_distance(q) < 0.0
        };
        let step = max / HIT_STEPS as f64;
        let inside = at(0.0);
        let k = (1..=HIT_STEPS).find(|&k| at(k as f64 * step) != inside)?;
        Some(bisect((k - 1) as f64 * step, k as f64 * step, at))
    }
}

/// The result's features by cell around the new edge, for the fit: the
/// new edge's pieces and corners in the cells they cross, those cells'
/// neighbours near the surface, and in all of them the object's old
/// features where the tool leaves them (so that the fit keeps them).
pub(super) fn result_cells(
    field: &OffsetField,
    combined: &Combined,
    segments: &[[DVec3; 2]],
    corners: &[DVec3],
    old: &BTreeMap<usize, CellFeatures>,
) -> BTreeMap<usize, CellFeatures> {
    let spec = &field.spec;
    let mut cells: BTreeMap<usize, CellFeatures> = BTreeMap::new();
    for &[a, b] in segments {
        for (cell, piece) in clip_to_cells(spec, a, b) {
            cells.entry(cell).or_default().pieces.push(piece);
        }
    }
    for &p in corners {
        if let Some(cell) = cell_of(spec, p) {
            cells.entry(cell).or_default().corners.push(p);
        }
    }
    add_cells_beside(&mut cells, spec, &field.values);
    for (cell, features) in cells.iter_mut() {
        if let Some(f) = old.get(cell) {
            add_kept_features(features, f, combined, spec.spacing);
        }
    }
    cells
}

/// Add to `features` the parts of `old` (an object cell's features) that
/// lie on the result.
fn add_kept_features(features: &mut CellFeatures, old: &CellFeatures, combined: &Combined, h: f64) {
    let kept = |p: DVec3| combined.signed_distance(p).abs() < 1e-6 * h;
    features
        .corners
        .extend(old.corners.iter().copied().filter(|&p| kept(p)));
    features
        .bends
        .extend(old.bends.iter().copied().filter(|&p| kept(p)));
    features
        .pieces
        .extend(kept_pieces(&old.pieces, combined, h));
}

/// Fit the samples around the new edge to the result as construction
/// fits them to a mesh: the energy search from a quarter cell in halving
/// steps over the corners of the cells of [`result_cells`], the samples
/// in `pinned` (on the new edge, or holding old features) staying where
/// they are, then the error-driven repair against points of the result.
/// Returns how many samples the search and the repair moved.
pub(super) fn fit_around_new_edge(
    field: &mut OffsetField,
    combined: &Combined,
    surface: &TriMesh,
    cells: &BTreeMap<usize, CellFeatures>,
    pinned: &BTreeSet<usize>,
) -> usize {
    let spec = field.spec;
    let h = spec.spacing;
    let truth = ResultTruth { combined, h };
    let search = Search::on_truth(&spec, &truth, cells, Weights::default());
    let mut active = search.candidates();
    let mut step = 0.25 * h;
    let mut moved = BTreeSet::new();
    for _ in 0..DEFAULT_ITERATIONS {
        let round = search.round(field, &active, pinned, step);
        step *= 0.5;
        let near: BTreeSet<usize> = round
            .iter()
            .flat_map(|&n| cells_around(&spec, n).flat_map(|c| corner_nodes(&spec, c)))
            .collect();
        active.retain(|n| near.contains(n));
        moved.extend(round);
    }
    let region: BTreeSet<usize> = cells.keys().flat_map(|&c| block(&spec, c, 2)).collect();
    let points = result_points(&spec, combined, surface, &region);
    let points = MeshPoints::from_points(&spec, points.iter().copied());
    let (_, repaired) = repair_samples(&search, field, &points, &BTreeMap::new());
    moved.len() + repaired
}

/// The samples the fit leaves in place: those just put on the new edge
/// (`aligned`), and those of the cells' corners holding an old feature
/// the tool left.
pub(super) fn pinned_samples(
    field: &OffsetField,
    combined: &Combined,
    cells: &BTreeMap<usize, CellFeatures>,
    aligned: &[usize],
) -> BTreeSet<usize> {
    let corners = cells.keys().flat_map(|&c| corner_nodes(&field.spec, c));
    let old: Vec<usize> = corners
        .filter(|&n| holds_old_feature(field, combined, n))
        .collect();
    aligned.iter().copied().chain(old).collect()
}
