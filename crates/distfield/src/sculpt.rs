//! CSG sculpting: union, subtraction or intersection of a field with a
//! tool (sphere, box, capped cylinder, or any closed surface), sample by
//! sample (min/max of the two signed distances).
//!
//! Min/max alone would round the new edges where the tool cuts the
//! object, exactly as a regular grid rounds any edge. So after combining,
//! each cell the tool changed is revisited with exact geometry: the
//! object's surface (as the field represents it, i.e. its extracted mesh)
//! and the tool's. A unified field gets exact directed distances on the
//! cells' edges where interpolation errs, and a feature point on the new
//! edge (where the two surfaces meet) in each cell it crosses; an offset
//! field gets a sample moved onto that edge instead.

use crate::extract::{cell_sheets, cell_triangles, corner_nodes, crosses, fan_fits, SampledField};
use crate::features::{
    cells_with_features, nudge_into, CellFeatures, Features, DEFAULT_FEATURE_ANGLE_DEG,
};
use crate::offset::{
    cells_around, may_take, node_position, on_outer_layer, stays_convex, OffsetField,
};
use crate::query::MeshQuery;
use crate::refine::{hand_over, mesh_points, Exact, MeshSamples};
use crate::sharp::Tangent;
use crate::sharp::{clamp_near, owner_cell};
use crate::unified::{
    farthest_from, repick_cell, sharp_point, snap_corners, storage_for, Extra, UnifiedField,
};
use crate::DistFieldError;
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use surfrecon_geom::{DVec3, TriMesh};
use surfrecon_grid::marching::tables::EDGE_CORNERS;
use surfrecon_grid::marching::{cell_case, crossing_fraction};
use surfrecon_grid::topology::Neighbourhood;
use surfrecon_grid::{Field3, GridSpec};

mod aligned;
mod further;

/// How a tool combines with the field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Operation {
    Union,
    Subtract,
    Intersect,
}

impl Operation {
    /// The combined signed distance (exact on the zero set).
    pub fn apply(self, object: f64, tool: f64) -> f64 {
        match self {
            Operation::Union => object.min(tool),
            Operation::Subtract => object.max(-tool),
            Operation::Intersect => object.max(tool),
        }
    }
}

/// A sculpting tool: a solid given by its exact signed distance.
pub enum Tool {
    Sphere {
        centre: DVec3,
        radius: f64,
    },
    Box {
        min: DVec3,
        max: DVec3,
    },
    /// A cylinder around the segment `a`-`b`, with flat caps.
    Cylinder {
        a: DVec3,
        b: DVec3,
        radius: f64,
    },
    /// A closed, outward-oriented surface (a mesh file, or the surface
    /// of another field).
    Surface(Box<MeshQuery>),
}

impl Tool {
    /// Refuse degenerate tools.
    pub fn check(&self) -> Result<(), DistFieldError> {
        let bad = |m: String| Err(DistFieldError::InvalidOption(m));
        match self {
            Tool::Sphere { centre, radius } if !(centre.is_finite() && *radius > 0.0 && radius.is_finite()) => {
                bad(format!("a sphere needs a finite centre and a positive radius, not {centre} / {radius}"))
            }
            Tool::Box { min, max } if !(min.is_finite() && max.is_finite() && min.cmplt(*max).all()) => {
                bad(format!("a box needs finite corners with min < max on every axis, not {min} / {max}"))
            }
            Tool::Cylinder { a, b, radius }
                if !(a.is_finite() && b.is_finite() && a != b && *radius > 0.0 && radius.is_finite()) =>
            {
                bad(format!("a cylinder needs two distinct finite end points and a positive radius, not {a} / {b} / {radius}"))
            }
            _ => Ok(()),
        }
    }

    /// Signed distance to the tool's surface, negative inside.
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        match self {
            Tool::Sphere { centre, radius } => p.distance(*centre) - radius,
            Tool::Box { min, max } => {
                let q = (p - (*min + *max) * 0.5).abs() - (*max - *min) * 0.5;
                q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
            }
            Tool::Cylinder { a, b, radius } => {
                let axis = *b - *a;
                let length = axis.length();
                let t = (p - *a).dot(axis) / length;
                let radial = ((p - *a) - axis * (t / length)).length() - radius;
                let along = (-t).max(t - length);
                if radial > 0.0 && along > 0.0 {
                    radial.hypot(along)
                } else {
                    radial.max(along)
                }
            }
            Tool::Surface(q) => q.signed_distance(p),
        }
    }

    /// The closest point of the tool's surface to `p`.
    pub fn closest_point(&self, p: DVec3) -> DVec3 {
        match self {
            Tool::Surface(q) => q.closest_point(p),
            Tool::Sphere { centre, radius } => {
                *centre + (p - *centre).normalize_or(DVec3::X) * *radius
            }
            // Exact distances: stepping back along the gradient lands on
            // the surface (a few steps settle edges and corners).
            _ => (0..4).fold(p, |x, _| x - self.gradient(x) * self.signed_distance(x)),
        }
    }

    fn gradient(&self, p: DVec3) -> DVec3 {
        let e = 1e-7 * (1.0 + p.abs().max_element());
        let g = DVec3::from_array(std::array::from_fn(|a| {
            let mut d = DVec3::ZERO;
            d[a] = e;
            (self.signed_distance(p + d) - self.signed_distance(p - d)) / (2.0 * e)
        }));
        g.normalize_or_zero()
    }
}

/// What a sculpting step changed.
#[derive(Debug, Clone, Copy, Default)]
pub struct SculptReport {
    /// Samples whose distance now comes from the tool.
    pub changed: usize,
    /// Cells the tool changed that the surface crosses.
    pub cells: usize,
    /// Points found on the new edges (where object and tool meet).
    pub edge_points: usize,
    /// Of those, kept as feature points (UDF) or samples moved onto them (ODF).
    pub kept: usize,
    /// Directed distances stored anew (UDF).
    pub directed: usize,
    /// Old extra data dropped because the tool changed its cell.
    pub dropped: usize,
    /// New corners that a sample was moved onto (UDF).
    pub snapped: usize,
    /// Changed cells given another feature point (or none) whose
    /// surrounding surface lies nearer the result.
    pub repicked: usize,
    /// Of those, samples given the side other than against most of their
    /// neighbours, where that puts the cells' surface nearer the result.
    pub turned: usize,
    /// Cells whose feature point the error-driven repair against the
    /// exact result changed ([`crate::refine`]).
    pub repaired: usize,
    /// Samples moved into a wall or gap of the result thinner than a
    /// cell that lay between them and a neighbour.
    pub thin: usize,
    /// Samples whose magnitude was raised so that a face with samples of
    /// alternating sign joins the pair the exact result joins (UDF).
    pub settled: usize,
    /// Samples given the value that makes the interpolated crossing on an
    /// edge from a sample floating in a thin wall exact (UDF).
    pub straightened: usize,
    /// Further feature points kept beside a cell's own (UDF): corners
    /// where the tool's own edges cross the object, and old edges' points
    /// a cell's point on the new edge displaced.
    pub further: usize,
    /// Samples the fit around the new edge moved (ODF: the energy search
    /// and the repair against the exact result, as in construction).
    pub fitted: usize,
    /// Blocks around a cell holding several of the result's corners
    /// whose cells took all the corners in their boxes at once, with the
    /// repair's turns revised (UDF; `further::add_corner_sets`).
    pub corner_sets: usize,
}

/// Combine a regular field with the tool.
pub fn sculpt_regular(field: &mut Field3, operation: Operation, tool: &Tool) -> SculptReport {
    let spec = field.spec;
    let changed = field
        .values
        .par_iter_mut()
        .enumerate()
        .map(|(i, v)| {
            let t = tool.signed_distance(node_position(&spec, i));
            let new = operation.apply(*v, t);
            let changed = new != *v;
            *v = new;
            changed as usize
        })
        .sum();
    SculptReport {
        changed,
        ..Default::default()
    }
}

/// The exact combined surface: the object as the field represents it
/// (its extracted mesh) and the tool.
struct Combined<'a> {
    object: MeshQuery,
    tool: &'a Tool,
    operation: Operation,
}

impl<'a> Combined<'a> {
    fn new(
        surface: &TriMesh,
        tool: &'a Tool,
        operation: Operation,
    ) -> Result<Self, DistFieldError> {
        Ok(Self {
            object: MeshQuery::new(surface)?,
            tool,
            operation,
        })
    }

    fn signed_distance(&self, p: DVec3) -> f64 {
        self.operation
            .apply(self.object.signed_distance(p), self.tool.signed_distance(p))
    }

