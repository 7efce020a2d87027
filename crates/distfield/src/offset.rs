//! Offset distance field (ODF): one sample per grid node, each free to
//! float within its own cell (the box of half a spacing around its node),
//! so that samples can sit on the corners and edges a regular grid cuts.
//!
//! Samples start on their nodes with the regular signed distances. The
//! samples around cells crossed by sharp features (and around those
//! cells' neighbours near the surface) then move to minimize
//!   E = λ_d E_dist + λ_s Σ_edges (1 − |g_i − g_j| / h)² + λ_o Σ (ê_i · ê_j)²
//! where E_dist sums, over the probes of each such cell (its corners,
//! bends and points along its feature edge pieces, and where the true
//! surface crosses lines through it), the squared distance to the
//! triangles marching cubes makes, plus the squared distances from those
//! triangles back to the true surface (in units of h²). For a move of one
//! sample the probes of its eight cells are measured against the surface
//! of all eight: a sample moving onto a cell face carries the surface
//! into the next cell. The spring term keeps grid edges near their rest
//! length h and the orthogonality term keeps the edges at a sample (and
//! at its neighbours) perpendicular. The search is the paper's: per
//! sample try ±x, ±y, ±z steps (plus a jump onto a feature point in
//! reach, onto the nearest surface point, and the other side for a sample
//! on the surface), take the best legal move, halve the step each round;
//! after the first round only samples next to one that moved are tried.
//! Before it, the samples whose boxes a feature passes through are put
//! onto it (corners first) and stay there (the paper's alignment of
//! samples with features); on a convex feature such a sample goes outside
//! first, on a concave one inside. A move is legal when the sample stays
//! in its box, every cell around it stays convex and the surface in its
//! cells keeps its topology. Samples of the same index parity share no
//! cell and no energy term, so each parity class moves in parallel and
//! the result does not depend on the thread count.

use crate::extract::{corner_nodes, crosses, extract, ExtractReport, SampledField};
use crate::features::{
    cells_with_features, clip_to_cells, closest_on_segment, CellFeatures, Features,
};
use crate::query::MeshQuery;
use crate::refine::block;
use crate::unified::BAND_CELLS;
use crate::{check_mesh, grid_for, DistFieldError};
use rayon::prelude::*;

mod repair;
pub(crate) use repair::{repair as repair_samples, MeshPoints, THINNED};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::time::Instant;
use surfrecon_geom::metrics::closest_point_on_triangle;
use surfrecon_geom::{DVec3, TriMesh};
use surfrecon_grid::marching::tables::cube_table;
use surfrecon_grid::marching::tables::EDGE_CORNERS;
use surfrecon_grid::marching::{cell_case, crossing_fraction};
use surfrecon_grid::sdf::signed_distance;
use surfrecon_grid::topology::Neighbourhood;
use surfrecon_grid::{GridSize, GridSpec};

/// The weights of the three energy terms.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Weights {
    pub distance: f64,
    pub spring: f64,
    pub ortho: f64,
}

impl Default for Weights {
    fn default() -> Self {
        Self {
            distance: 1.0,
            spring: 0.1,
            ortho: 0.1,
        }
    }
}

impl Weights {
    /// Error unless every weight is finite and not negative, and the
    /// distance term (the one that draws samples to the surface) is on.
    pub fn validate(&self) -> Result<(), DistFieldError> {
        let invalid = |name: &str, value: f64, range: &str| {
            DistFieldError::InvalidOption(format!("the {name} weight must be {range}, not {value}"))
        };
        if !(self.distance.is_finite() && self.distance > 0.0) {
            return Err(invalid("distance", self.distance, "a positive number"));
        }
        for (name, value) in [("spring", self.spring), ("ortho", self.ortho)] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(invalid(name, value, "a number ≥ 0"));
            }
        }
        Ok(())
    }
}

/// How to build an offset field.
#[derive(Debug, Clone, Copy)]
pub struct OdfOptions {
    pub size: GridSize,
    pub padding: usize,
    pub feature_angle_deg: f64,
    pub weights: Weights,
    /// Rounds of the search; the step halves every round from h/4.
    pub iterations: usize,
}

/// Rounds of the search by default. Steps below h/32 only nudge
/// thousands of samples (fandisk at 64 cells: 8 rounds moved 14,108
/// samples for the same maximum and mean error as 4 rounds' 9,967, in
/// twice the search time).
pub const DEFAULT_ITERATIONS: usize = 4;

/// More rounds would step by less than h/10⁶, far below any error.
pub const MAX_ITERATIONS: usize = 20;

impl Default for OdfOptions {
    fn default() -> Self {
        Self {
            size: GridSize::Resolution(64),
            padding: 2,
            feature_angle_deg: crate::features::DEFAULT_FEATURE_ANGLE_DEG,
            weights: Weights::default(),
            iterations: DEFAULT_ITERATIONS,
        }
    }
}

/// An offset distance field.
#[derive(Debug, Clone, PartialEq)]
pub struct OffsetField {
    pub spec: GridSpec<3>,
    /// Signed distance at each sample's position (negative inside).
    pub values: Vec<f64>,
    /// Positions of the samples that moved off their nodes.
    pub moved: BTreeMap<u32, DVec3>,
}

/// What building an offset field did.
#[derive(Debug, Clone, Copy, Default)]
pub struct OdfReport {
    pub samples: usize,
    pub feature_cells: usize,
    /// Samples the search considered.
    pub candidates: usize,
    /// Samples put onto a corner or a feature edge before the search.
    pub aligned: usize,
    pub moved: usize,
    /// Samples moved by Laplacian smoothing away from the surface.
    pub smoothed: usize,
    /// Places where the surface strayed from the mesh by more than
    /// 0.1 h after the search, and moves the repair kept there.
    pub repair_places: usize,
    pub repaired: usize,
    /// Total E_dist (each cell's probes against its own triangles) of
    /// the fitted cells, the feature cells and their neighbours near the
    /// surface, before and after.
    pub energy_before: f64,
    pub energy_after: f64,
    pub seconds: f64,
}

/// Refuse a mesh whose faces cross each other. The search pulls samples
/// onto the nearest triangles, internal ones too: two overlapping cubes
/// came out with dents 4.5-6.9 cells deep along the faces inside the
/// other cube (the unified field, which only stores exact distances and
/// points on the mesh's own edges, stays within about a cell; see
/// BENCHMARKS.md, issue #16 checklist).
fn refuse_self_intersections(mesh: &TriMesh) -> Result<(), DistFieldError> {
    let pairs = surfrecon_geom::intersections::self_intersections(mesh);
    match pairs.first() {
        None => Ok(()),
        Some([f, g]) => Err(DistFieldError::InvalidMesh(format!(
            "the mesh intersects itself ({} pairs of crossing triangles, e.g. {f} and {g}); \
             the offset field would pull its samples onto the internal faces: \
             repair the mesh, or use --kind udf or regular (signed by winding number)",
            pairs.len()
        ))),
    }
}

