//! The reconstruction pipeline: data → cleaning → distance → tagging →
//! convection → minimal surface flow → settling convection (coarse to
//! fine) → mesh or curves.

use crate::band::NarrowBand;
use crate::cleaning::{clean_points, CleaningStats};
use crate::error::{LevelsetError, Result};
use crate::flow::{evolve, EvolveParams, EvolveStats, Motion};
use crate::multires::{auto_levels, coarsen, upsample};
use crate::reinit::{reinitialize, signed_distance_everywhere};
use crate::tagging::{remove_unsupported, tag, BoundingBox};
use std::time::Instant;
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::{DVec3, Geometry, Polylines, TriMesh};
use surfrecon_grid::distance::{self, DataSet};
use surfrecon_grid::{Field, Field2, Field3, GridSize, GridSpec};

/// The data to reconstruct from: any mix of points, segments (curves) and
/// triangles (surface patches). In 2D only x and y are used.
#[derive(Clone, Debug, Default)]
pub struct Input {
    pub points: Vec<DVec3>,
    pub segments: Vec<[DVec3; 2]>,
    pub triangles: Vec<[DVec3; 3]>,
}

impl Input {
    /// Points only.
    pub fn from_points(points: Vec<DVec3>) -> Self {
        Input {
            points,
            ..Default::default()
        }
    }

    /// Everything a file holds: its triangles as patches, its polylines as
    /// segments, and its vertices as points (isolated vertices count too).
    pub fn from_geometry(g: &Geometry) -> Self {
        let v = &g.points.positions;
        let at = |i: u32| v.get(i as usize).copied();
        let triangles = g
            .triangles
            .iter()
            .filter_map(|t| Some([at(t[0])?, at(t[1])?, at(t[2])?]))
            .collect();
        let segments = g
            .lines
            .iter()
            .flat_map(|l| l.windows(2))
            .filter_map(|w| Some([at(w[0])?, at(w[1])?]))
            .collect();
        Input {
            points: v.clone(),
            segments,
            triangles,
        }
    }

    /// Number of data items.
    pub fn len(&self) -> usize {
        self.points.len() + self.segments.len() + self.triangles.len()
    }

    /// True without any data.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn all_vertices(&self) -> impl Iterator<Item = DVec3> + '_ {
        self.points
            .iter()
            .copied()
            .chain(self.segments.iter().flatten().copied())
            .chain(self.triangles.iter().flatten().copied())
    }
}

/// Every knob of the reconstruction; `Default` works without tuning.
#[derive(Clone, Debug, PartialEq)]
pub struct ReconstructParams {
    /// Cells along the longest axis of the data (None: from the sampling
    /// density, 32..=256 in 3D, 32..=1024 in 2D).
    pub resolution: Option<usize>,
    /// Offset ε of the outer distance contour, in world units (None: from
    /// the sampling density; then enlarged until the contour is closed).
    pub epsilon: Option<f64>,
    /// Exponent p ≥ 1 of the weighted area energy (1 or 2 are usual).
    pub p: f64,
    /// Maximum minimal surface flow steps per level.
    pub steps: usize,
    /// Maximum convection steps per level.
    pub convection_steps: usize,
    /// Narrow band half-width in cells (≥ 2).
    pub band: f64,
    /// Resolution levels (None: automatic, coarse levels for large grids).
    pub levels: Option<usize>,
    /// Convergence: mean zero-set displacement per step near the data,
    /// relative to the largest possible (see [`EvolveParams::tolerance`]);
    /// twice as loose on coarse levels.
    pub tolerance: f64,
    /// Also treat everything outside the data's bounding box as exterior
    /// (helps highly non-uniform data).
    pub bounding_box: bool,
    /// Compute the signed distance on the whole grid (not only the band).
    pub full_field: bool,
    /// Tagging keeps the topology of the outer contour d = ε: the exterior
    /// cannot tunnel through gaps in the data that ε closed (holes in a
    /// scan). Off: tagging also opens handles narrower than ε.
    pub keep_topology: bool,
    /// Remove outliers and project noisy points onto their neighbours'
    /// plane before anything else ([`crate::cleaning`]).
    pub clean: bool,
}

impl Default for ReconstructParams {
    fn default() -> Self {
        ReconstructParams {
            resolution: None,
            epsilon: None,
            p: 1.0,
            steps: 100,
            convection_steps: 100,
            band: 3.0,
            levels: None,
            tolerance: 0.02,
            bounding_box: false,
            full_field: false,
            clean: true,
            keep_topology: true,
        }
    }
}