    /// The outward unit normal at `p`: the combined distance's gradient,
    /// by central differences.
    fn normal(&self, p: DVec3, h: f64) -> Option<DVec3> {
        let e = 1e-4 * h;
        let gradient = DVec3::from_array(std::array::from_fn(|k| {
            let mut step = DVec3::ZERO;
            step[k] = e;
            self.signed_distance(p + step) - self.signed_distance(p - step)
        }));
        gradient.try_normalize()
    }

    /// Whether the tool moved the surface near `p`: the combined distance
    /// differs from the object's by more than `tolerance`. (Feature points
    /// elsewhere stay, including those beside their cell that are not on
    /// the extracted surface.)
    fn changes(&self, p: DVec3, tolerance: f64) -> bool {
        (self.signed_distance(p) - self.object.signed_distance(p)).abs() > tolerance
    }

    /// A point on both surfaces near `start` (alternating projections),
    /// if they meet there.
    fn edge_point(&self, start: DVec3, tolerance: f64) -> Option<DVec3> {
        let mut x = start;
        for _ in 0..32 {
            x = self.tool.closest_point(self.object.closest_point(x));
            if self.object.signed_distance(x).abs() < tolerance {
                return Some(x);
            }
        }
        None
    }
}

/// Combine every sample of `field` with the tool at the sample's
/// position; returns the changed samples (sorted), the cells around them
/// that the new surface crosses, and a report counting both.
fn combine<F: SampledField>(
    field: &mut F,
    values: impl Fn(&mut F) -> &mut Vec<f64>,
    operation: Operation,
    tool: &Tool,
) -> (Vec<usize>, Vec<usize>, SculptReport) {
    let spec = *field.spec();
    let new: Vec<(usize, f64)> = (0..spec.node_count())
        .into_par_iter()
        .filter_map(|i| {
            let v = field.value(i);
            let w = operation.apply(v, tool.signed_distance(field.position(i)));
            (w != v).then_some((i, w))
        })
        .collect();
    let values = values(field);
    for &(i, w) in &new {
        values[i] = w;
    }
    let changed: Vec<usize> = new.into_iter().map(|(i, _)| i).collect();
    let around: BTreeSet<usize> = changed
        .iter()
        .flat_map(|&n| cells_around(&spec, n))
        .collect();
    let cells: Vec<usize> = around
        .into_iter()
        .filter(|&c| crosses(&spec, values, c))
        .collect();
    let report = SculptReport {
        changed: changed.len(),
        cells: cells.len(),
        ..Default::default()
    };
    (changed, cells, report)
}

/// A point where object and tool meet in `cell` (its closed box), if
/// they do, moved just inside it. The search starts from the cell's
/// centre and, failing that, from its corners.
fn edge_point_in(spec: &GridSpec<3>, combined: &Combined, cell: usize) -> Option<DVec3> {
    let h = spec.spacing;
    let lo = node_position(spec, cell);
    let starts = std::iter::once(lo + DVec3::splat(0.5 * h)).chain(
        (0..8).map(|c| lo + DVec3::new((c & 1) as f64, ((c >> 1) & 1) as f64, (c >> 2) as f64) * h),
    );
    starts
        .filter_map(|start| combined.edge_point(start, 1e-6 * h))
        .find(|&p| {
            nudge_into(spec, cell, p).distance(p) < 1e-6 * h
                && combined.tool.signed_distance(p).abs() < 1e-6 * h
        })
        .map(|p| nudge_into(spec, cell, p))
}

/// The feature point of a cell whose moved samples widen it past its grid
/// box (into a wall above a cap's rim): the QEF point of its crossings,
/// where it lies on the result's edge (`on_edge`, the rim) within
/// [`WIDENED_MARGIN`] of the box of the samples where they sit, moved
/// into the grid box (where [`owner_cell`] gives it to the cell), if the
/// cell's fan around it fits there. On the rim itself the fan folds: the
/// crossing on the face of the moved samples lies on the cap, the one on
/// the wall below the rim, and the fan triangle between them stands
/// across the hole; so [`sharp_point`] gives the cell nothing. (A cap's
/// rim is the tool's own edge, which [`edge_point_in`], searching where
/// object and tool meet, never finds.)
fn widened_point(
    field: &UnifiedField,
    cell: usize,
    tangents: &[Tangent],
    cos_limit: f64,
    on_edge: impl Fn(DVec3) -> bool,
) -> Option<DVec3> {
    let spec = &field.spec;
    let positions = corner_nodes(spec, cell).map(|n| field.position(n));
    let lo = positions.iter().copied().fold(DVec3::INFINITY, DVec3::min);
    let hi = (positions.iter().copied()).fold(DVec3::NEG_INFINITY, DVec3::max);
    let grid = node_position(spec, cell);
    let widened = lo != grid || hi != grid + DVec3::splat(spec.spacing);
    if !widened || !crate::sharp::is_sharp(tangents, cos_limit) {
        return None;
    }
    let rim = crate::sharp::qef_minimizer(tangents)?;
    let margin = DVec3::splat(WIDENED_MARGIN * spec.spacing);
    if !(on_edge(rim) && rim.cmpge(lo - margin).all() && rim.cmple(hi + margin).all()) {
        return None;
    }
    let point = nudge_into(spec, cell, rim);
    fan_fits(field, cell, point).then_some(point)
}

/// How far past the box of its samples (spacings) a widened cell's rim
/// point may lie: the corner where an old edge passes over a cap's rim
/// lies 0.05 h below the cell on fandisk − cylinder.
const WIDENED_MARGIN: f64 = 0.1;

/// A point fitted to a cell's crossings counts as on the new edge within
/// this many spacings of both the tool and the result.
const ON_EDGE: f64 = 0.02;