/// Build the offset field of a closed, outward-oriented mesh.
pub fn build_odf(
    mesh: &TriMesh,
    options: &OdfOptions,
) -> Result<(OffsetField, OdfReport), DistFieldError> {
    let start = Instant::now();
    check_mesh(mesh)?;
    refuse_self_intersections(mesh)?;
    let w = options.weights;
    w.validate()?;
    if options.iterations > MAX_ITERATIONS {
        return Err(DistFieldError::InvalidOption(format!(
            "at most {MAX_ITERATIONS} search rounds, not {}",
            options.iterations
        )));
    }
    let spec = grid_for(mesh, options.size, options.padding)?;
    let values = signed_distance(mesh, &spec, Some(BAND_CELLS * spec.spacing))?.values;
    let query = MeshQuery::new(mesh)?;
    let features = Features::detect(mesh, options.feature_angle_deg);
    let mut cells = cells_with_features(mesh, &features, &spec, |_| true);
    let feature_cells = cells.len();
    add_cells_beside(&mut cells, &spec, &values);
    let mut field = Dense::new(spec, values);
    let search = Search::new(mesh, &spec, &query, &cells, w);
    let aligned = search.align(&mut field, &feature_targets(mesh, &features, &spec));
    // Samples on features stay there; the search fits the rest around them.
    let candidates = search.candidates();
    let mut report = OdfReport {
        samples: field.values.len(),
        feature_cells,
        candidates: candidates.len(),
        energy_before: search.total_energy(&field),
        ..Default::default()
    };
    report.aligned = aligned.len();
    let mut step = 0.25 * field.spec.spacing;
    // After the first round only samples sharing a cell with one that
    // moved are tried again: the others' energy is unchanged, and the
    // smaller steps seldom find what the larger did not (fandisk: same
    // error, a quarter less CPU).
    let mut active = candidates.clone();
    for _ in 0..options.iterations {
        let moved = search.round(&mut field, &active, &aligned, step);
        step *= 0.5;
        let near: BTreeSet<usize> = moved
            .iter()
            .flat_map(|&n| {
                search
                    .cells_around(n)
                    .flat_map(|c| corner_nodes(&field.spec, c))
            })
            .collect();
        active.retain(|n| near.contains(n));
    }
    let points = repair::MeshPoints::new(mesh, &spec);
    let crease_angle = repair::CREASE_ANGLE_DEG.min(options.feature_angle_deg);
    let creases = Features::detect(mesh, crease_angle);
    let creases = cells_with_features(mesh, &creases, &spec, |_| true);
    (report.repair_places, report.repaired) =
        repair::repair(&search, &mut field, &points, &creases);
    let mut field = field.into_field();
    report.smoothed = search.smooth_away_from_surface(&mut field);
    report.moved = field.moved.len();
    report.energy_after = search.total_energy(&field);
    report.seconds = start.elapsed().as_secs_f64();
    Ok((field, report))
}

/// Add to the feature cells their neighbours (sharing a face, edge or
/// corner) near the surface, without features of their own: samples
/// aligned with a feature sit on their corners too, and the surface there
/// must be fitted around them as well. (Fandisk: 0.40 h without them,
/// where a ridge sample's neighbour 0.04 h off a face, a corner of no
/// feature cell, was never moved and cut the ridge across its cell.)
pub(crate) fn add_cells_beside(
    cells: &mut BTreeMap<usize, CellFeatures>,
    spec: &GridSpec<3>,
    values: &[f64],
) {
    let near_surface = |c: usize| {
        let v = corner_nodes(spec, c).map(|n| values[n]);
        let crossed = v.iter().any(|&x| x < 0.0) && v.iter().any(|&x| x >= 0.0);
        crossed || v.iter().any(|x| x.abs() < 0.5 * spec.spacing)
    };
    let beside: Vec<usize> = cells
        .keys()
        .flat_map(|&c| block(spec, c, 1))
        .filter(|c| !cells.contains_key(c) && near_surface(*c))
        .collect();
    for c in beside {
        cells.entry(c).or_default();
    }
}

impl OffsetField {
    /// Where sample `node` sits.
    pub fn position_of(&self, node: usize) -> DVec3 {
        self.moved
            .get(&(node as u32))
            .copied()
            .unwrap_or_else(|| node_position(&self.spec, node))
    }

    /// The surface: marching cubes on the offset grid.
    pub fn extract(&self) -> (TriMesh, ExtractReport) {
        extract(self, &BTreeMap::new())
    }

    /// The surface before extraction's last steps (see
    /// [`crate::extract::raw_surface`]), which sculpting decides on.
    pub(crate) fn raw_surface(&self) -> TriMesh {
        let none = BTreeMap::new();
        crate::extract::raw_surface(self, &none, &none, &BTreeMap::new())
    }
}

impl SampledField for OffsetField {
    fn spec(&self) -> &GridSpec<3> {
        &self.spec
    }
    fn value(&self, node: usize) -> f64 {
        self.values[node]
    }
    fn position(&self, node: usize) -> DVec3 {
        self.position_of(node)
    }
}

pub(crate) fn node_position(spec: &GridSpec<3>, node: usize) -> DVec3 {
    DVec3::from_array(spec.position(spec.unlinear(node)))
}

/// Smallest triple product of a cell corner's edges, in h³, for a cell to
/// count as convex (regular cells have 1).
pub(crate) const MIN_CORNER_VOLUME: f64 = 0.1;
/// Most a probe adds to the energy (h²); a probe in a cell with no
/// crossing yet adds this plus its squared distance to the nearest
/// sample, which draws a sample onto it until the surface crosses the cell.
const UNREACHED: f64 = 1.0;

/// The surface samples are fitted to: the mesh in construction, the
/// exact result of object and tool after a sculpting step.
pub(crate) trait Truth: Sync {
    /// Signed distance at `p`, negative inside.
    fn signed_distance(&self, p: DVec3) -> f64;
    /// The surface point nearest `p`.
    fn closest_point(&self, p: DVec3) -> DVec3;
    /// Distance from `p` along `+axis` to the first surface point, if
    /// one lies within `max`.
    fn hit_along(&self, p: DVec3, axis: usize, max: f64) -> Option<f64>;
}

impl Truth for MeshQuery {
    fn signed_distance(&self, p: DVec3) -> f64 {
        MeshQuery::signed_distance(self, p)
    }
    fn closest_point(&self, p: DVec3) -> DVec3 {
        MeshQuery::closest_point(self, p)
    }
    fn hit_along(&self, p: DVec3, axis: usize, max: f64) -> Option<f64> {
        MeshQuery::hit_along(self, p, axis, max)
    }
}