/// Sizes and timings of one run.
#[derive(Clone, Debug, Default)]
pub struct Report {
    /// Nodes per axis of the finest grid.
    pub dims: Vec<usize>,
    /// Spacing h of the finest grid.
    pub spacing: f64,
    /// Number of resolution levels used.
    pub levels: usize,
    /// ε of the outer contour actually used (coarsest level).
    pub epsilon: f64,
    /// What point cleaning did (all zero when off).
    pub cleaning: CleaningStats,
    /// Heap pops of the tagging.
    pub heap_pops: usize,
    /// Inside nodes after tagging.
    pub tagged_inside: usize,
    /// Inside components dropped after tagging for lack of data.
    pub removed_components: usize,
    /// Band nodes at the end.
    pub band_nodes: usize,
    /// Blocks of 8^D nodes (the sparse grid's blocks) that hold them.
    pub band_blocks: usize,
    /// Convection and flow statistics, per level (coarsest first).
    pub convection: Vec<EvolveStats>,
    pub flow: Vec<EvolveStats>,
    /// The final convection after the flow (finest level only).
    pub settle: Vec<EvolveStats>,
    /// Seconds per stage, in execution order (stages repeat per level).
    pub timings: Vec<(String, f64)>,
}

impl Report {
    fn time<T>(&mut self, stage: &str, f: impl FnOnce() -> T) -> T {
        let t = Instant::now();
        let out = f();
        self.timings
            .push((stage.to_string(), t.elapsed().as_secs_f64()));
        out
    }

    /// Total seconds of all stages named `stage`.
    pub fn seconds(&self, stage: &str) -> f64 {
        self.timings
            .iter()
            .filter(|(s, _)| s == stage)
            .map(|(_, t)| t)
            .sum()
    }
}

/// A 3D reconstruction: the closed surface, φ and the run's report.
#[derive(Clone, Debug)]
pub struct Reconstruction3 {
    /// Watertight triangle mesh of φ = 0.
    pub mesh: TriMesh,
    /// φ: signed distance in the band (everywhere with `full_field`),
    /// negative inside.
    pub field: Field3,
    pub report: Report,
}

/// A 2D reconstruction: closed curves, φ and the report.
#[derive(Clone, Debug)]
pub struct Reconstruction2 {
    /// Closed curves of φ = 0 (z = 0).
    pub curves: Polylines,
    pub field: Field2,
    pub report: Report,
}

/// Reconstruct a closed surface from 3D data.
pub fn reconstruct_3d(input: &Input, params: &ReconstructParams) -> Result<Reconstruction3> {
    let (field, mut report) = reconstruct_field::<3>(input, params)?;
    let mesh = report.time("extract", || {
        surfrecon_grid::marching::marching_cubes(&field, 0.0)
    });
    Ok(Reconstruction3 {
        mesh,
        field,
        report,
    })
}

/// Reconstruct closed curves from 2D data (z ignored).
pub fn reconstruct_2d(input: &Input, params: &ReconstructParams) -> Result<Reconstruction2> {
    let (field, mut report) = reconstruct_field::<2>(input, params)?;
    let curves = report.time("extract", || {
        surfrecon_grid::marching::marching_squares(&field, 0.0)
    });
    Ok(Reconstruction2 {
        curves,
        field,
        report,
    })
}