/// Sculpt a unified field: combine, then restore exact crossings and put
/// feature points on the new edges.
pub fn sculpt_udf(
    field: &mut UnifiedField,
    operation: Operation,
    tool: &Tool,
    threshold: f64,
) -> Result<SculptReport, DistFieldError> {
    let surface = field.raw_surface();
    let combined = Combined::new(&surface, tool, operation)?;
    let features = Features::detect(&surface, DEFAULT_FEATURE_ANGLE_DEG);
    let mut corners = new_corners(&surface, &features, tool);
    let spec = field.spec;
    let h = spec.spacing;
    // Where the tool's own edges cross the object: corners of the result
    // offered as further points at the end.
    let rim_corners = further::tool_corners(tool, &combined.object, h);
    let all_corners: Vec<DVec3> = corners.iter().chain(&rim_corners).copied().collect();
    let old_features = cells_with_features(&surface, &features, &spec, |_| true);
    let (changed, mut cells, mut report) = combine(field, |f| &mut f.values, operation, tool);
    // Old directed distances of changed samples no longer describe the
    // surface. Their feature points are taken off them too (a changed
    // sample may move onto a new corner), but those the tool leaves on
    // the surface still mark an old edge: they go back to their cells
    // once the new corners and edges have theirs.
    let mut unhoused: Vec<(usize, DVec3)> = Vec::new();
    for &n in &changed {
        match field.extras.get(&(n as u32)) {
            Some(Extra::Position(_)) | None => {}
            Some(&Extra::FeaturePoint(p)) if !combined.changes(p, 1e-6 * h) => {
                unhoused.extend(owner_cell(&spec, n, p).map(|c| (c, p)));
                field.extras.remove(&(n as u32));
            }
            Some(_) => {
                field.extras.remove(&(n as u32));
                report.dropped += 1;
            }
        }
    }
    let stale: Vec<u32> = field
        .extras
        .iter()
        .filter_map(|(&i, e)| match e {
            Extra::FeaturePoint(p) if combined.changes(*p, 1e-6 * h) => Some(i),
            _ => None,
        })
        .collect();
    report.dropped += stale.len();
    for i in stale {
        field.extras.remove(&i);
    }
    // A field sculpted before may keep further points: those the tool
    // moves off the surface go as feature points do.
    for points in field.cell_points.values_mut() {
        let before = points.len();
        points.retain(|&p| !combined.changes(p, 1e-6 * h));
        report.dropped += before - points.len();
    }
    field.cell_points.retain(|_, points| !points.is_empty());
    // New corners a sample can sit on take it, as in construction: one
    // feature point per cell cannot keep both an old edge and the new one
    // where they meet.
    let snapped = snap_corners(field, &corners);
    corners.retain(|p| !snapped.contains(p));
    for p in &snapped {
        let node = field
            .extras
            .iter()
            .find_map(|(&n, e)| (*e == Extra::Position(*p)).then_some(n as usize));
        cells.extend(node.into_iter().flat_map(|n| cells_around(&spec, n)));
    }
    // Material (or a gap) thinner than a cell between two samples of one
    // side: a sample moves into it.
    let walls = fill_thin_walls(field, &combined, &changed);
    for &n in &walls {
        cells.extend(cells_around(&spec, n));
    }
    report.thin = walls.len();
    cells.sort_unstable();
    cells.dedup();
    cells.retain(|&c| crosses(&spec, &field.values, c));
    // Faces whose samples alternate in sign: the decider must join the
    // pair the result joins, or a hole opens through a wall (or a wall
    // through a hole) that no crossing or feature point can close.
    let settled = settle_ambiguous_faces(field, &combined, &cells);
    for &n in &settled {
        cells.extend(cells_around(&spec, n));
    }
    report.settled = settled.len();
    cells.sort_unstable();
    cells.dedup();
    cells.retain(|&c| crosses(&spec, &field.values, c));
    report.snapped = snapped.len();
    // Exact crossings on the edges of the cells the tool changed.
    let mut edges: BTreeSet<(usize, usize)> = BTreeSet::new();
    for &c in &cells {
        let nodes = corner_nodes(&spec, c);
        for [a, b] in EDGE_CORNERS {
            edges.insert((nodes[a as usize], (a ^ b).trailing_zeros() as usize));
        }
    }
    let crossings: HashMap<(usize, usize), Tangent> = edges
        .par_iter()
        .filter_map(|&(n, axis)| {
            let p = edge_crossing(field, &combined, n, axis)?;
            Some(((n, axis), (p, combined.normal(p, h)?)))
        })
        .collect();
    report.directed = store_directed(field, &crossings, threshold);
    // Edges from a sample floating in a thin wall take no directed
    // distance: the sample at their other end is set to what makes the
    // interpolation exact, and its own edges take theirs.
    let straightened = straighten_floating_edges(field, &crossings, threshold);
    if !straightened.is_empty() {
        report.directed += store_directed(field, &crossings, threshold);
    }
    report.straightened = straightened.len();
    // Feature points on the new edges: where the crossings' tangent
    // planes meet on both the tool and the result (a corner where the new
    // edge meets an old one), that point, else one on the new edge.
    let cos_limit = crate::features::DEFAULT_FEATURE_ANGLE_DEG
        .to_radians()
        .cos();
    let taken: BTreeSet<usize> = field.feature_points().into_keys().collect();
    for &c in &cells {
        if taken.contains(&c) {
            continue;
        }
        let tangents = cell_tangents(&spec, &crossings, c);
        let on_both = |q: DVec3| {
            combined.signed_distance(q).abs() < ON_EDGE * h
                && combined.tool.signed_distance(q).abs() < ON_EDGE * h
        };
        // (The fitted point may lie just outside the cell: a corner in a
        // cell the surface enters without changing any sample's sign.)
        let corner = corners
            .iter()
            .map(|&q| clamp_near(&spec, c, q, 0.5 * h))
            .filter(|&q| on_both(q) && storage_for(field, c, q).is_some())
            .find(|&q| fan_fits(&*field, c, q));
        let fitted = corner
            .or_else(|| sharp_point(field, c, &tangents, cos_limit).filter(|&q| on_both(q)))
            .or_else(|| widened_point(field, c, &tangents, cos_limit, on_both))
            .or_else(|| {
                // A cell of several sheets: the new edge on one of them.
                cell_sheets(&*field, c).iter().find_map(|edges| {
                    sheet_edge_point(&spec, &combined, &crossings, c, edges, cos_limit, on_both)
                        .filter(|&p| fan_fits(&*field, c, p))
                })
            });
        let Some(p) = fitted.or_else(|| edge_point_in(&spec, &combined, c)) else {
            continue;
        };
        report.edge_points += 1;
        let fits = fitted.is_some() || fan_fits(&*field, c, p);
        if let (Some(n), true) = (storage_for(field, c, p), fits) {
            field.extras.insert(n, Extra::FeaturePoint(p));
            report.kept += 1;
        }
    }
    // Cells beside the new edges: feature points from the crossings'
    // tangent planes (of one sheet at a time).
    let taken: BTreeSet<usize> = field.feature_points().into_keys().collect();
    let sharp: Vec<(usize, DVec3)> = cells
        .par_iter()
        .filter(|c| !taken.contains(c))
        .filter_map(|&c| {
            (sheet_tangents(field, &crossings, c).iter())
                .find_map(|tangents| sharp_point(field, c, tangents, cos_limit))
                .map(|p| (c, p))
        })
        .collect();
    for (c, p) in sharp {
        if let Some(n) = storage_for(field, c, p) {
            field.extras.insert(n, Extra::FeaturePoint(p));
            report.kept += 1;
        }
    }
    // The old edges' points go back to cells the new edges and corners
    // left without one (a cell's one point keeps the new corner first).
    let taken: BTreeSet<usize> = field.feature_points().into_keys().collect();
    let mut displaced = Vec::new();
    for (c, p) in unhoused {
        match storage_for(field, c, p).filter(|_| !taken.contains(&c)) {
            Some(n) => {
                field.extras.insert(n, Extra::FeaturePoint(p));
            }
            None => {
                report.dropped += 1;
                displaced.push(p);
            }
        }
    }
    report.turned = choose_sides(field, &combined, &snapped, &old_features, &corners);
    report.repicked = repick(field, &combined, &cells, &old_features, &corners);
    report.repaired = repair(field, &combined, &surface, &cells, &old_features, &corners);
    // One or two points per cell leave corners and edges that only a
    // further point keeps: the tool's own edges first, then the old
    // edges' points (which may help only once the rim is kept).
    let offered = further::offers(field, &combined, &rim_corners, &displaced);
    report.further = further::add_further_points(
        field,
        &combined,
        &surface,
        &offered,
        &old_features,
        &all_corners,
    );
    // Where a cell holds several of the result's corners, they and the
    // samples' sides are changed together (no single change helps).
    report.corner_sets =
        further::add_corner_sets(field, &combined, &surface, &old_features, &all_corners);
    Ok(report)
}

/// The point on the new edge of one sheet of `cell` (its crossing
/// `edges`): the QEF point of the sheet's exact crossings alone (those of
/// all sheets mix a cap's rim with the pocket's floor 0.7 h above it),
/// moved onto the tool (on a cap's rim, whose tangent planes' QEF lies
/// 0.06 h outside the circle), where it lies on the new edge (`on_edge`)
/// within [`SHEET_POINT_MARGIN`] of the cell, moved into it.
fn sheet_edge_point(
    spec: &GridSpec<3>,
    combined: &Combined,
    crossings: &HashMap<(usize, usize), Tangent>,
    cell: usize,
    edges: &[(usize, usize)],
    cos_limit: f64,
    on_edge: impl Fn(DVec3) -> bool,
) -> Option<DVec3> {
    let tangents: Vec<Tangent> = (edges.iter())
        .filter_map(|edge| crossings.get(edge).copied())
        .collect();
    if tangents.len() < edges.len() || !crate::sharp::is_sharp(&tangents, cos_limit) {
        return None;
    }
    let q = combined
        .tool
        .closest_point(crate::sharp::qef_minimizer(&tangents)?);
    let point = nudge_into(spec, cell, q);
    let near = point.distance(q) <= SHEET_POINT_MARGIN * spec.spacing;
    (near && on_edge(q)).then_some(point)
}

/// The exact crossings of `cell`, one list per sheet where it holds
/// several: the tangent planes of a cap and of a pocket's floor 0.7 h
/// above it (opposite normals) have a QEF point between the two, 0.3 h
/// off both, whose fan ran across.
fn sheet_tangents(
    field: &UnifiedField,
    crossings: &HashMap<(usize, usize), Tangent>,
    cell: usize,
) -> Vec<Vec<Tangent>> {
    let sheets = cell_sheets(field, cell);
    if sheets.is_empty() {
        return vec![cell_tangents(&field.spec, crossings, cell)];
    }
    (sheets.iter())
        .map(|edges| {
            (edges.iter())
                .filter_map(|e| crossings.get(e).copied())
                .collect()
        })
        .collect()
}

/// How far outside its cell (spacings) a sheet's point on the new edge
/// may lie to be moved in (as [`WIDENED_MARGIN`]: a corner where an old
/// edge passes over a cap's rim lies just past a cell's face).
const SHEET_POINT_MARGIN: f64 = 0.1;