/// The energy minimization over a field's samples.
pub(crate) struct Search<'a> {
    spec: &'a GridSpec<3>,
    query: &'a dyn Truth,
    cells: &'a BTreeMap<usize, CellFeatures>,
    /// Per feature cell, what its patch should match.
    targets: BTreeMap<usize, Target>,
    weights: Weights,
}

/// What a feature cell's patch should match: points it should pass
/// through and the source triangles near the cell (None: the truth's
/// own distances stand for them).
struct Target {
    probes: Vec<DVec3>,
    surface: Option<Boxed>,
}

/// Squared distance from `p` to the nearest of `triangles`.
fn distance2_to(p: DVec3, triangles: &[[DVec3; 3]]) -> f64 {
    triangles
        .iter()
        .map(|&t| p.distance_squared(closest_point_on_triangle(p, t)))
        .fold(f64::INFINITY, f64::min)
}

/// Triangles with their bounding boxes, for nearest-distance queries
/// that skip the triangles whose box is farther than the best so far.
#[derive(Default)]
struct Boxed {
    triangles: Vec<([DVec3; 3], DVec3, DVec3)>,
}

impl Boxed {
    fn new(triangles: impl IntoIterator<Item = [DVec3; 3]>) -> Self {
        let triangles = triangles
            .into_iter()
            .map(|t| (t, t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2])))
            .collect();
        Self { triangles }
    }

    /// Squared distance from `p` to the nearest triangle, or `cap` if
    /// none is nearer, starting from triangle `*hint` (the nearest
    /// to a point close by), which then becomes the nearest to `p`: a
    /// near first guess lets the box test skip most triangles.
    fn distance2_from(&self, p: DVec3, cap: f64, hint: &mut usize) -> f64 {
        let d2 = |t: &[DVec3; 3]| p.distance_squared(closest_point_on_triangle(p, *t));
        let mut best = cap;
        if let Some((t, _, _)) = self.triangles.get(*hint) {
            best = best.min(d2(t));
        }
        for (k, (t, lo, hi)) in self.triangles.iter().enumerate() {
            let outside = (*lo - p).max(p - *hi).max(DVec3::ZERO);
            if k != *hint && outside.length_squared() < best {
                let d = d2(t);
                if d < best {
                    best = d;
                    *hint = k;
                }
            }
        }
        best
    }
}

/// Sum over the corners and centres of `patch` (of feature cell `cell`)
/// of `measure` (a squared distance to the true surface). A corner shared
/// by several triangles counts once per triangle; every point is measured
/// once per `memo`.
fn patch_distance2(
    cell: usize,
    patch: &[[DVec3; 3]],
    memo: &mut Measured,
    mut measure: impl FnMut(DVec3) -> f64,
) -> f64 {
    let mut measured = |x: DVec3| {
        let key = (cell, x.to_array().map(f64::to_bits));
        *memo.0.entry(key).or_insert_with(|| measure(x))
    };
    let mut sum = 0.0;
    for t in patch {
        for x in [t[0], t[1], t[2]] {
            sum += measured(x);
        }
        sum += measured((t[0] + t[1] + t[2]) / 3.0);
    }
    sum
}

/// Squared distances from patch points to their cell's true surface,
/// kept over the tries of one sample: the crossings on the cell edges
/// that do not end at the sample stay where they are.
#[derive(Default)]
struct Measured(HashMap<(usize, [u64; 3]), f64>);

/// The source triangles within half a spacing of each feature cell (as
/// far as a patch can reach).
fn triangles_near_cells(
    mesh: &TriMesh,
    spec: &GridSpec<3>,
    cells: &BTreeMap<usize, CellFeatures>,
) -> BTreeMap<usize, Vec<[DVec3; 3]>> {
    let mut near: BTreeMap<usize, Vec<[DVec3; 3]>> = BTreeMap::new();
    for t in 0..mesh.triangles.len() {
        let corners = mesh.corners(t);
        let lo = corners.iter().fold(DVec3::INFINITY, |a, &b| a.min(b)) - 0.5 * spec.spacing;
        let hi = corners.iter().fold(DVec3::NEG_INFINITY, |a, &b| a.max(b)) + 0.5 * spec.spacing;
        let (glo, ghi) = (spec.to_grid(lo.to_array()), spec.to_grid(hi.to_array()));
        let range = |a: usize| {
            let from = glo[a].floor().max(0.0) as usize;
            let to = (ghi[a].floor().max(0.0) as usize).min(spec.dims[a].saturating_sub(2));
            from..=to
        };
        for k in range(2) {
            for j in range(1) {
                for i in range(0) {
                    let cell = spec.linear([i, j, k]);
                    if cells.contains_key(&cell) {
                        near.entry(cell).or_default().push(corners);
                    }
                }
            }
        }
    }
    near
}

/// The triangles marching cubes makes in a cell with these corner
/// positions and values.
fn cell_triangles(corners: &[(DVec3, f64); 8]) -> Vec<[DVec3; 3]> {
    let values = corners.map(|(_, v)| v);
    let (config, bits) = cell_case(&values, 0.0);
    if config == 0 || config == 255 {
        return Vec::new();
    }
    let crossing = |e: u8| {
        let [a, b] = EDGE_CORNERS[e as usize];
        let ((pa, va), (pb, vb)) = (corners[a as usize], corners[b as usize]);
        pa.lerp(pb, crossing_fraction(va, vb, 0.0))
    };
    let table = cube_table();
    let centres: Vec<DVec3> = table
        .loop_centres(config, bits)
        .iter()
        .map(|lp| lp.iter().map(|&e| crossing(e)).sum::<DVec3>() / lp.len() as f64)
        .collect();
    table
        .triangles(config, bits)
        .iter()
        .map(|t| {
            t.map(|e| {
                if e < 12 {
                    crossing(e)
                } else {
                    centres[e as usize - 12]
                }
            })
        })
        .collect()
}

/// Points a feature cell's patch should pass through: its corners and
/// bends, the ends and middles of its feature edge pieces, and where the
/// true surface crosses the cell's edges and twelve lines through it.
fn cell_probes(spec: &GridSpec<3>, query: &dyn Truth, cell: usize, f: &CellFeatures) -> Vec<DVec3> {
    let mut probes: Vec<DVec3> = f.corners.iter().chain(&f.bends).copied().collect();
    probes.extend(f.pieces.iter().flat_map(|&[a, b]| [a, (a + b) * 0.5, b]));
    let h = spec.spacing;
    let lo = node_position(spec, cell);
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for (s, t) in [
            (0.0, 0.0),
            (1.0, 0.0),
            (0.0, 1.0),
            (1.0, 1.0),
            (1.0 / 3.0, 1.0 / 3.0),
            (2.0 / 3.0, 1.0 / 3.0),
            (1.0 / 3.0, 2.0 / 3.0),
            (2.0 / 3.0, 2.0 / 3.0),
        ] {
            let mut origin = lo;
            origin[u] += s * h;
            origin[v] += t * h;
            if let Some(d) = query.hit_along(origin, axis, h) {
                let mut p = origin;
                p[axis] += d;
                probes.push(p);
            }
        }
    }
    probes
}

