//! Unified distance field (UDF): a regular grid of signed distances where a
//! sample stores extra data only where the plain distances would lose the
//! shape:
//! - the exact distances along +x, +y, +z to the surface, where the linear
//!   interpolation of two samples misplaces an edge crossing by more than
//!   a threshold (curved or sharp parts);
//! - one point on a sharp feature (a corner, or a point on a feature edge)
//!   of a cell the sample is a corner of, which extraction fans around;
//! - or the sample's own moved position, as in an offset field.
//!
//! Every sample keeps its minimum distance, which is what lets the kinds
//! mix: extraction interpolates it wherever nothing more is stored.

use crate::extract::{
    corner_nodes, fan_fits, fan_triangles, leans_on_neighbour, ExtractReport, SampledField,
};
use crate::features::{cells_with_features, nudge_into, CellFeatures, Features};
use crate::offset::{may_take, node_position, stays_convex};
use crate::query::MeshQuery;
use crate::sharp::{clamp_near, is_sharp, owner_cell, qef_minimizer, Tangent};
use crate::{check_mesh, grid_for, DistFieldError};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::time::Instant;
use surfrecon_geom::metrics::closest_point_on_triangle;
use surfrecon_geom::{DVec3, TriMesh};
use surfrecon_grid::marching::crossing_fraction;
use surfrecon_grid::sdf::signed_distance;
use surfrecon_grid::topology::Neighbourhood;
use surfrecon_grid::{GridSize, GridSpec};

/// Store directed distances where interpolation errs by more than this
/// many grid spacings (the paper's 0.1).
pub const DEFAULT_THRESHOLD: f64 = 0.1;

/// Beside feature points, directed distances are stored where
/// interpolation errs by more than this many spacings (or the threshold,
/// if smaller): fandisk's max error 0.177 h with 0.02, also with 0.05,
/// 0.181 h with 0.01 (0.194 h without).
const NEAR_FEATURE_THRESHOLD: f64 = 0.02;

/// Angle (degrees) between crossing normals above which a cell without
/// mesh features takes the QEF point of its crossings (or the feature
/// angle, if smaller): fandisk 0.177 h with 20° and 24°, but 0.101 h
/// instead of 0.135 h at the second-worst place with 20°.
const CREASE_ANGLE_DEG: f64 = 20.0;

/// Distances are exact within this many cells of the surface and clamped
/// beyond (signs stay right everywhere).
pub(crate) const BAND_CELLS: f64 = 3.0;

/// The extra data one sample may carry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Extra {
    /// Distances from the sample along +x, +y, +z to the surface;
    /// infinite where that edge has no stored crossing.
    Directed([f64; 3]),
    /// A point on a sharp feature inside one of the sample's cells (the
    /// cell containing the point).
    FeaturePoint(DVec3),
    /// The sample's own position, moved off its grid node within its cell.
    Position(DVec3),
}

/// A unified distance field.
#[derive(Debug, Clone, PartialEq)]
pub struct UnifiedField {
    pub spec: GridSpec<3>,
    /// Signed distance per sample (negative inside), node order.
    pub values: Vec<f64>,
    /// Extra data of the samples that need it, by sample index.
    pub extras: BTreeMap<u32, Extra>,
    /// Further feature points of cells (by their lowest sample's index)
    /// beyond the one or two their samples store: a cell holding two
    /// corners, or two lines and a sheet, whose samples all carry extra
    /// data already. Extraction fans each of a cell's sheets, and each
    /// run of a sheet's crossing loop, around its own point (see
    /// [`crate::extract::extract_points`]). Empty for almost every field.
    pub cell_points: BTreeMap<u32, Vec<DVec3>>,
}

/// How to build a unified field.
#[derive(Debug, Clone, Copy)]
pub struct UdfOptions {
    pub size: GridSize,
    /// Cells of padding around the mesh's bounds.
    pub padding: usize,
    /// Interpolation error (grid spacings) above which directed distances
    /// are stored.
    pub threshold: f64,
    /// Angle between face normals above which an edge is sharp.
    pub feature_angle_deg: f64,
}

impl Default for UdfOptions {
    fn default() -> Self {
        Self {
            size: GridSize::Resolution(64),
            padding: 2,
            threshold: DEFAULT_THRESHOLD,
            feature_angle_deg: crate::features::DEFAULT_FEATURE_ANGLE_DEG,
        }
    }
}