/// Directed distances for the edges whose exact crossing (`crossings`,
/// by edge) the interpolation between their samples misses by more than
/// `threshold` spacings, where the edge's lower sample can store one.
/// Returns the number stored anew.
fn store_directed(
    field: &mut UnifiedField,
    crossings: &HashMap<(usize, usize), Tangent>,
    threshold: f64,
) -> usize {
    let spec = field.spec;
    let h = spec.spacing;
    let mut stored = 0;
    let found: Vec<(usize, usize, f64)> = crossings
        .par_iter()
        .filter_map(|(&(n, axis), &(p, _))| {
            let m = n + spec.strides()[axis];
            let regular = !field.extras.contains_key(&(n as u32))
                || matches!(field.extras[&(n as u32)], Extra::Directed(_));
            let on_surface = matches!(field.extras.get(&(m as u32)), Some(Extra::Position(_)))
                && !field.floats(m);
            if !regular || on_surface {
                return None;
            }
            // To a floating sample the edge leaves the grid line: the
            // distance stored is the crossing's fraction of it, times h.
            let d = if field.floats(m) {
                let from = field.position(n);
                p.distance(from) / field.position(m).distance(from) * h
            } else {
                p[axis] - node_position(&spec, n)[axis]
            };
            let (a, b) = (field.values[n], field.values[m]);
            ((d - crossing_fraction(a, b, 0.0) * h).abs() > threshold * h).then_some((n, axis, d))
        })
        .collect();
    for (n, axis, d) in found {
        let entry = field
            .extras
            .entry(n as u32)
            .or_insert(Extra::Directed([f64::INFINITY; 3]));
        if let Extra::Directed(dirs) = entry {
            if dirs[axis] == f64::INFINITY {
                stored += 1;
            }
            dirs[axis] = d;
        }
    }
    stored
}

/// For each edge from a sample floating in a thin wall
/// ([`fill_thin_walls`]) to a sample not moved whose interpolated crossing
/// misses the exact one by more than `threshold` spacings (that sample's
/// distance is to another sheet, e.g. a pocket's side face above the
/// wall's floor, so the interpolation puts the floor 0.46 h too high on
/// fandisk − cylinder): the floating sample cannot store a directed
/// distance (it stores its position), so the other sample takes the value
/// that makes the interpolation exact — of the same sign, at most
/// [`MAX_STRAIGHTEN`] spacings, only where each of its edges that the
/// surface crosses will have its exact crossing or needs none
/// ([`edge_exact_after`]; the other floating edges into it within
/// `threshold`), and no cell around it changes its case (signs and the
/// faces' deciders). Returns the samples changed.
fn straighten_floating_edges(
    field: &mut UnifiedField,
    crossings: &HashMap<(usize, usize), Tangent>,
    threshold: f64,
) -> Vec<usize> {
    let spec = field.spec;
    let h = spec.spacing;
    let strides = spec.strides();
    let mut targets: BTreeMap<usize, f64> = BTreeMap::new();
    // In edge order: of several floating edges into one sample, the first
    // sets its value (the others must then stay within the threshold).
    let mut edges: Vec<(&(usize, usize), &Tangent)> = crossings.iter().collect();
    edges.sort_unstable_by_key(|e| *e.0);
    for (&(n, axis), &(p, _)) in edges {
        let m = n + strides[axis];
        let moved = matches!(field.extras.get(&(m as u32)), Some(Extra::Position(_)));
        if !field.floats(n) || moved {
            continue;
        }
        if floating_edge_error(field, n, m, p, field.values[m]) <= threshold * h {
            continue;
        }
        let (from, to) = (field.position(n), field.position(m));
        let t = p.distance(from) / to.distance(from);
        let v = field.values[n];
        targets.entry(m).or_insert(v * (t - 1.0) / t);
    }
    let mut changed = Vec::new();
    for (m, value) in targets {
        if value.abs() > MAX_STRAIGHTEN * h || (value < 0.0) != (field.values[m] < 0.0) {
            continue;
        }
        let cases = |field: &UnifiedField| {
            cells_around(&spec, m)
                .map(|c| cell_case(&corner_nodes(&spec, c).map(|k| field.values[k]), 0.0))
                .collect::<Vec<_>>()
        };
        let before = cases(field);
        let (old, stored) = (field.values[m], field.extras.clone());
        field.values[m] = value;
        let fits = cases(field) == before
            && (edges_at(&spec, m).into_iter())
                .all(|edge| edge_exact_after(field, crossings, edge, threshold));
        if fits {
            changed.push(m);
        } else {
            field.values[m] = old;
            field.extras = stored;
        }
    }
    changed
}

/// The grid edges at sample `m`, as (lower sample, axis).
fn edges_at(spec: &GridSpec<3>, m: usize) -> Vec<(usize, usize)> {
    let (idx, strides) = (spec.unlinear(m), spec.strides());
    let mut out = Vec::new();
    for axis in 0..3 {
        if idx[axis] + 1 < spec.dims[axis] {
            out.push((m, axis));
        }
        if idx[axis] > 0 {
            out.push((m - strides[axis], axis));
        }
    }
    out
}

/// Most a sample's value may be set to by [`straighten_floating_edges`]
/// (spacings; fandisk − cylinder needs 1.05 h where the distance is
/// 0.26 h).
const MAX_STRAIGHTEN: f64 = 1.5;

/// How far (length) the interpolated crossing on the edge from floating
/// sample `n` to `m`, with `m` at `value`, lies from the exact crossing `p`.
fn floating_edge_error(field: &UnifiedField, n: usize, m: usize, p: DVec3, value: f64) -> f64 {
    let t = crossing_fraction(field.values[n], value, 0.0);
    field.position(n).lerp(field.position(m), t).distance(p)
}

/// Whether edge `(n, axis)` (an edge of a sample whose value changed) will
/// have an exact crossing after [`store_directed`], or needs none: its
/// samples on one side, a sample moved onto the surface at its end, a
/// floating lower sample whose interpolation stays within `threshold`, or
/// the exact crossing known and the lower sample free to store it (a
/// feature point it holds handed to another sample of the point's cell,
/// see [`hand_over`]).
fn edge_exact_after(
    field: &mut UnifiedField,
    crossings: &HashMap<(usize, usize), Tangent>,
    (n, axis): (usize, usize),
    threshold: f64,
) -> bool {
    let m = n + field.spec.strides()[axis];
    if (field.values[n] >= 0.0) == (field.values[m] >= 0.0) {
        return true;
    }
    let on_surface = |k: usize| {
        matches!(field.extras.get(&(k as u32)), Some(Extra::Position(_))) && !field.floats(k)
    };
    if on_surface(n) || on_surface(m) {
        return true;
    }
    let Some(&(p, _)) = crossings.get(&(n, axis)) else {
        return false;
    };
    if field.floats(n) {
        return floating_edge_error(field, n, m, p, field.values[m])
            <= threshold * field.spec.spacing;
    }
    hand_over(field, n)
}

/// Construction's error-driven repair ([`crate::refine::repair`]) around
/// the changed `cells`, against the exact result: the combined distance
/// one way, points on the result the other (the object's surface where
/// the tool left it, the tool's where it cuts the object, the new edges
/// and corners). The rules above pick each cell's point by its own
/// crop; only the two-way error over a block sees what they leave, e.g.
/// a point that keeps the new edge but cuts an old one next door.
/// Returns the number of cells changed.
fn repair(
    field: &mut UnifiedField,
    combined: &Combined,
    surface: &TriMesh,
    cells: &[usize],
    old_features: &BTreeMap<usize, CellFeatures>,
    corners: &[DVec3],
) -> usize {
    let spec = field.spec;
    let features: BTreeMap<usize, CellFeatures> = cells
        .par_iter()
        .filter_map(|&c| {
            let f = result_cell_features(&spec, combined, c, old_features.get(&c), corners);
            (!f.bends.is_empty()).then_some((c, f))
        })
        .collect();
    let region: BTreeSet<usize> = cells
        .iter()
        .flat_map(|&c| crate::refine::block(&spec, c, 1))
        .collect();
    let points = result_points(&spec, combined, surface, &region)
        .into_iter()
        .chain(features.values().flat_map(|f| f.bends.iter().copied()));
    let samples = MeshSamples::from_points(&spec, points);
    crate::refine::repair(
        field,
        combined,
        &samples,
        &features,
        cells,
        crate::refine::TARGET,
    )
    .changed
}