/// The level set function φ (negative inside) of the reconstruction in
/// `D` = 2 or 3 dimensions, with the run's report.
pub fn reconstruct_field<const D: usize>(
    input: &Input,
    params: &ReconstructParams,
) -> Result<(Field<D>, Report)> {
    validate::<D>(input, params)?;
    let mut report = Report::default();
    let cleaned;
    let input = if params.clean {
        let (points, stats) = report.time("cleaning", || clean_points(&input.points, D));
        report.cleaning = stats;
        cleaned = Input {
            points,
            segments: input.segments.clone(),
            triangles: input.triangles.clone(),
        };
        &cleaned
    } else {
        input
    };
    let sampling = sampling_spacing(input);
    let fine = fine_grid::<D>(input, params, sampling)?;
    let levels = params
        .levels
        .unwrap_or_else(|| auto_levels(&fine.dims))
        .max(1);
    report.dims = fine.dims.to_vec();
    report.spacing = fine.spacing;
    report.levels = levels;
    let mut band: Option<NarrowBand<D>> = None;
    let mut coarse_d: Option<Field<D>> = None;
    for level in (0..levels).rev() {
        let spec = coarsen(&fine, 1 << level);
        let d = report.time("distance", || match &coarse_d {
            // Coarse levels only give the next level its start: one point per
            // half cell (distances off by at most 0.43 h) is plenty.
            None if level > 0 => unsigned_distance(&thinned(input, spec.spacing / 2.0), spec),
            None => unsigned_distance(input, spec),
            Some(c) => refined_distance(input, spec, c, FINE_EXACT_CELLS),
        })?;
        let mut current = match band.take() {
            None => initial_band(input, params, sampling, &d, &mut report),
            Some(coarse) => report.time("upsample", || {
                let mut b =
                    NarrowBand::from_field(upsample(&coarse.phi, spec), params.band * spec.spacing);
                reinitialize(&mut b);
                b
            }),
        };
        let stage = Stage {
            coarsest: level + 1 == levels,
            finest: level == 0,
        };
        evolve_level(&mut current, &d, params, stage, &mut report);
        band = Some(current);
        coarse_d = Some(d);
    }
    let band = band.expect("at least one level");
    report.band_nodes = band.len();
    report.band_blocks = band.block_count();
    let field = if params.full_field {
        report.time("full field", || signed_distance_everywhere(&band))
    } else {
        band.phi
    };
    Ok((field, report))
}

fn validate<const D: usize>(input: &Input, params: &ReconstructParams) -> Result<()> {
    if input.is_empty() {
        return Err(LevelsetError::InvalidInput(
            "no data to reconstruct from (no points, curves or triangles)".into(),
        ));
    }
    if let Some(bad) = input.all_vertices().find(|v| !v.is_finite()) {
        return Err(LevelsetError::InvalidInput(format!(
            "data contain a non-finite coordinate: {bad}"
        )));
    }
    let bad = |name, message: &str| {
        Err(LevelsetError::InvalidParameter {
            name,
            message: message.to_string(),
        })
    };
    if !(params.p >= 1.0 && params.p.is_finite()) {
        return bad(
            "p",
            &format!("must be a finite number ≥ 1, got {}", params.p),
        );
    }
    if !(params.band >= 2.0 && params.band <= 64.0) {
        return bad(
            "band",
            &format!("must be between 2 and 64 cells, got {}", params.band),
        );
    }
    if params
        .resolution
        .is_some_and(|r| !(4..=100_000).contains(&r))
    {
        return bad("resolution", "must be between 4 and 100000 cells");
    }
    if params.epsilon.is_some_and(|e| !(e > 0.0 && e.is_finite())) {
        return bad("epsilon", "must be a positive number");
    }
    if params.levels.is_some_and(|l| !(1..=6).contains(&l)) {
        return bad("levels", "must be between 1 and 6");
    }
    if !(params.tolerance >= 0.0 && params.tolerance.is_finite()) {
        return bad("tolerance", "must be a non-negative number");
    }
    Ok(())
}

/// Typical gap between neighbouring data: the 95th percentile of the
/// distance from a datum vertex to its nearest other vertex (over at most
/// 20,000 evenly strided vertices); 0 for a single vertex.
fn sampling_spacing(input: &Input) -> f64 {
    let verts: Vec<DVec3> = input.all_vertices().collect();
    if verts.len() < 2 {
        return 0.0;
    }
    let tree = KdTree::new(&verts);
    let stride = (verts.len() / 20_000).max(1);
    let mut gaps: Vec<f64> = verts
        .iter()
        .step_by(stride)
        .filter_map(|&v| tree.knn(v, 2).get(1).map(|n| n.distance))
        .filter(|g| *g > 0.0)
        .collect();
    if gaps.is_empty() {
        return 0.0;
    }
    gaps.sort_by(|a, b| a.total_cmp(b));
    gaps[(gaps.len() - 1) * 95 / 100]
}

/// Data bounds in the first `D` coordinates.
fn bounds<const D: usize>(input: &Input) -> ([f64; D], [f64; D]) {
    let mut lo = [f64::INFINITY; D];
    let mut hi = [f64::NEG_INFINITY; D];
    for v in input.all_vertices() {
        let c = v.to_array();
        for a in 0..D {
            lo[a] = lo[a].min(c[a]);
            hi[a] = hi[a].max(c[a]);
        }
    }
    (lo, hi)
}