/// What building a unified field stored.
#[derive(Debug, Clone, Copy, Default)]
pub struct UdfReport {
    pub samples: usize,
    /// Cells the surface passes through.
    pub boundary_cells: usize,
    /// Cells a feature edge or corner passes through.
    pub feature_cells: usize,
    pub directed: usize,
    pub feature_points: usize,
    pub positions: usize,
    /// Of the feature points, those of cells without a mesh feature inside
    /// whose crossings' normals differ by more than 20° or
    /// the feature angle (a sharp edge runs beside them, or a crease
    /// gentler than the feature angle through them).
    pub sharp_cells: usize,
    /// Cells crossed by separate feature lines whose point was changed
    /// for one whose surrounding surface lies nearer the mesh.
    pub repicked: usize,
    /// Changes the error-driven repair made ([`crate::refine`]): feature
    /// points replaced or removed, samples turned or moved.
    pub repaired: usize,
    /// Directed distances given up because all corners of a feature cell
    /// already carried extra data.
    pub directed_dropped: usize,
    pub seconds: f64,
}

/// Build the unified field of a closed, outward-oriented mesh.
pub fn build_udf(
    mesh: &TriMesh,
    options: &UdfOptions,
) -> Result<(UnifiedField, UdfReport), DistFieldError> {
    let start = Instant::now();
    check_mesh(mesh)?;
    if options.threshold.is_nan() || options.threshold < 0.0 {
        return Err(DistFieldError::InvalidOption(format!(
            "the directed-distance threshold must be at least 0, not {}",
            options.threshold
        )));
    }
    let spec = grid_for(mesh, options.size, options.padding)?;
    // The mesh's index, features and samples need no field: they are
    // made while the distances are (which leave a core idle at times).
    let (values, (query, (features, samples))) = rayon::join(
        || signed_distance(mesh, &spec, Some(BAND_CELLS * spec.spacing)),
        || {
            rayon::join(
                || MeshQuery::new(mesh),
                || {
                    rayon::join(
                        || Features::detect(mesh, options.feature_angle_deg),
                        || crate::refine::MeshSamples::new(mesh, &spec),
                    )
                },
            )
        },
    );
    let (values, query) = (values?.values, query?);
    let mut field = UnifiedField {
        spec,
        values,
        extras: BTreeMap::new(),
        cell_points: BTreeMap::new(),
    };
    let mut report = UdfReport {
        samples: field.values.len(),
        ..Default::default()
    };
    for (node, directed) in directed_distances(&field, &query, options.threshold) {
        field.extras.insert(node, Extra::Directed(directed));
        report.directed += 1;
    }
    let corners: Vec<DVec3> = features
        .corners
        .iter()
        .map(|&v| mesh.vertices[v as usize])
        .collect();
    let snapped = snap_corners(&mut field, &corners);
    let mut cells = cells_with_features(mesh, &features, &field.spec, |c| field.crosses(c));
    for f in cells.values_mut() {
        f.corners.retain(|p| !snapped.contains(p));
        f.bends.retain(|p| !snapped.contains(p));
        f.near_corners.retain(|p| !snapped.contains(p));
    }
    report.feature_cells = cells.len();
    report.positions = snapped.len();
    for (cell, f) in &cells {
        let Some(centroid) = crossing_centroid(&field, &query, *cell) else {
            continue;
        };
        // A corner in a neighbour no patch reaches comes first, as it is
        // (the cell's fan reaches out to it, from a sample that can hold
        // it); the rest lie in the cell.
        let margin = SHARP_MARGIN * field.spec.spacing;
        let near = f
            .near_corners
            .iter()
            .map(|&p| clamp_near(&field.spec, *cell, p, margin))
            .filter(|&p| storage_for(&field, *cell, p).is_some());
        let inside = f
            .candidates(centroid)
            .into_iter()
            .map(|p| nudge_into(&field.spec, *cell, p));
        // Where the cell holds separate feature lines (one point keeps
        // one), of the points whose fans fit, the one whose fan passes
        // nearest all of them; elsewhere the first that fits.
        let nearest_all = || {
            let probes = f.probes();
            inside
                .clone()
                .filter_map(|p| {
                    let fan = fan_triangles(&field, *cell, p)?;
                    Some((farthest_from(&fan, &probes), p))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .map(|(_, p)| p)
        };
        let first_fitting = || inside.clone().find(|&p| fan_fits(&field, *cell, p));
        let Some(point) = near
            .clone()
            .find(|&p| fan_fits(&field, *cell, p))
            .or_else(|| {
                if f.lines() > 1 {
                    nearest_all()
                } else {
                    first_fitting()
                }
            })
            .or_else(|| inside.clone().next())
        else {
            continue;
        };
        if let Some(node) = storage_for(&field, *cell, point) {
            field.extras.insert(node, Extra::FeaturePoint(point));
            report.feature_points += 1;
            continue;
        }
        let corners = corner_nodes(&field.spec, *cell);
        let free = corners
            .iter()
            .find(|&&n| !field.extras.contains_key(&(n as u32)));
        let node = *free.unwrap_or(&corners[0]) as u32;
        if let Some(Extra::Directed(_)) = field.extras.insert(node, Extra::FeaturePoint(point)) {
            report.directed -= 1;
            report.directed_dropped += 1;
        }
        report.feature_points += 1;
    }
    // Crossings bend sharply also at creases gentler than the feature
    // angle (fandisk's blends meet its faces at 28°, 0.14 h off without
    // a point there): cells without mesh features take a QEF point from
    // 20° on.
    let crease = options.feature_angle_deg.min(CREASE_ANGLE_DEG);
    let (sharp, creased) = sharp_cell_points(&field, &query, &cells, crease.to_radians().cos());
    for (cell, point) in sharp {
        if let Some(node) = storage_for(&field, cell, point) {
            field.extras.insert(node, Extra::FeaturePoint(point));
            report.feature_points += 1;
            report.sharp_cells += 1;
        }
    }
    report.repicked = repick_multi_line(&mut field, &query, &cells);
    let near = options.threshold.min(NEAR_FEATURE_THRESHOLD);
    report.directed += directed_near_features(&mut field, &query, near);
    let repaired = crate::refine::repair(
        &mut field,
        &query,
        &samples,
        &cells,
        &creased,
        crate::refine::TARGET,
    );
    report.repaired = repaired.changed;
    // The repair replaces stored data (a directed sample given a feature
    // point, a point removed, a sample moved): count what the file holds.
    let stored = |f: fn(&Extra) -> bool| field.extras.values().filter(|e| f(e)).count();
    report.directed = stored(|e| matches!(e, Extra::Directed(_)));
    report.feature_points = stored(|e| matches!(e, Extra::FeaturePoint(_)))
        + field.cell_points.values().map(Vec::len).sum::<usize>();
    report.positions = stored(|e| matches!(e, Extra::Position(_)));
    report.boundary_cells = field.boundary_cells();
    report.seconds = start.elapsed().as_secs_f64();
    Ok((field, report))
}

/// Put the nearest sample exactly on each corner (when that keeps its
/// cells convex and the sample carries nothing else but directed
/// distances), so marching cubes reaches the corner from every cell
/// around it; a fan around one cell's feature point often folds at a
/// pointed corner. The sample's distance is 0, signed against most of its
/// neighbours so that the edges to them cross the surface at the corner,
/// but on the side of at least one of them, so it never becomes an island.
/// Corners whose sample has all neighbours on one side are left to fans.
/// Returns the corners taken.
pub(crate) fn snap_corners(field: &mut UnifiedField, corners: &[DVec3]) -> Vec<DVec3> {
    let spec = field.spec;
    let cube = Neighbourhood::new(&spec.strides());
    let mut snapped = Vec::new();
    for &q in corners {
        let g = spec.to_grid(q.to_array());
        let idx: [usize; 3] = std::array::from_fn(|a| g[a].round().max(0.0) as usize);
        if (0..3).any(|a| idx[a] == 0 || idx[a] + 1 >= spec.dims[a]) {
            continue;
        }
        let n = spec.linear(idx);
        if field
            .extras
            .get(&(n as u32))
            .is_some_and(|e| !matches!(e, Extra::Directed(_)))
            || !stays_convex(&spec, n, q, |m| field.position(m))
        {
            continue;
        }
        if q == node_position(&spec, n) {
            // Already exact: the sample sits on the corner.
            snapped.push(q);
            continue;
        }
        let strides = spec.strides();
        let neighbours = (0..3)
            .flat_map(|a| [n - strides[a], n + strides[a]])
            .map(|m| field.values[m]);
        // Marching cubes counts 0 as outside. With all six neighbours on
        // one side no edge would cross at the corner (a tip thinner than a
        // cell): leave it to a fan.
        let inside = neighbours.filter(|&v| v < 0.0).count();
        if inside == 0 || inside == 6 {
            continue;
        }
        let value = if inside < 3 {
            -1e-9 * spec.spacing
        } else {
            0.0
        };
        if !may_take(&cube, n, value, |m| field.values[m]) {
            continue;
        }
        field.values[n] = value;
        field.extras.insert(n as u32, Extra::Position(q));
        snapped.push(q);
    }
    snapped
}

/// Cells crossed by separate feature lines, where one point keeps one
/// line: each re-picks its point by [`repick_cell`], scored by the cell's
/// feature probes' distance to the surface and the surface's distance to
/// the mesh. The choice above (by the cell's own fan) cannot see the
/// flips that join its point to its neighbours'. Returns the number of
/// cells changed.
fn repick_multi_line(
    field: &mut UnifiedField,
    query: &MeshQuery,
    cells: &BTreeMap<usize, CellFeatures>,
) -> usize {
    let mut changed = 0;
    for (&c, f) in cells.iter().filter(|(_, f)| f.lines() > 1) {
        let Some(centroid) = crossing_centroid(field, query, c) else {
            continue;
        };
        let probes = f.probes();
        let error = |triangles: &[[DVec3; 3]]| {
            let off = sample_points(triangles)
                .map(|p| query.signed_distance(p).abs())
                .fold(0.0, f64::max);
            farthest_from(triangles, &probes).max(off)
        };
        let candidates = f.candidates(centroid);
        let step = (candidates.len() / 16).max(1);
        changed += repick_cell(field, c, candidates.into_iter().step_by(step), error) as usize;
    }
    changed
}

/// Points at which [`repick_cell`]'s callers measure triangles against
/// the exact surface: centroids and edge midpoints.
pub(crate) fn sample_points(triangles: &[[DVec3; 3]]) -> impl Iterator<Item = DVec3> + '_ {
    triangles.iter().flat_map(|&[a, b, c]| {
        [
            (a + b + c) / 3.0,
            (a + b) * 0.5,
            (b + c) * 0.5,
            (c + a) * 0.5,
        ]
    })
}

/// A cell may need a point other than the one its own fan suggests: of
/// its current feature point, none (its table triangles) and the
/// `candidates` whose fan fits, keep the one for which `error` of the
/// surface within half a cell of the cell is smallest (by at least 0.01
/// spacings against the current one). That surface is extracted from a
/// crop of 8³ samples around the cell, so fans, merges into a neighbour's
/// fan and the flips that join feature points all count. Returns whether
/// the cell's point changed.
pub(crate) fn repick_cell(
    field: &mut UnifiedField,
    cell: usize,
    candidates: impl Iterator<Item = DVec3>,
    error: impl Fn(&[[DVec3; 3]]) -> f64,
) -> bool {
    let spec = field.spec;
    let h = spec.spacing;
    let idx = spec.unlinear(cell);
    if (0..3).any(|a| idx[a] < 3 || idx[a] + 5 > spec.dims[a]) {
        return false;
    }
    let now = field.feature_points().get(&cell).copied();
    if now.is_some_and(|p| crate::features::cell_of(&spec, p) != Some(cell)) {
        return false; // a point beside the cell: its merged fan stays
    }
    let score = |field: &UnifiedField| error(&surface_near(field, cell, 0.5));
    let stored = field.extras.iter().find_map(|(&m, e)| match *e {
        Extra::FeaturePoint(q) if now == Some(q) => Some(m),
        _ => None,
    });
    let mut best = (score(field) - 0.01 * h, now);
    if let Some(m) = stored {
        field.extras.remove(&m);
    }
    let options = std::iter::once(None).chain(candidates.map(|p| Some(nudge_into(&spec, cell, p))));
    for option in options {
        let node = match option {
            Some(p) => match storage_for(field, cell, p) {
                Some(m) if fan_fits(&*field, cell, p) => {
                    field.extras.insert(m, Extra::FeaturePoint(p));
                    Some(m)
                }
                _ => continue,
            },
            None => None,
        };
        let e = score(field);
        if e < best.0 {
            best = (e, option);
        }
        if let Some(m) = node {
            field.extras.remove(&m);
        }
    }
    if let Some(p) = best.1 {
        let node = if best.1 == now {
            stored
        } else {
            storage_for(field, cell, p)
        };
        if let Some(m) = node {
            field.extras.insert(m, Extra::FeaturePoint(p));
        }
    }
    best.1 != now
}

/// The triangles within half a cell of `cell` (by their centroids) of
/// the surface extracted from a crop of 8³ samples around it, so that
/// fans, merges into a neighbour's fan and the flips that join feature
/// points all show. `cell` must lie 3 cells inside the grid.
pub(crate) fn surface_near(field: &UnifiedField, cell: usize, reach: f64) -> Vec<[DVec3; 3]> {
    let spec = field.spec;
    let h = spec.spacing;
    let lo = node_position(&spec, cell) - DVec3::splat(reach * h);
    let hi = lo + DVec3::splat((1.0 + 2.0 * reach) * h);
    local_surface(field, spec.unlinear(cell).map(|i| i - 3), 8)
        .into_iter()
        .filter(|&[a, b, c]| {
            let m = (a + b + c) / 3.0;
            m.cmpge(lo).all() && m.cmple(hi).all()
        })
        .collect()
}

/// The surface of the block of `side`³ samples of `field` from sample
/// `lo` on (the triangles near the block's border may differ from the
/// whole field's).
pub(crate) fn local_surface(field: &UnifiedField, lo: [usize; 3], side: usize) -> Vec<[DVec3; 3]> {
    let mesh = crop(field, lo, side).raw_surface();
    (0..mesh.triangles.len()).map(|t| mesh.corners(t)).collect()
}

/// The block of `side`³ samples of `field` from sample `lo` on, as a
/// field of its own.
pub(crate) fn crop(field: &UnifiedField, lo: [usize; 3], side: usize) -> UnifiedField {
    let spec = field.spec;
    let mut values = Vec::with_capacity(side * side * side);
    let mut extras = BTreeMap::new();
    let mut cell_points = BTreeMap::new();
    for k in 0..side {
        for j in 0..side {
            for i in 0..side {
                let n = spec.linear([lo[0] + i, lo[1] + j, lo[2] + k]);
                if let Some(e) = field.extras.get(&(n as u32)) {
                    extras.insert(values.len() as u32, *e);
                }
                // A cell of the crop has its lowest sample in it and no
                // sample on the crop's last layers.
                if let Some(points) = field.cell_points.get(&(n as u32)) {
                    if i + 1 < side && j + 1 < side && k + 1 < side {
                        cell_points.insert(values.len() as u32, points.clone());
                    }
                }
                values.push(field.values[n]);
            }
        }
    }
    UnifiedField {
        spec: GridSpec {
            origin: spec.position(lo),
            spacing: spec.spacing,
            dims: [side; 3],
        },
        values,
        extras,
        cell_points,
    }
}

/// Samples with an edge crossing that interpolation misplaces by more than
/// `threshold` spacings, with their exact distances along the three axes.
fn directed_distances(
    field: &UnifiedField,
    query: &MeshQuery,
    threshold: f64,
) -> Vec<(u32, [f64; 3])> {
    let h = field.spec.spacing;
    (0..field.values.len())
        .into_par_iter()
        .filter_map(|node| {
            let (directed, error) = exact_crossings(field, query, node);
            (error > threshold * h).then_some((node as u32, directed))
        })
        .collect()
}

/// The exact distances from sample `node` along +x, +y, +z to the
/// surface on its sign-changing edges (infinite on the others), and the
/// largest distance by which interpolating the two samples misplaces one.
fn exact_crossings(field: &UnifiedField, query: &MeshQuery, node: usize) -> ([f64; 3], f64) {
    let spec = &field.spec;
    let h = spec.spacing;
    let strides = spec.strides();
    let idx = spec.unlinear(node);
    let mut directed = [f64::INFINITY; 3];
    let mut error = 0.0f64;
    for axis in (0..3).filter(|&a| idx[a] + 1 < spec.dims[a]) {
        let (a, b) = (field.values[node], field.values[node + strides[axis]]);
        if (a >= 0.0) == (b >= 0.0) {
            continue;
        }
        let origin = DVec3::from_array(spec.position(idx));
        if let Some(d) = query.hit_along(origin, axis, h) {
            directed[axis] = d;
            error = error.max((d - crossing_fraction(a, b, 0.0) * h).abs());
        }
    }
    (directed, error)
}

/// Beside sharp features a crossing misplaced by less than the threshold
/// still folds the surface: a fan triangle from a feature point to it
/// turns (0.09 h under fandisk's ridge on a face 0.04 h from a grid plane
/// kept the flip that joins two feature points from happening, 0.17 h).
/// So the corners of the cells with a feature point store their exact
/// crossings where interpolation errs by more than `threshold` spacings;
/// a corner that holds the cell's feature point hands it to another
/// corner that can hold it and needs nothing itself. Returns how many
/// were stored.
fn directed_near_features(field: &mut UnifiedField, query: &MeshQuery, threshold: f64) -> usize {
    let h = field.spec.spacing;
    let mut nodes: Vec<usize> = field
        .feature_points()
        .keys()
        .flat_map(|&c| corner_nodes(&field.spec, c))
        .filter(|&n| {
            !matches!(
                field.extras.get(&(n as u32)),
                Some(Extra::Directed(_) | Extra::Position(_))
            )
        })
        .collect();
    nodes.sort_unstable();
    nodes.dedup();
    let found: Vec<(u32, [f64; 3])> = nodes
        .into_par_iter()
        .filter_map(|node| {
            let (directed, error) = exact_crossings(field, query, node);
            (error > threshold * h).then_some((node as u32, directed))
        })
        .collect();
    let needy: std::collections::HashSet<u32> = found.iter().map(|f| f.0).collect();
    let mut count = 0;
    for (node, directed) in found {
        if let Some(&Extra::FeaturePoint(p)) = field.extras.get(&node) {
            let Some(cell) = owner_cell(&field.spec, node as usize, p) else {
                continue;
            };
            let other = corner_nodes(&field.spec, cell).into_iter().find(|&m| {
                !needy.contains(&(m as u32))
                    && !field.extras.contains_key(&(m as u32))
                    && owner_cell(&field.spec, m, p) == Some(cell)
            });
            let Some(m) = other else { continue };
            field.extras.insert(m as u32, Extra::FeaturePoint(p));
        }
        field.extras.insert(node, Extra::Directed(directed));
        count += 1;
    }
    count
}

/// The largest distance from `points` to the triangles.
pub(crate) fn farthest_from(triangles: &[[DVec3; 3]], points: &[DVec3]) -> f64 {
    points
        .iter()
        .map(|&p| {
            triangles
                .iter()
                .map(|&t| p.distance(closest_point_on_triangle(p, t)))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}

/// How far outside its cell a feature point found from the crossings may
/// lie (in spacings): a sharp edge passing just beside a cell is where its
/// patch must reach.
const SHARP_MARGIN: f64 = 0.5;

/// Feature points for the boundary cells that have no mesh feature inside
/// but whose crossings' normals differ by more than the feature angle:
/// the QEF minimizer of the crossings' tangent planes, within
/// [`SHARP_MARGIN`] of the cell, where the cell's fan around it fits.
/// Also the cells without mesh features whose crossings' normals differ
/// by more than a crease ([`crate::refine::CREASE_COS`]), for the repair.
fn sharp_cell_points(
    field: &UnifiedField,
    query: &MeshQuery,
    featured: &BTreeMap<usize, CellFeatures>,
    cos_limit: f64,
) -> (Vec<(usize, DVec3)>, Vec<usize>) {
    let spec = &field.spec;
    let [nx, ny, nz] = spec.dims;
    let found: Vec<(usize, Option<DVec3>)> = (0..nz - 1)
        .into_par_iter()
        .flat_map_iter(|k| {
            let cells = (0..ny - 1).flat_map(move |j| (0..nx - 1).map(move |i| [i, j, k]));
            cells.filter_map(|idx| {
                let cell = spec.linear(idx);
                if featured.contains_key(&cell) || !field.crosses(cell) {
                    return None;
                }
                let tangents = crossing_tangents(field, query, cell);
                is_sharp(&tangents, crate::refine::CREASE_COS)
                    .then(|| (cell, sharp_point(field, cell, &tangents, cos_limit)))
            })
        })
        .collect();
    let points = found.iter().filter_map(|&(c, p)| Some((c, p?))).collect();
    (points, found.into_iter().map(|(c, _)| c).collect())
}

/// The feature point of `cell` from its crossings' `tangents` when their
/// normals differ by more than the angle whose cosine is `cos_limit`: the
/// QEF minimizer within [`SHARP_MARGIN`] of the cell, if the cell's fan
/// around it fits or it lies in a crossed neighbour (whose fan the cell
/// then joins at extraction, which checks it there).
pub(crate) fn sharp_point(
    field: &UnifiedField,
    cell: usize,
    tangents: &[Tangent],
    cos_limit: f64,
) -> Option<DVec3> {
    if !is_sharp(tangents, cos_limit) {
        return None;
    }
    let spec = &field.spec;
    let point = clamp_near(
        spec,
        cell,
        qef_minimizer(tangents)?,
        SHARP_MARGIN * spec.spacing,
    );
    (leans_on_neighbour(field, cell, point) || fan_fits(field, cell, point)).then_some(point)
}

/// A sample of `cell` free to store `point` as the cell's feature point
/// (one whose cells put `point` in `cell`, see [`owner_cell`]).
pub(crate) fn storage_for(field: &UnifiedField, cell: usize, point: DVec3) -> Option<u32> {
    corner_nodes(&field.spec, cell)
        .into_iter()
        .find(|&n| {
            !field.extras.contains_key(&(n as u32))
                && owner_cell(&field.spec, n, point) == Some(cell)
        })
        .map(|n| n as u32)
}

/// The exact crossings on a cell's sign-changing edges with the surface
/// normal there (outward: from the inside sample to the outside one).
pub(crate) fn crossing_tangents(
    field: &UnifiedField,
    query: &MeshQuery,
    cell: usize,
) -> Vec<Tangent> {
    crossed_edges(field, cell)
        .filter_map(|(origin, axis, va, _)| {
            let (d, n) = query.hit_with_normal(origin, axis, field.spec.spacing)?;
            let mut p = origin;
            p[axis] += d;
            let n = if (n[axis] > 0.0) == (va < 0.0) { n } else { -n };
            Some((p, n))
        })
        .collect()
}

/// The mean of the exact crossings on a cell's sign-changing edges.
fn crossing_centroid(field: &UnifiedField, query: &MeshQuery, cell: usize) -> Option<DVec3> {
    let h = field.spec.spacing;
    let (mut sum, mut count) = (DVec3::ZERO, 0);
    for (origin, axis, va, vb) in crossed_edges(field, cell) {
        let d = query
            .hit_along(origin, axis, h)
            .unwrap_or_else(|| crossing_fraction(va, vb, 0.0) * h);
        let mut p = origin;
        p[axis] += d;
        sum += p;
        count += 1;
    }
    (count > 0).then(|| sum / count as f64)
}

/// The sign-changing edges of `cell`: the position of the edge's lower
/// sample, the edge's axis, and the two samples' values.
fn crossed_edges(
    field: &UnifiedField,
    cell: usize,
) -> impl Iterator<Item = (DVec3, usize, f64, f64)> + '_ {
    let spec = &field.spec;
    let nodes = corner_nodes(spec, cell);
    surfrecon_grid::marching::tables::EDGE_CORNERS
        .into_iter()
        .filter_map(move |[a, b]| {
            let (na, nb) = (nodes[a as usize], nodes[b as usize]);
            let (va, vb) = (field.values[na], field.values[nb]);
            let origin = DVec3::from_array(spec.position(spec.unlinear(na)));
            ((va >= 0.0) != (vb >= 0.0))
                .then(|| (origin, (a ^ b).trailing_zeros() as usize, va, vb))
        })
}

impl UnifiedField {
    /// Whether the surface crosses `cell` (its corners' signs differ).
    pub fn crosses(&self, cell: usize) -> bool {
        crate::extract::crosses(&self.spec, &self.values, cell)
    }

    /// Cells the surface passes through.
    pub fn boundary_cells(&self) -> usize {
        let [nx, ny, nz] = self.spec.dims;
        (0..nz - 1)
            .into_par_iter()
            .map(|k| {
                let cells = (0..ny - 1).flat_map(|j| (0..nx - 1).map(move |i| [i, j, k]));
                cells
                    .filter(|&idx| self.crosses(self.spec.linear(idx)))
                    .count()
            })
            .sum()
    }

    /// Feature points by their cell (see [`owner_cell`]).
    pub fn feature_points(&self) -> BTreeMap<usize, DVec3> {
        let far = FAR_FROM_OWNER * self.spec.spacing;
        self.extras
            .iter()
            .filter_map(|(&n, e)| match *e {
                Extra::FeaturePoint(p) => owner_cell(&self.spec, n as usize, p)
                    .filter(|&c| outside_cell(&self.spec, c, p) <= far)
                    .map(|c| (c, p)),
                _ => None,
            })
            .collect()
    }

    /// Whether sample `node` was moved off its grid node to a place off
    /// the surface (not onto a corner or feature line, where its distance
    /// is 0).
    pub fn floats(&self, node: usize) -> bool {
        matches!(self.extras.get(&(node as u32)), Some(Extra::Position(_)))
            && self.values[node].abs() > FLOAT_OFF_SURFACE * self.spec.spacing
    }

    /// The surface: marching cubes with the stored crossings, positions
    /// and feature fans.
    pub fn extract(&self) -> (TriMesh, ExtractReport) {
        let first = self.feature_points();
        let more = self.more_points();
        crate::extract::extract_points(self, &first, &self.second_points(&first), &more)
    }

    /// The surface before extraction's last steps (see
    /// [`crate::extract::raw_surface`]): what construction and sculpting
    /// score and decide on, in crops many times over.
    pub(crate) fn raw_surface(&self) -> TriMesh {
        let first = self.feature_points();
        let more = self.more_points();
        crate::extract::raw_surface(self, &first, &self.second_points(&first), &more)
    }

    /// [`Self::cell_points`] by cell as extraction takes them.
    pub fn more_points(&self) -> BTreeMap<usize, Vec<DVec3>> {
        (self.cell_points.iter())
            .map(|(&c, points)| (c as usize, points.clone()))
            .collect()
    }

    /// Per cell owning two feature points (two feature lines through it),
    /// the one [`Self::feature_points`] does not give.
    pub fn second_points(&self, first: &BTreeMap<usize, DVec3>) -> BTreeMap<usize, DVec3> {
        self.extras
            .iter()
            .filter_map(|(&n, e)| match *e {
                Extra::FeaturePoint(p) => owner_cell(&self.spec, n as usize, p)
                    .filter(|c| first.get(c).is_some_and(|&f| f != p))
                    .map(|c| (c, p)),
                _ => None,
            })
            .collect()
    }
}

/// Distance (spacings) from the surface beyond which a moved sample
/// counts as floating ([`UnifiedField::floats`]); samples moved onto the
/// surface hold ±1e-9 h or 0.
const FLOAT_OFF_SURFACE: f64 = 1e-6;

/// How far (in spacings) a stored feature point may lie outside the cell
/// it belongs to ([`owner_cell`]) and still be fanned. Construction's lie
/// within 0.28 h (fandisk); a few sculpted points lay 0.7-0.9 h away
/// (two cells from the sheet they were meant for), and their fans
/// crossed the neighbours' triangles (fandisk − sphere: 8 of its 18
/// crossing pairs).
const FAR_FROM_OWNER: f64 = 0.5;

/// Distance from `p` to the box of `cell`.
fn outside_cell(spec: &GridSpec<3>, cell: usize, p: DVec3) -> f64 {
    let lo = DVec3::from_array(spec.position(spec.unlinear(cell)));
    let hi = lo + DVec3::splat(spec.spacing);
    (lo - p).max(p - hi).max(DVec3::ZERO).length()
}

impl SampledField for UnifiedField {
    fn spec(&self) -> &GridSpec<3> {
        &self.spec
    }
    fn value(&self, node: usize) -> f64 {
        self.values[node]
    }
    fn position(&self, node: usize) -> DVec3 {
        match self.extras.get(&(node as u32)) {
            Some(Extra::Position(p)) => *p,
            _ => DVec3::from_array(self.spec.position(self.spec.unlinear(node))),
        }
    }
    fn crossing(&self, node: usize, axis: usize) -> Option<DVec3> {
        let Some(Extra::Directed(d)) = self.extras.get(&(node as u32)) else {
            return None;
        };
        // Directed distances were measured between grid nodes, except
        // towards a sample floating off the surface (sculpting moves one
        // into a wall thinner than a cell): there d / h is the fraction of
        // the edge to it. A sample moved onto the surface is its edges'
        // crossing itself.
        let other = node + self.spec.strides()[axis];
        if !d[axis].is_finite() {
            return None;
        }
        let from = self.position(node);
        match self.extras.get(&(other as u32)) {
            Some(Extra::Position(q)) if self.floats(other) => {
                Some(from.lerp(*q, d[axis] / self.spec.spacing))
            }
            Some(Extra::Position(_)) => None,
            _ => {
                let mut p = from;
                p[axis] += d[axis];
                Some(p)
            }
        }
    }
}