/// The result's features in `cell` for the repair: every point of
/// [`result_features`] as a candidate, and the lines as pieces — the
/// object's old feature pieces where the tool leaves them (cut where it
/// takes them), and the new edge's points chained along it. A cell that
/// both cross (a new edge running beside an old ridge into the corner
/// where it pierces it) then counts two lines, and the repair may move a
/// sample onto the line its one point does not keep.
fn result_cell_features(
    spec: &GridSpec<3>,
    combined: &Combined,
    cell: usize,
    old: Option<&CellFeatures>,
    corners: &[DVec3],
) -> CellFeatures {
    let h = spec.spacing;
    let mut pieces = kept_pieces(
        old.map(|f| f.pieces.as_slice()).unwrap_or_default(),
        combined,
        h,
    );
    let edge = new_edge_points(spec, combined, cell);
    pieces.extend(chain_points(&edge, h));
    CellFeatures {
        bends: features_with_edge(spec, combined, cell, old, corners, edge),
        pieces,
        ..Default::default()
    }
}

/// The stretches of the object's feature segments `pieces` that lie on
/// the result (the `combined` distance within 1e-6 `h` of 0), each cut
/// back to its last point there; none shorter than that.
fn kept_pieces(pieces: &[[DVec3; 2]], combined: &Combined, h: f64) -> Vec<[DVec3; 2]> {
    let kept = |p: DVec3| combined.signed_distance(p).abs() < 1e-6 * h;
    (pieces.iter())
        .filter_map(|&[a, b]| match (kept(a), kept(b)) {
            (true, true) => Some([a, b]),
            (true, false) => Some([a, last_kept(a, b, kept)]),
            (false, true) => Some([last_kept(b, a, kept), b]),
            (false, false) => None,
        })
        .filter(|[a, b]| a.distance(*b) > 1e-6 * h)
        .collect()
}

/// The last point of segment `a`-`b` from `a` on which `kept` holds
/// (`kept(a)`, not `kept(b)`; bisection).
fn last_kept(a: DVec3, b: DVec3, kept: impl Fn(DVec3) -> bool) -> DVec3 {
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if kept(a.lerp(b, mid)) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    a.lerp(b, lo)
}

/// Points on one line, joined in order along it (their widest spread;
/// within a cell a new edge is nearly straight) into pieces sharing
/// their ends, near duplicates left out.
fn chain_points(points: &[DVec3], h: f64) -> Vec<[DVec3; 2]> {
    let Some((a, b)) = points
        .iter()
        .flat_map(|&p| points.iter().map(move |&q| (p, q)))
        .max_by(|x, y| x.0.distance(x.1).total_cmp(&y.0.distance(y.1)))
    else {
        return Vec::new();
    };
    let along = b - a;
    let mut sorted = points.to_vec();
    sorted.sort_by(|p, q| (*p - a).dot(along).total_cmp(&(*q - a).dot(along)));
    sorted.dedup_by(|p, q| p.distance(*q) < 1e-3 * h);
    sorted.windows(2).map(|w| [w[0], w[1]]).collect()
}

/// Lattice points per axis and cell projected onto the tool for
/// [`result_points`].
const TOOL_SAMPLES: usize = 4;

/// Points on the exact result in the cells of `region`: the object's
/// surface points (as [`MeshSamples`] takes them) and projections onto
/// the tool of a lattice in each cell, where the result keeps them.
fn result_points(
    spec: &GridSpec<3>,
    combined: &Combined,
    surface: &TriMesh,
    region: &BTreeSet<usize>,
) -> Vec<DVec3> {
    let h = spec.spacing;
    let kept = |p: &DVec3| {
        crate::features::cell_of(spec, *p).is_some_and(|c| region.contains(&c))
            && combined.signed_distance(*p).abs() < 1e-3 * h
    };
    let object: Vec<DVec3> = mesh_points(surface).collect();
    let mut points: Vec<DVec3> = object.into_par_iter().filter(kept).collect();
    let step = h / TOOL_SAMPLES as f64;
    let region: Vec<usize> = region.iter().copied().collect();
    // Only cells the tool's surface passes through have its points.
    let touched = |c: &&usize| {
        let centre = node_position(spec, **c) + DVec3::splat(0.5 * h);
        combined.tool.signed_distance(centre).abs() <= 0.5 * 3f64.sqrt() * h
    };
    points.par_extend(region.par_iter().filter(touched).flat_map_iter(|&c| {
        let lo = node_position(spec, c) + DVec3::splat(0.5 * step);
        let n = TOOL_SAMPLES;
        (0..n * n * n).filter_map(move |k| {
            let at =
                lo + DVec3::new((k % n) as f64, ((k / n) % n) as f64, (k / (n * n)) as f64) * step;
            let p = combined.tool.closest_point(at);
            kept(&p).then_some(p)
        })
    }));
    points
}

impl Exact for Combined<'_> {
    fn signed_distance(&self, p: DVec3) -> f64 {
        Combined::signed_distance(self, p)
    }

    fn tangents(&self, field: &UnifiedField, cell: usize) -> Vec<Tangent> {
        let spec = &field.spec;
        let h = spec.spacing;
        let nodes = corner_nodes(spec, cell);
        EDGE_CORNERS
            .iter()
            .filter_map(|&[a, b]| {
                let axis = (a ^ b).trailing_zeros() as usize;
                let p = edge_crossing(field, self, nodes[a as usize], axis)?;
                Some((p, self.normal(p, h)?))
            })
            .collect()
    }
}

/// A sample moved onto a new corner sits on the surface and may count as
/// either side; which one decides how the crossing loops of its cells
/// join. Keep the side whose cells' triangles lie nearer the result, both
/// ways (the largest of the result's features' distances to them and of
/// their distances to the result), where topology allows both. Returns
/// the number of samples turned to the other side.
fn choose_sides(
    field: &mut UnifiedField,
    combined: &Combined,
    snapped: &[DVec3],
    old_features: &BTreeMap<usize, CellFeatures>,
    corners: &[DVec3],
) -> usize {
    let spec = field.spec;
    let h = spec.spacing;
    let cube = Neighbourhood::new(&spec.strides());
    let mut turned = 0;
    for p in snapped {
        let Some(n) = field
            .extras
            .iter()
            .find_map(|(&n, e)| (*e == Extra::Position(*p)).then_some(n as usize))
        else {
            continue;
        };
        let other = if field.values[n] < 0.0 {
            0.0
        } else {
            -1e-9 * h
        };
        if !may_take(&cube, n, other, |m| field.values[m]) {
            continue;
        }
        let error = |field: &UnifiedField| {
            let points = field.feature_points();
            cells_around(&spec, n)
                .filter(|&c| crosses(&spec, &field.values, c))
                .map(|c| {
                    let triangles = cell_triangles(field, c, points.get(&c).copied());
                    let probes = result_features(&spec, combined, c, old_features.get(&c), corners);
                    farthest_from(&triangles, &probes).max(farthest_off(combined, &triangles))
                })
                .fold(0.0, f64::max)
        };
        let before = error(field);
        let old = std::mem::replace(&mut field.values[n], other);
        if error(field) < before - SIDE_GAIN * h {
            turned += 1;
        } else {
            field.values[n] = old;
        }
    }
    turned
}

/// The other side must bring the cells' triangles nearer the result by
/// this many spacings.
const SIDE_GAIN: f64 = 0.01;

/// Changed cells with a new edge or corner re-pick their feature point
/// by [`repick_cell`] from the result's feature points in the cell,
/// scored both ways against the exact result. Returns the number of
/// cells changed.
fn repick(
    field: &mut UnifiedField,
    combined: &Combined,
    cells: &[usize],
    old_features: &BTreeMap<usize, CellFeatures>,
    corners: &[DVec3],
) -> usize {
    let spec = field.spec;
    let h = spec.spacing;
    let mut changed = 0;
    let points = field.feature_points();
    for &c in cells {
        let probes = result_features(&spec, combined, c, old_features.get(&c), corners);
        let old_count = old_features.get(&c).map_or(0, |f| f.probes().len());
        // An old point the tool left may now stand off the sheet the
        // cell's crossings bound (an old edge just above a new cap): its
        // fan strays from the result, so it is weighed like a new one.
        let strays = points.get(&c).is_some_and(|&p| {
            farthest_off(combined, &cell_triangles(&*field, c, Some(p))) > STRAY_FAN * h
        });
        if probes.len() <= old_count && !strays {
            continue; // no new edge or corner here
        }
        let error = |triangles: &[[DVec3; 3]]| {
            farthest_from(triangles, &probes).max(farthest_off(combined, triangles))
        };
        let step = (probes.len() / 12).max(1);
        changed += repick_cell(field, c, probes.iter().copied().step_by(step), error) as usize;
    }
    changed
}

/// A cell's fan farther than this many spacings off the result is
/// weighed again by [`repick`] even where no new feature crosses it.
const STRAY_FAN: f64 = 0.25;