/// Where each sample whose box (half a spacing around its node) a
/// feature passes through should sit to hold it: on the corner in its
/// box, else in the middle of the piece of feature edge in its box (of
/// several, the piece whose middle lies nearest its node). Samples so
/// placed line up along each feature line, one per box it crosses, and
/// marching cubes then runs the surface through them (the paper's
/// alignment of samples with features, its Figure 2). The middles keep
/// them spread along the line: fandisk 0.43 h, against 0.56 h with the
/// points nearest the nodes, which crowd where a line grazes a box.
fn feature_targets(
    mesh: &TriMesh,
    features: &Features,
    spec: &GridSpec<3>,
) -> BTreeMap<usize, AlignTarget> {
    let v = |i: u32| mesh.vertices[i as usize];
    line_targets(
        spec,
        features.edges.iter().map(|&[a, b]| [v(a), v(b)]),
        features.corners.iter().map(|&c| v(c)),
    )
}

/// [`feature_targets`] for feature lines given as `segments` and
/// `corners` (the new edge of a sculpting step, too).
pub(crate) fn line_targets(
    spec: &GridSpec<3>,
    segments: impl IntoIterator<Item = [DVec3; 2]>,
    corners: impl IntoIterator<Item = DVec3>,
) -> BTreeMap<usize, AlignTarget> {
    // Node boxes are the cells of the grid shifted by half a spacing.
    let half = 0.5 * spec.spacing;
    let boxes = GridSpec::<3> {
        origin: spec.origin.map(|o| o - half),
        ..*spec
    };
    let mut targets: BTreeMap<usize, (f64, AlignTarget)> = BTreeMap::new();
    for [a, b] in segments {
        for (node, [p, q]) in clip_to_cells(&boxes, a, b) {
            let home = node_position(spec, node);
            let point = (p + q) * 0.5;
            let d = point.distance(home);
            let target = AlignTarget {
                point,
                corner: false,
                piece: [p, q],
            };
            let slot = targets.entry(node).or_insert((f64::INFINITY, target));
            if d < slot.0 {
                *slot = (d, target);
            }
        }
    }
    for p in corners {
        if let Some(node) = crate::features::cell_of(&boxes, p) {
            // A corner outranks any edge point.
            let target = AlignTarget {
                point: p,
                corner: true,
                piece: [p, p],
            };
            targets.insert(node, (-1.0, target));
        }
    }
    targets.into_iter().map(|(n, (_, t))| (n, t)).collect()
}

/// Where [`Search::align`] puts a sample.
#[derive(Debug, Clone, Copy)]
pub(crate) struct AlignTarget {
    pub point: DVec3,
    /// On a corner (placed before the samples on edges).
    pub corner: bool,
    /// The piece of feature line in the sample's box that `point` is the
    /// middle of (both ends `point` for a corner).
    pub piece: [DVec3; 2],
}

/// Read and write access to samples that may move.
pub(crate) trait Movable: Sync {
    fn value(&self, node: usize) -> f64;
    fn position(&self, node: usize) -> DVec3;
    fn set(&mut self, node: usize, position: DVec3, value: f64);
}

/// A field's samples with every position stored, for the search (which
/// reads positions far more often than a map of the moved ones allows).
struct Dense {
    spec: GridSpec<3>,
    values: Vec<f64>,
    positions: Vec<DVec3>,
}

impl Dense {
    fn new(spec: GridSpec<3>, values: Vec<f64>) -> Self {
        let positions = (0..values.len()).map(|n| node_position(&spec, n)).collect();
        Self {
            spec,
            values,
            positions,
        }
    }

    fn into_field(self) -> OffsetField {
        let moved = (self.positions.iter().enumerate())
            .filter(|&(n, p)| *p != node_position(&self.spec, n))
            .map(|(n, p)| (n as u32, *p))
            .collect();
        OffsetField {
            spec: self.spec,
            values: self.values,
            moved,
        }
    }
}

impl Movable for Dense {
    fn value(&self, node: usize) -> f64 {
        self.values[node]
    }
    fn position(&self, node: usize) -> DVec3 {
        self.positions[node]
    }
    fn set(&mut self, node: usize, position: DVec3, value: f64) {
        self.values[node] = value;
        self.positions[node] = position;
    }
}

impl Movable for OffsetField {
    fn value(&self, node: usize) -> f64 {
        self.values[node]
    }
    fn position(&self, node: usize) -> DVec3 {
        self.position_of(node)
    }
    fn set(&mut self, node: usize, position: DVec3, value: f64) {
        self.values[node] = value;
        if position == node_position(&self.spec, node) {
            self.moved.remove(&(node as u32));
        } else {
            self.moved.insert(node as u32, position);
        }
    }
}

impl<'a> Search<'a> {
    pub fn new(
        mesh: &TriMesh,
        spec: &'a GridSpec<3>,
        query: &'a MeshQuery,
        cells: &'a BTreeMap<usize, CellFeatures>,
        weights: Weights,
    ) -> Self {
        let mut near = triangles_near_cells(mesh, spec, cells);
        let targets = cells
            .iter()
            .map(|(&c, f)| {
                let surface = Some(Boxed::new(near.remove(&c).unwrap_or_default()));
                (
                    c,
                    Target {
                        probes: cell_probes(spec, query, c, f),
                        surface,
                    },
                )
            })
            .collect();
        Self {
            spec,
            query,
            cells,
            targets,
            weights,
        }
    }

    /// A search fitting `cells` to `truth` alone (no source triangles):
    /// after a sculpting step, the result of object and tool.
    pub fn on_truth(
        spec: &'a GridSpec<3>,
        truth: &'a dyn Truth,
        cells: &'a BTreeMap<usize, CellFeatures>,
        weights: Weights,
    ) -> Self {
        let targets = cells
            .iter()
            .map(|(&c, f)| {
                let probes = cell_probes(spec, truth, c, f);
                let target = Target {
                    probes,
                    surface: None,
                };
                (c, target)
            })
            .collect();
        Self {
            spec,
            query: truth,
            cells,
            targets,
            weights,
        }
    }

    /// The samples at the corners of feature cells, sorted.
    pub fn candidates(&self) -> Vec<usize> {
        let set: BTreeSet<usize> = self
            .cells
            .keys()
            .flat_map(|&c| corner_nodes(self.spec, c))
            .collect();
        set.into_iter().filter(|&n| self.interior(n)).collect()
    }

    /// Samples not on the grid's outer layer (those have incomplete cells).
    fn interior(&self, node: usize) -> bool {
        !on_outer_layer(self.spec, node)
    }