/// Default grid spacing as a share of the sampling gap: the zero set is
/// placed to a fraction of a cell, so a grid a little finer than the data
/// gains accuracy (Chamfer distance on the bunny scan −25% against a
/// spacing equal to the gap) at a moderate cost.
const SPACING_PER_GAP: f64 = 0.8;

/// The finest grid: resolution given or from the sampling density, padded
/// so the band and the outer contour stay clear of the border on every
/// level; refused if it would not fit in memory.
fn fine_grid<const D: usize>(
    input: &Input,
    params: &ReconstructParams,
    sampling: f64,
) -> Result<GridSpec<D>> {
    let (lo, hi) = bounds::<D>(input);
    let longest = (0..D).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
    let max_auto = if D == 2 { 1024 } else { 256 };
    let resolution = params.resolution.unwrap_or_else(|| {
        if sampling > 0.0 && longest > 0.0 {
            ((longest / (SPACING_PER_GAP * sampling)).round() as usize).clamp(32, max_auto)
        } else {
            64
        }
    });
    let size = if longest > 0.0 {
        GridSize::Resolution(resolution)
    } else {
        // A single point: any spacing gives the same (tiny) result.
        GridSize::Spacing(1.0 / resolution as f64)
    };
    // Padding: band + stencil border + room for the contour, in cells of
    // the coarsest level (levels are estimated from the unpadded size).
    let unpadded: [usize; D] = std::array::from_fn(|a| {
        let extent = hi[a] - lo[a];
        if longest > 0.0 {
            (extent / longest * resolution as f64).ceil() as usize + 1
        } else {
            2
        }
    });
    let levels = params
        .levels
        .unwrap_or_else(|| auto_levels(&unpadded))
        .clamp(1, 6);
    let per_level = params.band.ceil() as usize + crate::band::BORDER + 3;
    let padding = per_level << (levels - 1);
    let spec = GridSpec::from_bounds(lo, hi, size, padding)?;
    // φ, d (f64 each), marks (u32), tags and labels (u8 each), headroom.
    spec.check_memory(32)?;
    if spec.node_count() > u32::MAX as usize {
        return Err(LevelsetError::InvalidParameter {
            name: "resolution",
            message: format!("grid {} has more than 2^32 nodes", spec.dims_string()),
        });
    }
    Ok(spec)
}

/// Distance, outer contour and tagging, then the initial band.
fn initial_band<const D: usize>(
    input: &Input,
    params: &ReconstructParams,
    sampling: f64,
    d: &Field<D>,
    report: &mut Report,
) -> NarrowBand<D> {
    let h = d.spec.spacing;
    let auto = 3.0 * h.max(sampling);
    let epsilon = params.epsilon.unwrap_or(auto);
    let bbox: Option<BoundingBox<D>> = params.bounding_box.then(|| {
        let (lo, hi) = bounds::<D>(input);
        (lo.map(|x| x - 2.0 * h), hi.map(|x| x + 2.0 * h))
    });
    let tagging = report.time("tagging", || {
        tag(
            d,
            epsilon,
            params.epsilon.is_none(),
            h,
            bbox.as_ref(),
            params.keep_topology,
        )
    });
    report.epsilon = tagging.epsilon;
    report.heap_pops = tagging.heap_pops;
    report.tagged_inside = tagging.inside_count();
    let mut inside = tagging.inside();
    report.removed_components = report.time("tagging", || {
        let data_nodes: Vec<usize> = input
            .all_vertices()
            .filter_map(|v| nearest_node(&d.spec, v))
            .collect();
        remove_unsupported(&d.spec, &mut inside, &data_nodes)
    });
    report.time("reinit", || {
        let mut band = NarrowBand::from_inside(d.spec, &inside, params.band * h);
        reinitialize(&mut band);
        band
    })
}

/// The grid node nearest to `v` (first `D` coordinates), if inside the grid.
fn nearest_node<const D: usize>(spec: &GridSpec<D>, v: DVec3) -> Option<usize> {
    let g = spec.to_grid(std::array::from_fn(|a| v[a]));
    let mut idx = [0usize; D];
    for a in 0..D {
        let i = g[a].round();
        if !(i >= 0.0 && i < spec.dims[a] as f64) {
            return None;
        }
        idx[a] = i as usize;
    }
    Some(spec.linear(idx))
}