/// Points on the sharp features of the result in `cell`: the object's
/// old features that the tool left, the new corners, and points on the
/// new edge (where object and tool meet).
fn result_features(
    spec: &GridSpec<3>,
    combined: &Combined,
    cell: usize,
    old: Option<&CellFeatures>,
    corners: &[DVec3],
) -> Vec<DVec3> {
    let edge = new_edge_points(spec, combined, cell);
    features_with_edge(spec, combined, cell, old, corners, edge)
}

/// [`result_features`] given the new edge's points in the cell.
fn features_with_edge(
    spec: &GridSpec<3>,
    combined: &Combined,
    cell: usize,
    old: Option<&CellFeatures>,
    corners: &[DVec3],
    edge: Vec<DVec3>,
) -> Vec<DVec3> {
    let h = spec.spacing;
    let lo = node_position(spec, cell);
    let inside = |p: DVec3| (p - lo).min_element() >= 0.0 && (p - lo).max_element() <= h;
    let mut probes: Vec<DVec3> = old
        .map(|f| f.probes())
        .unwrap_or_default()
        .into_iter()
        .filter(|&p| combined.signed_distance(p).abs() < 1e-6 * h)
        .collect();
    probes.extend(corners.iter().copied().filter(|&p| inside(p)));
    probes.extend(edge);
    probes
}

/// Points on the new edge (where object and tool meet) in `cell`.
fn new_edge_points(spec: &GridSpec<3>, combined: &Combined, cell: usize) -> Vec<DVec3> {
    let h = spec.spacing;
    let lo = node_position(spec, cell);
    let inside = |p: DVec3| (p - lo).min_element() >= 0.0 && (p - lo).max_element() <= h;
    // A new edge lies on both surfaces: both pass within half a diagonal
    // of the cell's centre (a cheap test before searching for it).
    let centre = lo + DVec3::splat(0.5 * h);
    let reach = 0.5 * 3f64.sqrt() * h;
    if combined.tool.signed_distance(centre).abs() > reach
        || combined.object.signed_distance(centre).abs() > reach
    {
        return Vec::new();
    }
    (0..27)
        .map(|k| lo + DVec3::new((k % 3) as f64, ((k / 3) % 3) as f64, (k / 9) as f64) * (0.5 * h))
        .filter_map(|s| combined.edge_point(s, 1e-6 * h))
        .filter(|&p| inside(p) && combined.tool.signed_distance(p).abs() < 1e-6 * h)
        .collect()
}

/// The largest distance of triangles (sampled at their corners, edge
/// midpoints and centroids) from the combined surface.
fn farthest_off(combined: &Combined, triangles: &[[DVec3; 3]]) -> f64 {
    triangles
        .iter()
        .flat_map(|&[a, b, c]| {
            [
                a,
                b,
                c,
                (a + b) * 0.5,
                (b + c) * 0.5,
                (c + a) * 0.5,
                (a + b + c) / 3.0,
            ]
        })
        .map(|p| combined.signed_distance(p).abs())
        .fold(0.0, f64::max)
}

/// Where the sharp edges of `surface` (the object as its field represents
/// it) pierce the tool: the corners a new edge makes with an old one.
fn new_corners(surface: &TriMesh, features: &Features, tool: &Tool) -> Vec<DVec3> {
    features
        .edges
        .iter()
        .filter_map(|&[a, b]| {
            let (mut p, mut q) = (surface.vertices[a as usize], surface.vertices[b as usize]);
            let inside = tool.signed_distance(p) < 0.0;
            if inside == (tool.signed_distance(q) < 0.0) {
                return None;
            }
            for _ in 0..48 {
                let mid = p.lerp(q, 0.5);
                if (tool.signed_distance(mid) < 0.0) == inside {
                    p = mid;
                } else {
                    q = mid;
                }
            }
            Some(p.lerp(q, 0.5))
        })
        .collect()
}

/// The exact crossings of the combined surface on `cell`'s sign-changing
/// edges with its outward normals, from `crossings` (by edge).
fn cell_tangents(
    spec: &GridSpec<3>,
    crossings: &HashMap<(usize, usize), Tangent>,
    cell: usize,
) -> Vec<Tangent> {
    let nodes = corner_nodes(spec, cell);
    EDGE_CORNERS
        .iter()
        .filter_map(|&[a, b]| {
            let axis = (a ^ b).trailing_zeros() as usize;
            crossings.get(&(nodes[a as usize], axis)).copied()
        })
        .collect()
}

/// Where the combined surface crosses the edge from sample `n` along
/// `+axis`, if its samples lie on different sides. The edge runs between
/// the samples' positions where one floats inside a thin wall
/// ([`fill_thin_walls`]); otherwise, as before, along the grid (a sample
/// moved onto the surface is its own crossing there).
fn edge_crossing(
    field: &UnifiedField,
    combined: &Combined,
    n: usize,
    axis: usize,
) -> Option<DVec3> {
    let spec = &field.spec;
    let h = spec.spacing;
    let m = n + spec.strides()[axis];
    if (field.values[n] >= 0.0) == (field.values[m] >= 0.0) {
        return None;
    }
    if field.floats(n) || field.floats(m) {
        return segment_root(combined, field.position(n), field.position(m));
    }
    let origin = node_position(spec, n);
    let mut p = origin;
    p[axis] += edge_root(combined, origin, axis, h)?;
    Some(p)
}

/// Where the combined distance changes sign on segment `a`-`b`
/// (bisection), if its ends lie on different sides.
fn segment_root(combined: &Combined, a: DVec3, b: DVec3) -> Option<DVec3> {
    let inside = |t: f64| combined.signed_distance(a.lerp(b, t)) < 0.0;
    (inside(0.0) != inside(1.0)).then(|| a.lerp(b, bisect(0.0, 1.0, inside)))
}

/// Distance along `+axis` from `origin` to the combined surface within
/// one spacing (bisection on the exact combined distance).
fn edge_root(combined: &Combined, origin: DVec3, axis: usize, h: f64) -> Option<f64> {
    let inside = |t: f64| {
        let mut p = origin;
        p[axis] += t;
        combined.signed_distance(p) < 0.0
    };
    (inside(0.0) != inside(h)).then(|| bisect(0.0, h, inside))
}