    /// Put samples onto their `targets` (see [`feature_targets`]) where
    /// that is legal: the sample stays in its box, its cells convex, and
    /// the surface keeps its topology ([`Self::same_topology`]). Returns
    /// the samples moved.
    pub fn align(
        &self,
        field: &mut impl Movable,
        targets: &BTreeMap<usize, AlignTarget>,
    ) -> BTreeSet<usize> {
        let reach = 0.5 * self.spec.spacing * (1.0 - 1e-9);
        let mut count = BTreeSet::new();
        // Corners first: the samples on the edges leading to a corner
        // must leave room for the corner's own sample.
        let (corners, edges): (Vec<_>, Vec<_>) = targets.iter().partition(|(_, t)| t.corner);
        for (&node, t) in corners.into_iter().chain(edges) {
            let p = t.point;
            if !self.interior(node)
                || (p - node_position(self.spec, node)).abs().max_element() > reach
                || !self.stays_convex(&*field, node, p)
            {
                continue;
            }
            let values = on_surface_values(self.query.signed_distance(p), self.spec.spacing);
            // On a convex edge or corner the sample goes outside first and
            // on a concave one inside: the surface then passes through it
            // once its neighbours across the faces lie on the other side,
            // which the search can reach by moving them within their
            // boxes. (The other way round, a sample inside on a convex
            // ridge joins the solid only through ambiguous faces whose
            // decider separates it unless a neighbour lies exactly on the
            // surface: fandisk's ridges then stayed cut by 0.4 h.)
            let outside_first = self.solid_fraction(p) < 0.5;
            let ordered = values.iter().copied().rev().filter(|_| outside_first);
            let ordered = ordered.chain(values.iter().copied().filter(|_| !outside_first));
            let legal = ordered
                .filter_map(|v| self.same_topology(&*field, node, v))
                .next();
            if let Some(v) = legal {
                field.set(node, p, v);
                count.insert(node);
            }
        }
        count
    }

    fn solid_fraction(&self, p: DVec3) -> f64 {
        solid_fraction(p, 0.25 * self.spec.spacing, |q| {
            self.query.signed_distance(q)
        })
    }

    /// One round over the candidates, parity class by parity class.
    /// Samples in `pinned` stay where they are but may change side when
    /// they lie on the surface. Returns the samples that moved.
    pub fn round(
        &self,
        field: &mut impl Movable,
        candidates: &[usize],
        pinned: &BTreeSet<usize>,
        step: f64,
    ) -> Vec<usize> {
        let mut moved = Vec::new();
        for class in 0..8 {
            let moves: Vec<(usize, DVec3, f64)> = candidates
                .par_iter()
                .filter(|&&n| parity(self.spec, n) == class)
                .filter_map(|&n| self.best_move(&*field, n, step, pinned.contains(&n)))
                .collect();
            for (n, p, v) in moves {
                field.set(n, p, v);
                moved.push(n);
            }
        }
        moved
    }

    /// The best legal move of sample `node` that lowers its energy (of
    /// equal energies, the first try).
    fn best_move(
        &self,
        field: &impl Movable,
        node: usize,
        step: f64,
        pinned: bool,
    ) -> Option<(usize, DVec3, f64)> {
        let here = field.position(node);
        let mut memo = Measured::default();
        let current = self
            .local_energy(
                field,
                node,
                here,
                field.value(node),
                f64::INFINITY,
                &mut memo,
            )
            // Only an infinite energy (huge weights) reaches no bound.
            .unwrap_or(f64::INFINITY);
        // A try must come below `current` and below the best so far:
        // its energy is abandoned once its partial sum reaches that.
        let mut best: Option<(DVec3, f64, f64)> = None;
        let mut consider = |p: DVec3, v: f64, memo: &mut Measured| {
            let bound = best.map_or(current - 1e-12, |b| b.2.min(current - 1e-12));
            if let Some(e) = self.local_energy(field, node, p, v, bound, memo) {
                if e < bound {
                    best = Some((p, v, e));
                }
            }
        };
        if pinned {
            for v in on_surface_values(field.value(node), self.spec.spacing) {
                if v != field.value(node) {
                    if let Some(v) = self.same_topology(field, node, v) {
                        consider(here, v, &mut memo);
                    }
                }
            }
            return best.map(|(_, v, _)| (node, here, v));
        }
        let mut tries: Vec<DVec3> = (0..6)
            .map(|k| {
                let mut d = DVec3::ZERO;
                d[k / 2] = if k % 2 == 0 { step } else { -step };
                here + d
            })
            .collect();
        tries.push(here); // on the surface: the other side
                          // The nearest surface point: a sample on the surface pins it there.
        tries.push(self.query.closest_point(here));
        tries.extend(self.feature_points_near(node, here));
        let home = node_position(self.spec, node);
        let reach = 0.5 * self.spec.spacing * (1.0 - 1e-9);
        let h = self.spec.spacing;
        for p in tries {
            if (p - home).abs().max_element() > reach || !self.stays_convex(field, node, p) {
                continue;
            }
            for v in on_surface_values(self.query.signed_distance(p), h) {
                if let Some(v) = self.same_topology(field, node, v) {
                    consider(p, v, &mut memo);
                }
            }
        }
        best.map(|(p, v, _)| (node, p, v))
    }

    /// The value `v` if sample `node` may take it: when the sample stays
    /// on its side and no ambiguous face around it changes its decision
    /// (every cell keeps its case), or else when the surface inside its
    /// eight cells keeps its topology ([`local_topology`]). Samples on a
    /// feature often must cross, or tip an ambiguous face, for the surface
    /// to pass through them: beside a ridge whose sample sits on a cell
    /// face corner, that face's segment reaches the sample only if the
    /// sample is inside and the face's inside diagonal connected.
    /// (Allowing any simple point to cross, as digital topology does, gave
    /// fandisk and a rotated box a spurious handle: the decider's
    /// connectivity is not digital topology's.)
    fn same_topology(&self, field: &impl Movable, node: usize, v: f64) -> Option<f64> {
        keeps_topology(self.spec, node, v, |n| field.value(n))
    }

    /// Corners and bends in the cells around `node`, and the points of
    /// their feature edges nearest `here`: places a sample may jump to.
    fn feature_points_near(&self, node: usize, here: DVec3) -> Vec<DVec3> {
        self.cells_around(node)
            .filter_map(|c| self.cells.get(&c))
            .flat_map(|f| {
                let on_pieces = f
                    .pieces
                    .iter()
                    .map(move |&[a, b]| closest_on_segment(here, a, b));
                f.corners.iter().chain(&f.bends).copied().chain(on_pieces)
            })
            .collect()
    }