/// Where a level stands in the coarse-to-fine sequence.
#[derive(Clone, Copy)]
struct Stage {
    coarsest: bool,
    finest: bool,
}

/// Convergence tolerances are this many times looser on coarse levels:
/// they only give the next level its start.
const COARSE_TOLERANCE: f64 = 2.0;

/// Convection, minimal surface flow, and on the finest level a last
/// convection that settles the zero set onto the data.
fn evolve_level<const D: usize>(
    band: &mut NarrowBand<D>,
    d: &Field<D>,
    params: &ReconstructParams,
    stage: Stage,
    report: &mut Report,
) {
    // Finer levels start from an already converged coarse solution.
    let scale = |n: usize| if stage.coarsest { n } else { n.div_ceil(2) };
    let tolerance = if stage.finest {
        params.tolerance
    } else {
        COARSE_TOLERANCE * params.tolerance
    };
    let conv = EvolveParams {
        max_steps: scale(params.convection_steps),
        tolerance,
        keep_topology: params.keep_topology,
        ..Default::default()
    };
    let stats = report.time("convection", || evolve(band, d, Motion::Convection, &conv));
    report.convection.push(stats);
    let flow = EvolveParams {
        max_steps: scale(params.steps),
        ..conv
    };
    let stats = report.time("flow", || {
        evolve(band, d, Motion::MinimalSurface { p: params.p }, &flow)
    });
    report.flow.push(stats);
    if stage.finest {
        // The flow smooths, and where d > 0 between samples its curvature
        // term also pulls the surface slightly inside the data; a last
        // convection puts the zero set back on the data where there are
        // data, leaving the flow's shape where the surface spans gaps.
        let stats = report.time("settle", || evolve(band, d, Motion::Convection, &conv));
        report.settle.push(stats);
    }
}

/// The input with at most one point per cube of side `cell` (the first
/// in input order): coarse levels need no more, and dense scans have many
/// points per coarse cell. Distances change by at most √3·cell/2.
fn thinned(input: &Input, cell: f64) -> Input {
    let mut seen = std::collections::HashSet::with_capacity(input.points.len());
    let points = input
        .points
        .iter()
        .filter(|p| seen.insert((*p / cell).floor().as_i64vec3().to_array()))
        .copied()
        .collect();
    Input {
        points,
        segments: input.segments.clone(),
        triangles: input.triangles.clone(),
    }
}

/// Cells around the data where finer levels compute the exact distance.
const FINE_EXACT_CELLS: f64 = 2.0;

/// Distance on a finer level: exact within a few cells of the data (where
/// the surface settles and accuracy matters), the coarser level's distance
/// interpolated elsewhere (its error there, O(coarse h), only affects how
/// fast far-away parts move). Saves the full-grid sweeps on the fine grid.
fn refined_distance<const D: usize>(
    input: &Input,
    spec: GridSpec<D>,
    coarse: &Field<D>,
    band_cells: f64,
) -> Result<Field<D>> {
    // Defaults for any other option, present or future.
    #[allow(clippy::needless_update)]
    let options = distance::DistanceOptions {
        band_cells,
        propagate: false,
        ..Default::default()
    };
    let mut exact = distance::unsigned_distance_with(&data_set::<D>(input), &spec, &options)?.field;
    let far = upsample(coarse, spec);
    for (e, f) in exact.values.iter_mut().zip(far.values) {
        if !e.is_finite() {
            *e = f;
        }
    }
    Ok(exact)
}

fn data_set<const D: usize>(input: &Input) -> DataSet<D> {
    let project = |v: &DVec3| -> [f64; D] { std::array::from_fn(|a| v[a]) };
    DataSet::<D> {
        points: input.points.iter().map(project).collect(),
        segments: input
            .segments
            .iter()
            .map(|s| s.each_ref().map(project))
            .collect(),
        triangles: input
            .triangles
            .iter()
            .map(|t| t.each_ref().map(project))
            .collect(),
    }
}

/// Unsigned distance from every node to the data (grid crate: exact near
/// the data, closest-datum sweeping elsewhere; O(nodes + data)).
fn unsigned_distance<const D: usize>(input: &Input, spec: GridSpec<D>) -> Result<Field<D>> {
    Ok(distance::unsigned_distance(&data_set::<D>(input), &spec)?.field)
}