/// The parameter in [`lo`, `hi`] where `inside` changes (bisection, 48
/// halvings); `inside(lo)` and `inside(hi)` differ.
fn bisect(mut lo: f64, mut hi: f64, inside: impl Fn(f64) -> bool) -> f64 {
    let start = inside(lo);
    for _ in 0..48 {
        let mid = 0.5 * (lo + hi);
        if inside(mid) == start {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Where the result has a wall (or a gap) thinner than a cell between
/// two samples on the same side (a tool's flat cap a fraction of a cell
/// below an object's face), no edge of the grid crosses it and marching
/// cubes leaves it out: the surfaces on both sides of it vanish, a full
/// cell and more off. For each such edge touching a changed sample, the
/// endpoint nearer the wall moves into it (as an offset field's sample,
/// within its own box) and takes the result's distance there, so the
/// edges from it cross both faces of the wall. Moves that would leave a
/// cell not convex, or a feature point without a sample, are not made;
/// nor into the thin tips of wedges ([`is_wall`]). Returns the samples
/// moved.
fn fill_thin_walls(field: &mut UnifiedField, combined: &Combined, changed: &[usize]) -> Vec<usize> {
    let spec = field.spec;
    let h = spec.spacing;
    let strides = spec.strides();
    let edges = edges_at_samples(&spec, changed);
    let found: Vec<(f64, usize, DVec3)> = edges
        .par_iter()
        .filter_map(|&(n, axis)| {
            let m = n + strides[axis];
            let (a, b) = (field.values[n], field.values[m]);
            // Both samples' distances bound how near the surface comes:
            // a wall between them needs their sum below a spacing.
            if (a < 0.0) != (b < 0.0) || a.abs() + b.abs() >= h {
                return None;
            }
            let (pa, pb) = (field.position(n), field.position(m));
            let (depth, p) = deepest_across(combined, pa, pb, a < 0.0, h)?;
            // The nearer sample moves (within half a spacing of its node).
            let node = if p.distance(node_position(&spec, n)) <= p.distance(node_position(&spec, m))
            {
                n
            } else {
                m
            };
            Some((depth, node, p))
        })
        .collect();
    let mut found = found;
    // Deepest first: a sample beside two walls takes the thicker.
    found.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
    let mut moved = Vec::new();
    for (_, node, p) in found {
        let value = combined.signed_distance(p);
        if !may_fill(&spec, combined, node, p, value, |m| field.position(m))
            // A feature point it holds goes to another sample of its cell.
            || !crate::refine::hand_over(field, node)
        {
            continue;
        }
        field.values[node] = value;
        field.extras.insert(node as u32, Extra::Position(p));
        moved.push(node);
    }
    moved
}

/// The grid edges (lower sample, axis) touching any of `samples`.
fn edges_at_samples(spec: &GridSpec<3>, samples: &[usize]) -> BTreeSet<(usize, usize)> {
    let strides = spec.strides();
    let mut edges = BTreeSet::new();
    for &n in samples {
        let idx = spec.unlinear(n);
        for axis in 0..3 {
            if idx[axis] > 0 {
                edges.insert((n - strides[axis], axis));
            }
            if idx[axis] + 1 < spec.dims[axis] {
                edges.insert((n, axis));
            }
        }
    }
    edges
}

/// [`fill_thin_walls`] for an offset field, whose samples may sit on the
/// surface: a grid edge passes through a wall when its samples lie on one
/// side with the result crossing twice between them, or when one sample
/// lies on the surface (within [`ON_SURFACE`]) and the result crosses
/// well before it (a cap below an object's concave edge, whose sample is
/// the wall's far face: interpolation puts the edge's only crossing at
/// that sample and the near face is lost). A sample off the surface
/// moves to the wall's deepest point within its box and takes the
/// result's distance there, deepest walls first. Without this the fit
/// that follows keeps whatever sides min/max gave the samples (its moves
/// keep the topology): the wall between fandisk's face and a cylinder's
/// cap a fraction of a cell below it stayed pierced.
fn fill_thin_walls_odf(
    field: &mut OffsetField,
    combined: &Combined,
    changed: &[usize],
) -> Vec<usize> {
    let spec = field.spec;
    let strides = spec.strides();
    let edges = edges_at_samples(&spec, changed);
    let mut found: Vec<(f64, usize, DVec3)> = edges
        .par_iter()
        .flat_map_iter(|&(n, axis)| odf_wall_places(field, combined, n, n + strides[axis]))
        .collect();
    found.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
    let mut moved = Vec::new();
    for (_, node, p) in found {
        let value = combined.signed_distance(p);
        if moved.contains(&node)
            || !may_fill(&spec, combined, node, p, value, |m| field.position_of(m))
        {
            continue;
        }
        field.values[node] = value;
        field.moved.insert(node as u32, p);
        moved.push(node);
    }
    moved
}

/// A sample this many spacings or nearer the surface counts as on it.
const ON_SURFACE: f64 = 0.01;

/// Where the samples of grid edge `n`-`m` could go into a wall the edge
/// passes through (see [`fill_thin_walls_odf`]): for each sample off the
/// surface, the wall's deepest point within its box, with its depth.
fn odf_wall_places(
    field: &OffsetField,
    combined: &Combined,
    n: usize,
    m: usize,
) -> Vec<(f64, usize, DVec3)> {
    let spec = &field.spec;
    let h = spec.spacing;
    let (a, b) = (field.values[n], field.values[m]);
    let (pa, pb) = (field.position_of(n), field.position_of(m));
    let on_surface = |v: f64| v.abs() < ON_SURFACE * h;
    let length = pa.distance(pb);
    let changes = || sign_changes(combined, pa, pb, h);
    // The wall as distances from `pa`, and the side it is not on.
    let wall = if (a < 0.0) == (b < 0.0) {
        if a.abs() + b.abs() >= h {
            return Vec::new();
        }
        match changes()[..] {
            [t0, t1, ..] => (t0, t1, a < 0.0),
            _ => return Vec::new(),
        }
    } else if on_surface(b) && !on_surface(a) && a.abs() < h {
        match changes().first() {
            Some(&t0) if length - t0 >= 2.0 * WALL_DEPTH * h => (t0, length, a < 0.0),
            _ => return Vec::new(),
        }
    } else if on_surface(a) && !on_surface(b) && b.abs() < h {
        match changes().last() {
            Some(&t1) if t1 >= 2.0 * WALL_DEPTH * h => (0.0, t1, b < 0.0),
            _ => return Vec::new(),
        }
    } else {
        return Vec::new();
    };
    let (t0, t1, inside) = wall;
    let half = 0.5 * h * (1.0 - 1e-6);
    let along = (pb - pa) / length;
    [(n, a), (m, b)]
        .into_iter()
        .filter(|&(_, v)| !on_surface(v))
        .filter_map(|(k, _)| {
            // The part of the wall inside the sample's box.
            let home = node_position(spec, k);
            let (lo, hi) = box_span(pa - home, along, half);
            let (lo, hi) = (t0.max(lo), t1.min(hi));
            (lo < hi)
                .then(|| deepest_between(combined, pa, pb, lo, hi, inside))?
                .map(|(depth, p)| (depth, k, p))
        })
        .collect()
}

/// The distances along a ray from `start` (relative to a box's centre)
/// in unit `direction` between which it lies in the box of half-width
/// `half`.
fn box_span(start: DVec3, direction: DVec3, half: f64) -> (f64, f64) {
    (0..3).fold((f64::NEG_INFINITY, f64::INFINITY), |(lo, hi), k| {
        if direction[k] == 0.0 {
            return if start[k].abs() <= half {
                (lo, hi)
            } else {
                (f64::INFINITY, f64::NEG_INFINITY)
            };
        }
        let (s, t) = (
            (-half - start[k]) / direction[k],
            (half - start[k]) / direction[k],
        );
        (lo.max(s.min(t)), hi.min(s.max(t)))
    })
}

/// Whether sample `node` may move into the wall at `p` (at distance
/// `value` from the result): not on the outer layer, within its box, a
/// wall by [`is_wall`], and its cells stay convex.
fn may_fill(
    spec: &GridSpec<3>,
    combined: &Combined,
    node: usize,
    p: DVec3,
    value: f64,
    position: impl Fn(usize) -> DVec3,
) -> bool {
    let h = spec.spacing;
    let reach = (p - node_position(spec, node)).abs().max_element();
    !on_outer_layer(spec, node)
        && reach < 0.5 * h
        && is_wall(combined, p, value, h)
        && stays_convex(spec, node, p, position)
}

/// Whether the thin place around `p` (at distance `value` from the
/// result's surface) is a wall worth a sample: at least [`WALL_DEPTH`]
/// deep, and not the tip of a wedge where the tool meets the object at
/// a shallow angle (those lie within [`WEDGE_RATIO`] times their depth of
/// the new edge, whose feature points keep them; a sample moved into one
/// breaks their fans: fandisk − sphere went from 0.10 to 0.36 h).
fn is_wall(combined: &Combined, p: DVec3, value: f64, h: f64) -> bool {
    let depth = value.abs();
    depth >= WALL_DEPTH * h
        && combined
            .edge_point(p, 1e-6 * h)
            .is_none_or(|q| q.distance(p) > WEDGE_RATIO * depth)
}

/// Least half-thickness (spacings) of a wall a sample is moved into.
const WALL_DEPTH: f64 = 0.1;
/// A thin place nearer the new edge than this many times its depth is a
/// wedge, not a wall (the wedges of the tuned cases: 1.2-2.3).
const WEDGE_RATIO: f64 = 4.0;

/// Smallest step (spacings) of the marches along a segment: walls thinner
/// than this are left out.
const MARCH_STEP: f64 = 0.01;

/// The points where the combined distance changes sign along `a`-`b`,
/// marching by the distance itself (a lower bound of the distance to the
/// surface, so no crossing further apart than [`MARCH_STEP`] is missed).
fn sign_changes(combined: &Combined, a: DVec3, b: DVec3, h: f64) -> Vec<f64> {
    let length = a.distance(b);
    let mut out = Vec::new();
    let mut t = 0.0;
    let mut side = combined.signed_distance(a) < 0.0;
    while t < length {
        let d = combined.signed_distance(a.lerp(b, t / length));
        if (d < 0.0) != side {
            out.push(t);
            side = d < 0.0;
        }
        t += d.abs().max(MARCH_STEP * h);
    }
    if (combined.signed_distance(b) < 0.0) != side {
        out.push(length);
    }
    out
}

/// A wall on the other side than `inside` that segment `a`-`b` (both
/// ends on side `inside`) passes through: its deepest point sampled
/// along the segment and how deep it is.
fn deepest_across(
    combined: &Combined,
    a: DVec3,
    b: DVec3,
    inside: bool,
    h: f64,
) -> Option<(f64, DVec3)> {
    let changes = sign_changes(combined, a, b, h);
    let [t0, t1, ..] = changes[..] else {
        return None;
    };
    deepest_between(combined, a, b, t0, t1, inside)
}

/// The deepest point of the other side than `inside` sampled on
/// `a`-`b` between distances `t0` and `t1` from `a`, and its depth.
fn deepest_between(
    combined: &Combined,
    a: DVec3,
    b: DVec3,
    t0: f64,
    t1: f64,
    inside: bool,
) -> Option<(f64, DVec3)> {
    let length = a.distance(b);
    (0..=16)
        .map(|k| a.lerp(b, (t0 + (t1 - t0) * k as f64 / 16.0) / length))
        .map(|p| (combined.signed_distance(p), p))
        .filter(|&(d, _)| (d < 0.0) != inside)
        .map(|(d, p)| (d.abs(), p))
        .max_by(|x, y| x.0.total_cmp(&y.0))
}

/// A result side counts as known at a face's centre only this many
/// spacings or more from the surface.
const FACE_MARGIN: f64 = 0.02;
/// A raised sample's product exceeds the other diagonal's by this factor.
const RAISE_MARGIN: f64 = 1.05;
/// A sample is raised to at most this many spacings.
const MAX_RAISE: f64 = 1.0;

/// The four samples of a grid face in cyclic order (`0`-`2` and `1`-`3`
/// are its diagonals): the face through `base` normal to `axis`.
fn face_nodes(spec: &GridSpec<3>, base: usize, axis: usize) -> [usize; 4] {
    let s = spec.strides();
    let (u, v) = (s[(axis + 1) % 3], s[(axis + 2) % 3]);
    [base, base + u, base + u + v, base + v]
}

/// The faces a sample is a corner of, as (lowest sample, normal axis).
fn faces_at(spec: &GridSpec<3>, node: usize) -> Vec<(usize, usize)> {
    let idx = spec.unlinear(node);
    let s = spec.strides();
    let mut out = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for (du, dv) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let fits = |k: usize, d: usize| idx[k] >= d && idx[k] - d + 1 < spec.dims[k];
            if fits(u, du) && fits(v, dv) {
                out.push((node - du * s[u] - dv * s[v], axis));
            }
        }
    }
    out
}

/// Whether the grid's asymptotic decider joins the outside samples of a
/// face whose signs alternate (the same rule as marching cubes').
fn decider_joins_outside(v: [f64; 4]) -> bool {
    let (even, odd) = (v[0] * v[2], v[1] * v[3]);
    if v[0] >= 0.0 {
        even >= odd
    } else {
        odd >= even
    }
}

/// For a face whose samples alternate in sign and whose decider joins
/// the pair the exact result does not: the side (true: outside) the
/// result joins, judged by its sign at the face's centre (the samples'
/// mean position), when that lies clearly off the surface.
fn misjoined(field: &UnifiedField, combined: &Combined, nodes: [usize; 4]) -> Option<bool> {
    let v = nodes.map(|n| field.values[n]);
    let outside = v.map(|x| x >= 0.0);
    if !(outside[0] == outside[2] && outside[1] == outside[3] && outside[0] != outside[1]) {
        return None;
    }
    let centre = nodes.iter().map(|&n| field.position(n)).sum::<DVec3>() / 4.0;
    let d = combined.signed_distance(centre);
    let joined = d >= 0.0;
    (d.abs() >= FACE_MARGIN * field.spec.spacing && joined != decider_joins_outside(v))
        .then_some(joined)
}

/// How many faces at `node` are misjoined ([`misjoined`]).
fn misjoined_at(field: &UnifiedField, combined: &Combined, node: usize) -> usize {
    faces_at(&field.spec, node)
        .into_iter()
        .filter(|&(base, axis)| {
            misjoined(field, combined, face_nodes(&field.spec, base, axis)).is_some()
        })
        .count()
}

/// Faces of `cells` whose samples alternate in sign, where the decider
/// joins the other diagonal than the exact result (e.g. a hole and an old
/// pocket on either side of a wall thinner than a cell, through which the
/// decider would open a slot: a handle). The sample values are distances
/// the interpolation reads only between samples, and sculpting stores
/// exact crossings on the cells' edges afterwards; so one sample of the
/// diagonal to join has its magnitude raised just enough that its
/// diagonal's product wins — a plain sample (no moved position or feature
/// point, whose edges can then store their crossings), the least raise
/// first, at most [`MAX_RAISE`] spacings, kept only if fewer faces around
/// it are misjoined afterwards. Returns the samples raised.
fn settle_ambiguous_faces(
    field: &mut UnifiedField,
    combined: &Combined,
    cells: &[usize],
) -> Vec<usize> {
    let spec = field.spec;
    let h = spec.spacing;
    let s = spec.strides();
    let faces: BTreeSet<(usize, usize)> = cells
        .iter()
        .flat_map(|&c| (0..3).flat_map(move |axis| [(c, axis), (c + s[axis], axis)]))
        .collect();
    let wrong: Vec<[usize; 4]> = faces
        .par_iter()
        .map(|&(base, axis)| face_nodes(&spec, base, axis))
        .filter(|&nodes| misjoined(field, combined, nodes).is_some())
        .collect();
    let mut raised = Vec::new();
    for nodes in wrong {
        // An earlier raise may have settled it.
        let Some(outside) = misjoined(field, combined, nodes) else {
            continue;
        };
        let first = usize::from((field.values[nodes[0]] >= 0.0) != outside);
        let (pair, other) = (
            [nodes[first], nodes[first + 2]],
            [nodes[1 - first], nodes[3 - first]],
        );
        let beaten = (field.values[other[0]] * field.values[other[1]]).abs();
        let plain = |n: usize| {
            !on_outer_layer(&spec, n)
                && matches!(
                    field.extras.get(&(n as u32)),
                    None | Some(Extra::Directed(_))
                )
        };
        let choice = [(pair[0], pair[1]), (pair[1], pair[0])]
            .into_iter()
            .filter(|&(n, m)| plain(n) && field.values[n] != 0.0 && field.values[m] != 0.0)
            .map(|(n, m)| (n, RAISE_MARGIN * beaten / field.values[m].abs()))
            .filter(|&(_, target)| target <= MAX_RAISE * h)
            .min_by(|x, y| {
                let ratio = |&(n, t): &(usize, f64)| t / field.values[n].abs();
                ratio(x).total_cmp(&ratio(y))
            });
        let Some((n, target)) = choice else {
            continue;
        };
        let before = misjoined_at(field, combined, n);
        let old = field.values[n];
        field.values[n] = target.copysign(old);
        if misjoined_at(field, combined, n) < before {
            raised.push(n);
        } else {
            field.values[n] = old;
        }
    }
    raised.sort_unstable();
    raised.dedup();
    raised
}

/// Sculpt an offset field: combine at the samples' positions, move
/// samples into walls thinner than a cell ([`fill_thin_walls_odf`]), put
/// the samples whose boxes the new edge (and the new corners) pass through
/// onto it ([`aligned::align_to_new_edge`]), then fit the samples around
/// them to the exact result ([`aligned::fit_around_new_edge`]), as
/// construction aligns and fits samples to a mesh's features.
pub fn sculpt_odf(
    field: &mut OffsetField,
    operation: Operation,
    tool: &Tool,
) -> Result<SculptReport, DistFieldError> {
    let surface = field.raw_surface();
    let combined = Combined::new(&surface, tool, operation)?;
    let spec = field.spec;
    let h = spec.spacing;
    let features = Features::detect(&surface, DEFAULT_FEATURE_ANGLE_DEG);
    let old_features = cells_with_features(&surface, &features, &spec, |_| true);
    let mut corners = new_corners(&surface, &features, tool);
    corners.extend(further::tool_corners(tool, &combined.object, h));
    let mut segments = aligned::new_edge_segments(&surface, tool);
    segments.extend(further::tool_edge_segments(&combined, h));
    let (changed, _, mut report) = combine(field, |f| &mut f.values, operation, tool);
    let walls = fill_thin_walls_odf(field, &combined, &changed);
    report.thin = walls.len();
    let aligned = aligned::align_to_new_edge(field, &combined, &segments, &corners);
    report.edge_points = aligned.offered;
    report.kept = aligned.moved.len();
    let cells = aligned::result_cells(field, &combined, &segments, &corners, &old_features);
    // The fit's moves would take the wall's samples onto its faces, where
    // they keep its side but not its thickness: they stay.
    let mut pinned = aligned::pinned_samples(field, &combined, &cells, &aligned.moved);
    pinned.extend(walls);
    report.fitted = aligned::fit_around_new_edge(field, &combined, &surface, &cells, &pinned);
    Ok(report)
}