    fn cells_around(&self, node: usize) -> impl Iterator<Item = usize> + '_ {
        cells_around(self.spec, node)
    }

    /// Energy terms that change when `node` moves to `p` with value `v`,
    /// or None once they reach `bound` (the distance term, summed last,
    /// only grows).
    fn local_energy(
        &self,
        field: &impl Movable,
        node: usize,
        p: DVec3,
        v: f64,
        bound: f64,
        memo: &mut Measured,
    ) -> Option<f64> {
        let at = |n: usize| {
            if n == node {
                (p, v)
            } else {
                (field.position(n), field.value(n))
            }
        };
        let h = self.spec.spacing;
        let neighbours = self.neighbours(node);
        let spring: f64 = neighbours
            .iter()
            .flatten()
            .map(|&n| (1.0 - at(n).0.distance(p) / h).powi(2))
            .sum();
        let mut ortho = 0.0;
        // Perpendicular edge pairs at the sample, then at each neighbour
        // the edge back to the sample against the neighbour's other edges.
        let edge = |from: usize, to: usize| (at(to).0 - at(from).0).normalize_or_zero();
        for a in 0..6 {
            for b in (a + 1)..6 {
                if a / 2 != b / 2 {
                    if let (Some(na), Some(nb)) = (neighbours[a], neighbours[b]) {
                        ortho += edge(node, na).dot(edge(node, nb)).powi(2);
                    }
                }
            }
        }
        for (a, n) in neighbours.iter().enumerate() {
            let Some(n) = *n else { continue };
            let back = edge(n, node);
            for (b, m) in self.neighbours(n).iter().enumerate() {
                if let Some(m) = *m {
                    if b / 2 != a / 2 {
                        ortho += back.dot(edge(n, m)).powi(2);
                    }
                }
            }
        }
        let w = self.weights;
        let total = |distance: f64| w.distance * distance + w.spring * spring + w.ortho * ortho;
        if total(0.0) >= bound {
            return None;
        }
        let distance = self.block_energy(node, &at, &|partial| total(partial) >= bound, memo)?;
        Some(total(distance))
    }

    /// The six axis neighbours (−x, +x, −y, +y, −z, +z), where they exist.
    fn neighbours(&self, node: usize) -> [Option<usize>; 6] {
        let idx = self.spec.unlinear(node);
        let strides = self.spec.strides();
        std::array::from_fn(|k| {
            let a = k / 2;
            if k % 2 == 0 {
                (idx[a] > 0).then(|| node - strides[a])
            } else {
                (idx[a] + 1 < self.spec.dims[a]).then(|| node + strides[a])
            }
        })
    }

    /// E_dist of one cell, in h², both ways: the squared distances from
    /// the cell's probes (feature points, points of the true surface) to
    /// the triangles marching cubes makes in it, and from those triangles'
    /// corners and centres back to the true surface, each capped at
    /// [`UNREACHED`].
    fn cell_energy(&self, cell: usize, at: &impl Fn(usize) -> (DVec3, f64)) -> f64 {
        let Some(target) = self.targets.get(&cell) else {
            return 0.0;
        };
        let corners = corner_nodes(self.spec, cell).map(at);
        let patch = cell_triangles(&corners);
        let h2 = self.spec.spacing * self.spec.spacing;
        if patch.is_empty() {
            // Draw the nearest sample onto the surface.
            let nearest = |q: DVec3| {
                corners
                    .iter()
                    .map(|&(p, _)| p.distance_squared(q))
                    .fold(f64::INFINITY, f64::min)
            };
            return target
                .probes
                .iter()
                .map(|&q| UNREACHED + nearest(q) / h2)
                .sum();
        }
        // Slivers of no area (a crossing on a sample on the surface) show
        // no surface: a chain of such samples makes a flat tube along a
        // feature line that would pass for the line itself.
        let solid: Vec<[DVec3; 3]> = patch
            .iter()
            .copied()
            .filter(|t| (t[1] - t[0]).cross(t[2] - t[0]).length() > 1e-6 * h2)
            .collect();
        let to_patch = target.probes.iter().map(|&q| distance2_to(q, &solid));
        let points = patch
            .iter()
            .flat_map(|t| [t[0], t[1], t[2], (t[0] + t[1] + t[2]) / 3.0]);
        let to_surface = points.map(|x| self.distance2_back(target, x, UNREACHED * h2, &mut 0));
        to_patch
            .chain(to_surface)
            .map(|d2| (d2 / h2).min(UNREACHED))
            .sum()
    }

    /// E_dist of the cells around `node`, with each cell's probes
    /// measured against the surface of all eight cells: where the sample
    /// moves onto a cell face, the surface through a probe can pass into
    /// the next cell of the block, and still passes through the probe.
    /// The block's outer boundary does not move with the sample, so the
    /// block's surface stays comparable between tries.
    /// Returns None as soon as `over` holds for the partial sum.
    fn block_energy(
        &self,
        node: usize,
        at: &impl Fn(usize) -> (DVec3, f64),
        over: &dyn Fn(f64) -> bool,
        memo: &mut Measured,
    ) -> Option<f64> {
        let h2 = self.spec.spacing * self.spec.spacing;
        let patches: Vec<(usize, [DVec3; 8], Vec<[DVec3; 3]>)> = self
            .cells_around(node)
            .map(|c| {
                let corners = corner_nodes(self.spec, c).map(at);
                let patch = cell_triangles(&corners);
                (c, corners.map(|(p, _)| p), patch)
            })
            .collect();
        let solid = Boxed::new(
            patches
                .iter()
                .flat_map(|(_, _, patch)| patch.iter().copied())
                .filter(|t| (t[1] - t[0]).cross(t[2] - t[0]).length() > 1e-6 * h2),
        );
        let mut hint = 0;
        let mut to_block = |q: DVec3| solid.distance2_from(q, UNREACHED * h2, &mut hint);
        let mut energy = 0.0;
        for (c, corners, patch) in &patches {
            let Some(target) = self.targets.get(c) else {
                continue;
            };
            for &q in &target.probes {
                let d2 = to_block(q) / h2;
                energy += if d2 < UNREACHED {
                    d2
                } else {
                    // Draw the nearest sample onto the surface.
                    let nearest = corners
                        .iter()
                        .map(|p| p.distance_squared(q))
                        .fold(f64::INFINITY, f64::min);
                    UNREACHED + nearest / h2
                };
            }
            if over(energy) {
                return None;
            }
            let mut hint = 0;
            let back = |x: DVec3| self.distance2_back(target, x, UNREACHED * h2, &mut hint);
            energy += patch_distance2(*c, patch, memo, back) / h2;
            if over(energy) {
                return None;
            }
        }
        Some(energy)
    }

    fn stays_convex(&self, field: &impl Movable, node: usize, p: DVec3) -> bool {
        stays_convex(self.spec, node, p, |n| field.position(n))
    }

    /// Squared distance from `x` (on a patch of `target`'s cell) back to
    /// the true surface, at most `cap`: to the source triangles near the
    /// cell ([`Boxed::distance2_from`], starting from triangle `*hint`)
    /// or, without them, the truth's own distance.
    fn distance2_back(&self, target: &Target, x: DVec3, cap: f64, hint: &mut usize) -> f64 {
        match &target.surface {
            Some(near) => near.distance2_from(x, cap, hint),
            None => self.query.signed_distance(x).powi(2).min(cap),
        }
    }

    /// Total E_dist over the fitted cells (see [`OdfReport::energy_before`]).
    pub fn total_energy(&self, field: &impl Movable) -> f64 {
        let at = |n: usize| (field.position(n), field.value(n));
        self.cells.keys().map(|&c| self.cell_energy(c, &at)).sum()
    }

    /// Laplacian smoothing of the samples next to moved ones whose cells
    /// the surface does not cross: each goes to the mean of its cells'
    /// centres (kept in its box and legal). Returns how many moved.
    pub fn smooth_away_from_surface(&self, field: &mut OffsetField) -> usize {
        let moved: Vec<usize> = field.moved.keys().map(|&n| n as usize).collect();
        let mut ring: BTreeSet<usize> = BTreeSet::new();
        for n in moved {
            ring.extend(
                self.neighbours(n)
                    .into_iter()
                    .flatten()
                    .filter(|&m| self.interior(m)),
            );
        }
        let mut count = 0;
        for n in ring {
            if field.moved.contains_key(&(n as u32))
                || self
                    .cells_around(n)
                    .any(|c| crosses(self.spec, &field.values, c))
            {
                continue;
            }
            let centres: Vec<DVec3> = self
                .cells_around(n)
                .map(|c| {
                    corner_nodes(self.spec, c)
                        .map(|m| field.position_of(m))
                        .iter()
                        .sum::<DVec3>()
                        / 8.0
                })
                .collect();
            let home = node_position(self.spec, n);
            let reach = DVec3::splat(0.5 * self.spec.spacing * (1.0 - 1e-9));
            let target = (centres.iter().sum::<DVec3>() / centres.len() as f64)
                .clamp(home - reach, home + reach);
            if target != home && self.stays_convex(&*field, n, target) {
                let v = self.query.signed_distance(target);
                if (v >= 0.0) == (field.values[n] >= 0.0) {
                    field.set(n, target, v);
                    count += 1;
                }
            }
        }
        count
    }
}

/// The fraction of a ball of radius `r` around `p` (26 points on it)
/// inside the solid whose signed distance is `distance`: below one half
/// at a convex edge or corner, above at a concave one.
pub(crate) fn solid_fraction(p: DVec3, r: f64, distance: impl Fn(DVec3) -> f64) -> f64 {
    let mut inside = 0;
    let mut total = 0;
    for dz in -1i32..=1 {
        for dy in -1i32..=1 {
            for dx in -1i32..=1 {
                if dx == 0 && dy == 0 && dz == 0 {
                    continue;
                }
                let d = DVec3::new(dx as f64, dy as f64, dz as f64).normalize();
                total += 1;
                if distance(p + d * r) < 0.0 {
                    inside += 1;
                }
            }
        }
    }
    inside as f64 / total as f64
}

/// See [`Search::same_topology`]: the value `v` if sample `node` may take
/// it, its samples' values given by `value`.
pub(crate) fn keeps_topology(
    spec: &GridSpec<3>,
    node: usize,
    v: f64,
    value: impl Fn(usize) -> f64,
) -> Option<f64> {
    if (v < 0.0) == (value(node) < 0.0) {
        if let Some(v) = same_cases(spec, node, v, &value) {
            return Some(v);
        }
    }
    let after = |n: usize| if n == node { v } else { value(n) };
    (local_topology(spec, node, &value) == local_topology(spec, node, after)).then_some(v)
}

/// The (up to eight) cells that have `node` as a corner.
pub fn cells_around(spec: &GridSpec<3>, node: usize) -> impl Iterator<Item = usize> + '_ {
    let idx = spec.unlinear(node);
    (0..8).filter_map(move |c: usize| {
        let mut cell = idx;
        for (a, i) in cell.iter_mut().enumerate() {
            if (c >> a) & 1 == 1 {
                *i = i.checked_sub(1)?;
            }
            if *i + 1 >= spec.dims[a] {
                return None;
            }
        }
        Some(spec.linear(cell))
    })
}

/// Whether every cell around `node` stays convex with `node` at `p`: at
/// each cell corner the three edges keep a positive triple product of at
/// least [`MIN_CORNER_VOLUME`] h³ (no sample crosses the plane of its
/// neighbours).
pub(crate) fn stays_convex(
    spec: &GridSpec<3>,
    node: usize,
    p: DVec3,
    position: impl Fn(usize) -> DVec3,
) -> bool {
    least_corner_volume(spec, node, p, position) > MIN_CORNER_VOLUME * spec.spacing.powi(3)
}

/// The smallest triple product of the edges at any corner of the cells
/// around `node`, with `node` at `p` (h³ on a regular grid).
pub(crate) fn least_corner_volume(
    spec: &GridSpec<3>,
    node: usize,
    p: DVec3,
    position: impl Fn(usize) -> DVec3,
) -> f64 {
    corner_volumes(spec, node, p, &position).fold(f64::INFINITY, f64::min)
}

/// The triple products of the edges at each corner of the cells around
/// `node` (signed so that a convex cell's are positive), `node` at `p`.
fn corner_volumes<'s>(
    spec: &'s GridSpec<3>,
    node: usize,
    p: DVec3,
    position: &'s impl Fn(usize) -> DVec3,
) -> impl Iterator<Item = f64> + 's {
    cells_around(spec, node).flat_map(move |cell| {
        let pos = corner_nodes(spec, cell).map(|n| if n == node { p } else { position(n) });
        (0..8).map(move |c: usize| {
            let e = [1, 2, 4].map(|bit| pos[c ^ bit] - pos[c]);
            let sign = if c.count_ones().is_multiple_of(2) {
                1.0
            } else {
                -1.0
            };
            sign * e[0].cross(e[1]).dot(e[2])
        })
    })
}

/// Whether sample `node` may take the value `v`: always when it stays on
/// its side; across the surface only when it is a simple point (digital
/// topology), so marching cubes gains no island, tunnel or handle. (Used
/// where a sample is moved onto the surface on purpose; the energy search
/// keeps every sample's side.)
/// `cube` is the neighbourhood of the field's grid; `node` must not lie on
/// the grid's outer layer.
pub(crate) fn may_take(
    cube: &Neighbourhood,
    node: usize,
    v: f64,
    value: impl Fn(usize) -> f64,
) -> bool {
    // Which connectivity marching cubes gives each side depends on the
    // values (the asymptotic decider), so the sample must be simple with
    // either side taken face-connected.
    (value(node) < 0.0) == (v < 0.0)
        || (cube.is_simple(node, |n| value(n) < 0.0) && cube.is_simple(node, |n| value(n) >= 0.0))
}

/// The value sample `node` may take where its exact distance is `v`
/// without changing any cell's marching-cubes case: it stays on its side
/// (landing on the surface, it keeps its old side) and no ambiguous face
/// around it changes its decision.
pub(crate) fn same_cases(
    spec: &GridSpec<3>,
    node: usize,
    v: f64,
    value: impl Fn(usize) -> f64,
) -> Option<f64> {
    let old = value(node);
    let v = if (v < 0.0) == (old < 0.0) {
        v
    } else if v.abs() <= 1e-6 * spec.spacing {
        if old < 0.0 {
            -1e-9 * spec.spacing
        } else {
            0.0
        }
    } else {
        return None;
    };
    let decisions = |value: &dyn Fn(usize) -> f64| {
        cells_around(spec, node)
            .map(|c| cell_case(&corner_nodes(spec, c).map(value), 0.0).1)
            .collect::<Vec<u8>>()
    };
    let after = |n: usize| if n == node { v } else { value(n) };
    (decisions(&value) == decisions(&after)).then_some(v)
}

/// The topology of the marching-cubes surface inside the 2×2×2 cells
/// around `node`: per connected piece, the loops it has on the block's
/// outer faces (each named by its smallest vertex) and its Euler
/// characteristic, sorted. The outer faces do not touch `node`, so its
/// value leaves the loops there unchanged; two values giving the same
/// pieces give surfaces of the same topology (a piece is fixed, up to
/// homeomorphism, by its boundary loops and Euler characteristic).
pub(crate) fn local_topology(
    spec: &GridSpec<3>,
    node: usize,
    value: impl Fn(usize) -> f64,
) -> Vec<(Vec<u64>, i64)> {
    let table = cube_table();
    let mut triangles: Vec<[u64; 3]> = Vec::new();
    for cell in cells_around(spec, node) {
        let corners = corner_nodes(spec, cell);
        let (config, bits) = cell_case(&corners.map(&value), 0.0);
        for t in table.triangles(config, bits) {
            triangles.push(t.map(|e| {
                if e < 12 {
                    let lower = EDGE_CORNERS[e as usize][0] as usize;
                    2 * (corners[lower] as u64 * 3 + e as u64 / 4)
                } else {
                    2 * (cell as u64 * 16 + e as u64 - 12) + 1
                }
            }));
        }
    }
    let mut ids: Vec<u64> = triangles.iter().flatten().copied().collect();
    ids.sort_unstable();
    ids.dedup();
    let index = |v: u64| ids.binary_search(&v).expect("a vertex of the block");
    let mut parent: Vec<usize> = (0..ids.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut edges: BTreeMap<(usize, usize), usize> = BTreeMap::new();
    for t in &triangles {
        let v = t.map(index);
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_default() += 1;
            let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
            parent[ra] = rb;
        }
    }
    // Per piece: V - E + F, and the boundary loops (edges used once).
    let mut euler: BTreeMap<usize, i64> = BTreeMap::new();
    for v in 0..ids.len() {
        *euler.entry(root(&mut parent, v)).or_default() += 1;
    }
    for t in &triangles {
        *euler.entry(root(&mut parent, index(t[0]))).or_default() += 1;
    }
    let mut ring: Vec<usize> = (0..ids.len()).collect();
    for (&(a, b), &count) in &edges {
        *euler.entry(root(&mut parent, a)).or_default() -= 1;
        if count == 1 {
            let (ra, rb) = (root(&mut ring, a), root(&mut ring, b));
            ring[ra] = rb;
        }
    }
    let mut loops: BTreeMap<usize, BTreeMap<usize, u64>> = BTreeMap::new();
    for (&(a, b), &count) in &edges {
        if count == 1 {
            for v in [a, b] {
                let name = loops
                    .entry(root(&mut parent, v))
                    .or_default()
                    .entry(root(&mut ring, v))
                    .or_insert(u64::MAX);
                *name = (*name).min(ids[v]);
            }
        }
    }
    let mut pieces: Vec<(Vec<u64>, i64)> = euler
        .into_iter()
        .map(|(piece, chi)| {
            let mut names: Vec<u64> = loops
                .get(&piece)
                .map(|l| l.values().copied().collect())
                .unwrap_or_default();
            names.sort_unstable();
            (names, chi)
        })
        .collect();
    pieces.sort_unstable();
    pieces
}

/// The values a sample may take where the exact distance is `v`: `v`
/// itself, or on the surface (within 1e-6 h) either side of it, just
/// inside (−1e-9 h) or outside (0; marching cubes counts 0 as outside).
pub(crate) fn on_surface_values(v: f64, h: f64) -> Vec<f64> {
    if v.abs() <= 1e-6 * h {
        vec![-1e-9 * h, 0.0]
    } else {
        vec![v]
    }
}

/// Whether `node` lies on the grid's outer layer.
pub(crate) fn on_outer_layer(spec: &GridSpec<3>, node: usize) -> bool {
    let idx = spec.unlinear(node);
    (0..3).any(|a| idx[a] == 0 || idx[a] + 1 >= spec.dims[a])
}

/// Parity class (0..8) of a node's index: nodes of one class share no cell.
fn parity(spec: &GridSpec<3>, node: usize) -> usize {
    let idx = spec.unlinear(node);
    (idx[0] & 1) | (idx[1] & 1) << 1 | (idx[2] & 1) << 2
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> GridSpec<3> {
        GridSpec {
            origin: [0.0; 3],
            spacing: 1.0,
            dims: [5, 5, 5],
        }
    }

    #[test]
    fn a_dent_keeps_the_topology_and_a_cavity_does_not() {
        let spec = spec();
        let centre = spec.linear([2, 2, 2]);
        // The half-space z < 2.5: one disk (χ = 1) with one loop.
        let plane = |n: usize| spec.unlinear(n)[2] as f64 - 2.5;
        let flat = local_topology(&spec, centre, plane);
        assert_eq!(flat.len(), 1);
        assert_eq!((flat[0].0.len(), flat[0].1), (1, 1));
        // The centre sample just below the plane turned outside: a dent
        // open to the outside above it.
        let dent = |n: usize| if n == centre { 0.5 } else { plane(n) };
        assert_eq!(local_topology(&spec, centre, dent), flat);
        // Inside a solid, the same flip opens a cavity: a new closed piece.
        let solid = |_: usize| -1.0;
        let cavity = |n: usize| if n == centre { 1.0 } else { -1.0 };
        assert!(local_topology(&spec, centre, solid).is_empty());
        assert_eq!(local_topology(&spec, centre, cavity), vec![(vec![], 2)]);
    }
}
