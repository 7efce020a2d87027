//! The reconstruction pipeline: data → cleaning → distance → tagging →
//! convection → minimal surface flow → settling convection (coarse to
//! fine) → mesh or curves → in 3D, refinement. Stacks of contour slices
//! take the [`crate::slices`] path instead.

use crate::anchors::{with_corners, DataCells, PointPlanes, TangentSides};
use crate::band::{BandDistance, NarrowBand};
use crate::centre;
use crate::cleaning::{clean_points_with_normals, dropped_points, CleaningStats};
use crate::error::{LevelsetError, Result};
use crate::flow::{evolve, Anchors, EvolveParams, EvolveStats, Motion};
use crate::holes::seal_with_normals;
use crate::multires::{
    auto_levels, coarsen, grow_to_points, interpolate, reopen_near_buried, restore_near_missed,
    upsample_band,
};
use crate::reach::{reach_far_points, sampling_gap, MAX_PULL_CELLS};
use crate::refine::{refine_surface, undo_crossing_moves, RefineOptions, RefineStats};
use crate::reinit::{reinitialize, signed_distance_everywhere};
use crate::slices::{detect_slices, interpolate_slices, join_lost_parts, SliceStack};
use crate::tagging::{remove_unsupported, tag, BoundingBox, Tagging};
use std::sync::Arc;
use std::time::Instant;
use surfrecon_geom::progress::{no_progress, Hook, Progress};
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::{DVec3, Geometry, Polylines, TriMesh};
use surfrecon_grid::distance::{self, DataSet};
use surfrecon_grid::marching::{marching_cubes, settle_lone_nodes};
use surfrecon_grid::sparse::{marching_cubes_sparse, Block, BlockGrid, BLOCK};
use surfrecon_grid::spec::for_each_in_box;
use surfrecon_grid::{Field, Field2, Field3, GridSize, GridSpec};

/// The data to reconstruct from: any mix of points, segments (curves) and
/// triangles (surface patches). In 2D only x and y are used.
#[derive(Clone, Debug, Default)]
pub struct Input {
    pub points: Vec<DVec3>,
    /// Unit outward normals of `points`, in the same order, or empty. Used
    /// only to keep the outside from flooding in through holes.
    pub normals: Vec<DVec3>,
    pub segments: Vec<[DVec3; 2]>,
    pub triangles: Vec<[DVec3; 3]>,
}

impl Input {
    /// Whether every point has a normal (and there are points).
    pub fn is_oriented(&self) -> bool {
        !self.points.is_empty() && self.normals.len() == self.points.len()
    }

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
        let normals = match &g.points.normals {
            Some(n) if n.len() == v.len() => n.clone(),
            _ => Vec::new(),
        };
        Input {
            points: v.clone(),
            normals,
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
    /// Maximum minimal surface flow steps.
    pub steps: usize,
    /// Maximum convection steps.
    pub convection_steps: usize,
    /// Narrow band half-width in cells (≥ 2).
    pub band: f64,
    /// Resolution levels (None: automatic, coarse levels for large grids;
    /// coarse levels build the initial surface, the coarsest also evolves).
    pub levels: Option<usize>,
    /// Convergence: mean zero-set displacement per step near the data,
    /// relative to the largest possible (see [`EvolveParams::tolerance`]).
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
    /// 3D: snap the surface onto the point data and fair the patches over
    /// gaps in scans ([`crate::refine`]).
    pub refine: bool,
    /// 3D: data on a few parallel planes (contour slices) are interpolated
    /// between the slices' 2D reconstructions ([`crate::slices`]) instead
    /// of evolved in 3D.
    pub slices: bool,
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
            refine: true,
            slices: true,
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
    /// Points a coarser level left outside its surface, which a finer
    /// level grew the surface back to ([`crate::multires::grow_to_points`]).
    pub grown_to_points: usize,
    /// Points the coarsest evolution left outside, around which the tagged
    /// inside was put back ([`crate::multires::restore_near_missed`]).
    pub restored_near_points: usize,
    /// Points a coarser level's surface buried inside, around which the
    /// next finer level re-opened the filled concavities, summed over the
    /// levels
    /// ([`crate::multires::reopen_near_buried`]).
    pub reopened_near_points: usize,
    /// Nodes whose six neighbours all lay on the other side, given their
    /// side before extraction so they leave no speck
    /// ([`surfrecon_grid::marching::settle_lone_nodes`]).
    pub lone_nodes: usize,
    /// Pieces of a stack of slices joined to the body
    /// ([`crate::slices::join_lost_parts`]).
    pub joined_parts: usize,
    /// Nodes the points' oriented normals sealed against the exterior
    /// flood ([`crate::holes`]).
    pub sealed_nodes: usize,
    /// Tangent disks the finest level's distance includes (0: points
    /// only; see the README).
    pub surfels: usize,
    /// Points added along the given normals of clean points (the corners
    /// of their tangent disks; 0 if none).
    pub densified: usize,
    /// Band nodes at the end.
    pub band_nodes: usize,
    /// Blocks of 8^D nodes (the sparse grid's blocks) allocated for φ.
    pub band_blocks: usize,
    /// Blocks on which the finest level computed the distance d (the
    /// band's blocks and their neighbours).
    pub distance_blocks: usize,
    /// Bytes of φ (blocks, block table, marks, band list) and of d on the
    /// finest level at the end.
    pub band_bytes: usize,
    pub distance_bytes: usize,
    /// Convection and flow statistics (the finest level, the only one
    /// that evolves).
    pub convection: Vec<EvolveStats>,
    pub flow: Vec<EvolveStats>,
    /// The final convection after the flow (finest level only).
    pub settle: Vec<EvolveStats>,
    /// What the 3D refinement did (all zero when off or in 2D).
    pub refine: RefineStats,
    /// Axis and number of the contour slices when the data formed a stack
    /// (then no level-set evolution in 3D ran).
    pub slices: Option<(usize, usize)>,
    /// Seconds per stage, in execution order (upsampling and growing
    /// repeat per level).
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
    /// φ on the sparse block grid: signed distance in the band, ±band
    /// half-width elsewhere; negative inside.
    pub phi: BlockGrid<3>,
    /// φ as a signed distance on the whole grid (`full_field` only).
    pub field: Option<Field3>,
    pub report: Report,
}

/// A 2D reconstruction: closed curves, φ and the report.
#[derive(Clone, Debug)]
pub struct Reconstruction2 {
    /// Closed curves of φ = 0 (z = 0).
    pub curves: Polylines,
    pub phi: BlockGrid<2>,
    pub field: Option<Field2>,
    pub report: Report,
}

impl Reconstruction3 {
    /// φ on the dense grid: the full signed distance with `full_field`,
    /// else the band's values with ±half-width elsewhere. O(grid) memory.
    pub fn dense_field(&self) -> Field3 {
        self.field.clone().unwrap_or_else(|| self.phi.to_dense())
    }
}

impl Reconstruction2 {
    /// See [`Reconstruction3::dense_field`].
    pub fn dense_field(&self) -> Field2 {
        self.field.clone().unwrap_or_else(|| self.phi.to_dense())
    }
}

/// Reconstruct a closed surface from 3D data.
pub fn reconstruct_3d(input: &Input, params: &ReconstructParams) -> Result<Reconstruction3> {
    reconstruct_3d_with(input, params, &no_progress)
}

/// [`reconstruct_3d`] reporting to `hook` between stages and inside the
/// evolutions; [`LevelsetError::Cancelled`] when the hook cancels.
pub fn reconstruct_3d_with(
    input: &Input,
    params: &ReconstructParams,
    hook: Hook,
) -> Result<Reconstruction3> {
    validate::<3>(input, params)?;
    let by = centring::<3>(input);
    let r = reconstruct_3d_centred(&centre::moved(input, by), params, hook)?;
    Ok(r.moved_by(by))
}

/// [`reconstruct_3d_with`] on validated data near the origin.
fn reconstruct_3d_centred(
    input: &Input,
    params: &ReconstructParams,
    hook: Hook,
) -> Result<Reconstruction3> {
    if params.slices {
        if let Some(stack) = detect_slices(input) {
            check(hook, "slices")?;
            return reconstruct_stack(&stack, params);
        }
    }
    let mut report = Report::default();
    check(hook, "cleaning")?;
    let raw = input;
    let input = cleaned(raw, params, 3, &mut report);
    let (mut phi, field) = evolve_field::<3>(&input, params, &mut report, hook)?;
    check(hook, "extract")?;
    // Straight from the blocks: same triangles as on the dense φ.
    let (mut mesh, lone_nodes) = report.time("extract", || {
        let lone_nodes = settle_lone_nodes(&mut phi, 0.0);
        (marching_cubes_sparse(&phi, 0.0), lone_nodes)
    });
    report.lone_nodes = lone_nodes;
    if params.refine && !input.points.is_empty() {
        // Gaps are measured from the points: curves and patches bound them
        // elsewhere, so with them present no patch is faired.
        let options = RefineOptions {
            fair_gaps: input.segments.is_empty() && input.triangles.is_empty(),
            exact_points: report.cleaning.projected == 0,
        };
        check(hook, "refine")?;
        let on_grid = mesh.vertices.clone();
        report.refine = report.time("refine", || {
            let spacing = phi.spec().spacing;
            refine_surface(&mut mesh, &input.points, &input.normals, spacing, options)
        });
        // Before the reach: its pulls to thin tips are what the data ask
        // for, and putting them back would cut the tips again.
        report.refine.uncrossed =
            report.time("uncross", || undo_crossing_moves(&mut mesh, &on_grid));
        if options.exact_points {
            let dropped = dropped_points(&raw.points, &input.points);
            let reached = report.time("reach", || {
                let spacing = phi.spec().spacing;
                reach_far_points(&mut mesh, &input.points, &dropped, spacing, MAX_PULL_CELLS)
            });
            report.refine.reached_far_points = reached;
        }
    }
    Ok(Reconstruction3 {
        mesh,
        phi,
        field,
        report,
    })
}

/// A stack of contour slices: the field interpolated between the slices'
/// 2D reconstructions, and its zero set.
fn reconstruct_stack(stack: &SliceStack, params: &ReconstructParams) -> Result<Reconstruction3> {
    let mut report = Report {
        slices: Some((stack.axis, stack.levels.len())),
        levels: 1,
        ..Default::default()
    };
    let field = report.time("slices", || interpolate_slices(stack, params))?;
    report.dims = field.spec.dims.to_vec();
    report.spacing = field.spec.spacing;
    let mut field = field;
    report.joined_parts = join_lost_parts(&mut field, stack);
    let mut phi = BlockGrid::from_dense_band(&field, params.band * field.spec.spacing)?;
    report.band_blocks = phi.blocks().len();
    let (mesh, lone_nodes) = report.time("extract", || {
        // The cubic blend can dip a single node across zero (a one-node
        // speck). It is no distance, so the band may miss a crossing: the
        // dense field is extracted, with the settled nodes.
        let lone_nodes = settle_lone_nodes(&mut phi, 0.0);
        for (idx, value) in phi.iter_nodes() {
            field.values[field.spec.linear(idx)] = value;
        }
        (marching_cubes(&field, 0.0), lone_nodes)
    });
    report.lone_nodes = lone_nodes;
    Ok(Reconstruction3 {
        mesh,
        phi,
        field: params.full_field.then_some(field),
        report,
    })
}

/// Reconstruct closed curves from 2D data (z ignored).
pub fn reconstruct_2d(input: &Input, params: &ReconstructParams) -> Result<Reconstruction2> {
    reconstruct_2d_with(input, params, &no_progress)
}

/// [`reconstruct_2d`] reporting to `hook`, which may cancel.
pub fn reconstruct_2d_with(
    input: &Input,
    params: &ReconstructParams,
    hook: Hook,
) -> Result<Reconstruction2> {
    validate::<2>(input, params)?;
    let by = centring::<2>(input);
    let (phi, field, mut report) = field_centred::<2>(&centre::moved(input, by), params, hook)?;
    check(hook, "extract")?;
    // 2D grids are small: extract from the dense φ.
    let curves = report.time("extract", || {
        surfrecon_grid::marching::marching_squares(&phi.to_dense(), 0.0)
    });
    let r = Reconstruction2 {
        curves,
        phi,
        field,
        report,
    };
    Ok(r.moved_by(by))
}

/// The level set function φ (negative inside) of the reconstruction in
/// `D` = 2 or 3 dimensions on the sparse block grid, with the dense signed
/// distance everywhere when `full_field` asks for it, and the run's report.
pub fn reconstruct_field<const D: usize>(
    input: &Input,
    params: &ReconstructParams,
) -> Result<(BlockGrid<D>, Option<Field<D>>, Report)> {
    reconstruct_field_with(input, params, &no_progress)
}

/// [`reconstruct_field`] reporting to `hook`, which may cancel.
pub fn reconstruct_field_with<const D: usize>(
    input: &Input,
    params: &ReconstructParams,
    hook: Hook,
) -> Result<(BlockGrid<D>, Option<Field<D>>, Report)> {
    validate::<D>(input, params)?;
    let by = centring::<D>(input);
    let (mut phi, mut field, report) = field_centred::<D>(&centre::moved(input, by), params, hook)?;
    centre::move_fields(&mut phi, field.as_mut(), by);
    Ok((phi, field, report))
}

/// [`reconstruct_field_with`] on validated data near the origin.
fn field_centred<const D: usize>(
    input: &Input,
    params: &ReconstructParams,
    hook: Hook,
) -> Result<(BlockGrid<D>, Option<Field<D>>, Report)> {
    let mut report = Report::default();
    check(hook, "cleaning")?;
    let input = cleaned(input, params, D, &mut report);
    let (phi, field) = evolve_field::<D>(&input, params, &mut report, hook)?;
    Ok((phi, field, report))
}

/// [`LevelsetError::Cancelled`] if `hook` cancels at the start of `stage`.
fn check(hook: Hook, stage: &'static str) -> Result<()> {
    report_to(hook, Progress::stage(stage))
}

fn report_to(hook: Hook, at: Progress) -> Result<()> {
    match hook(at) {
        std::ops::ControlFlow::Continue(()) => Ok(()),
        std::ops::ControlFlow::Break(()) => Err(LevelsetError::Cancelled),
    }
}

/// The input with its points cleaned when `params.clean` asks for it.
fn cleaned<'a>(
    input: &'a Input,
    params: &ReconstructParams,
    dim: usize,
    report: &mut Report,
) -> std::borrow::Cow<'a, Input> {
    if !params.clean {
        return std::borrow::Cow::Borrowed(input);
    }
    let (points, normals, stats) = report.time("cleaning", || {
        clean_points_with_normals(&input.points, &input.normals, dim)
    });
    report.cleaning = stats;
    std::borrow::Cow::Owned(Input {
        points,
        normals,
        segments: input.segments.clone(),
        triangles: input.triangles.clone(),
    })
}

/// [`reconstruct_field`] on validated, cleaned input.
fn evolve_field<const D: usize>(
    input: &Input,
    params: &ReconstructParams,
    report: &mut Report,
    hook: Hook,
) -> Result<(BlockGrid<D>, Option<Field<D>>)> {
    let mut sampling = sampling_spacing(input);
    let fine = fine_grid::<D>(input, params, sampling)?;
    let levels = params
        .levels
        .unwrap_or_else(|| auto_levels(&fine.dims))
        .max(1);
    report.dims = fine.dims.to_vec();
    report.spacing = fine.spacing;
    report.levels = levels;
    // The points' tangent planes, for every level's anchors. Clean points
    // are densified along their given normals, else their distance
    // includes their tangent disks (the grid stays the input's). Points
    // already closer than half a cell apart gain nothing from the corners
    // but their cost (300k spikes: 900k more points, the same surface).
    let sparse = sampling > DENSIFY_BELOW_CELLS * fine.spacing;
    let mut fits = report.time("anchors", || PointPlanes::new(&input.points, D));
    let clean = is_clean_points(input, &report.cleaning);
    let dense;
    let input = match &fits {
        Some(f) if sparse && is_plain_points(input, &report.cleaning) && input.is_oriented() => {
            let with_disk = report.time("anchors", || match clean {
                true => vec![true; input.points.len()],
                false => f.normals_agree(&input.normals),
            });
            let denser = report.time("anchors", || f.densified(&input.normals, &with_disk));
            dense = Input {
                points: denser.points().to_vec(),
                // The sealing of holes reads them.
                normals: with_corners(&input.normals, &with_disk),
                ..Input::default()
            };
            report.densified = dense.points.len() - input.points.len();
            fits = Some(denser);
            &dense
        }
        _ => input,
    };
    if report.densified > 0 {
        sampling = sampling_spacing(input);
    }
    let surfels = match &fits {
        Some(f) if clean && report.densified == 0 => report.time("anchors", || f.surfels()),
        _ => Vec::new(),
    };
    report.surfels = surfels.len();
    let coarsest_spec = coarsen(&fine, 1 << (levels - 1));
    check(hook, "distance")?;
    let coarsest_d = report.time("distance", || {
        let finest = (levels == 1).then_some(surfels.as_slice());
        coarsest_distance(input, coarsest_spec, finest)
    })?;
    check(hook, "tagging")?;
    let mut band = initial_band(input, params, sampling, &coarsest_d, report)?;
    if levels > 1 {
        let data = LevelData {
            input,
            sampling,
            fits: fits.as_ref(),
        };
        band = evolve_coarsest(&data, band, &coarsest_d, params, report, hook)?;
    }
    // Each finer level takes the coarser surface and grows it to the
    // points it missed.
    for level in (0..levels - 1).rev() {
        report_to(
            hook,
            Progress {
                stage: "level",
                done: levels - 1 - level,
                total: levels,
            },
        )?;
        let spec = coarsen(&fine, 1 << level);
        band = report.time("upsample", || -> Result<NarrowBand<D>> {
            let mut b = upsample_band(&band, spec, params.band * spec.spacing)?;
            reinitialize(&mut b);
            Ok(b)
        })?;
        let radius = (GROW_CELLS * spec.spacing).max(GROW_GAPS * sampling);
        let (grown, missed) = report.time("grow", || grow_to_points(band, &input.points, radius));
        band = grown;
        report.grown_to_points += missed;
        // The coarser level filled concavities narrower than its cells.
        let reach = report.epsilon.min(REOPEN_CELLS * spec.spacing);
        let (reopened, buried) = report.time("reopen", || {
            reopen_near_buried(band, &input.points, reach, params.keep_topology)
        });
        band = reopened;
        report.reopened_near_points += buried;
    }
    check(hook, "distance")?;
    let mut d = if levels == 1 {
        BandDistance::dense(coarsest_d)?
    } else {
        report.time("distance", || {
            refined_distance(input, &surfels, fine, coarsest_d, FINE_EXACT_CELLS)
        })?
    };
    let data = LevelData {
        input,
        sampling,
        fits: fits.as_ref(),
    };
    solve_level(&data, &mut band, &mut d, params, report, hook)?;
    report.band_nodes = band.len();
    report.band_blocks = band.block_count();
    report.band_bytes = band.memory_bytes();
    let field = params
        .full_field
        .then(|| report.time("full field", || signed_distance_everywhere(&band)));
    Ok((band.phi, field))
}

/// What every level's evolution reads of the data: the (cleaned,
/// perhaps densified) input, its sampling gap and its tangent planes.
#[derive(Clone, Copy)]
struct LevelData<'a> {
    input: &'a Input,
    sampling: f64,
    fits: Option<&'a PointPlanes>,
}

/// The coarsest level's evolution, which brings the surface from the
/// tagged contour down to the data (into creases and concavities a finer
/// level's convection alone gets stuck over). Parts thinner than a coarse
/// cell erode there, so around every point it leaves outside (by more than
/// [`RESTORE_CELLS`]) the tagged inside is put back within ε, for the finer
/// levels to shape.
fn evolve_coarsest<const D: usize>(
    data: &LevelData,
    tagged: NarrowBand<D>,
    distance: &Arc<Field<D>>,
    params: &ReconstructParams,
    report: &mut Report,
    hook: Hook,
) -> Result<NarrowBand<D>> {
    let mut band = tagged.clone();
    let mut d = BandDistance::dense(distance.clone())?;
    solve_level(data, &mut band, &mut d, params, report, hook)?;
    let epsilon = report.epsilon;
    let (band, restored) = report.time("restore", || {
        restore_near_missed(band, &tagged, &data.input.points, RESTORE_CELLS, epsilon)
    });
    report.restored_near_points = restored;
    Ok(band)
}

/// Points with given normals are densified only when their sampling gap
/// exceeds this many cells.
const DENSIFY_BELOW_CELLS: f64 = 0.5;

/// How far around a buried point a level re-opens, in its cells, at most
/// (else ε): what the next coarser level filled lies within a few of its
/// cells of the data. ε alone is the coarsest level's, and at three
/// levels its balls around tens of thousands of buried points cost
/// minutes (437k points at 400 cells: reopening 316 s, with 8 cells
/// 9 s, the same fit).
const REOPEN_CELLS: f64 = 8.0;

/// Points farther outside the coarse evolved surface than this many coarse
/// cells get the tagged inside back around them (measured on the spikes
/// shape: 2 cells leaves the thin cones eroded and spurious handles).
const RESTORE_CELLS: f64 = 0.5;

/// The coarsest level's unsigned distance on the whole grid. Below finer
/// levels it only gives them their start: one point per half cell
/// (distances off by at most 0.43 h) is plenty.
fn coarsest_distance<const D: usize>(
    input: &Input,
    spec: GridSpec<D>,
    finest: Option<&[[DVec3; 3]]>,
) -> Result<Arc<Field<D>>> {
    let d = match finest {
        Some(surfels) => unsigned_distance(input, surfels, spec)?,
        None => unsigned_distance(&thinned(input, spec.spacing / 2.0), &[], spec)?,
    };
    Ok(Arc::new(d))
}

/// Whether the data are clean points, which the evolution may take as
/// samples of small disks in their tangent planes: with given normals the
/// disks' corners join the points (four times the density for every
/// point-based stage: anchors, restoring, growing; a fin thinner than two
/// sampling gaps then keeps flat faces instead of crumpling), else the
/// finest level's distance includes the disks (surfels), fitted planes
/// being too unreliable in sparse parts to add points on (spikes
/// non-uniform: 5× the error). Either way the surface lies on the sampled
/// surface between samples instead of bulging around each point. Where
/// cleaning dropped outliers some survive, whose disks would scatter: with
/// given normals only the points whose normals agree with their
/// neighbours' then get disks, without them none does.
fn is_clean_points(input: &Input, cleaning: &CleaningStats) -> bool {
    is_plain_points(input, cleaning)
        && (cleaning.outliers as f64) <= STRAY_SHARE * input.points.len() as f64
}

/// Points alone (no curves or patches, which bound gaps themselves) that
/// cleaning did not find noisy: noisy points' disks scatter (1% noise:
/// 5–20% worse).
fn is_plain_points(input: &Input, cleaning: &CleaningStats) -> bool {
    input.segments.is_empty() && input.triangles.is_empty() && cleaning.projected == 0
}

/// Share of the points that cleaning may drop as outliers with the data
/// still counted clean (it drops a few tips of thin parts of clean data;
/// inputs with outliers lose percents).
const STRAY_SHARE: f64 = 1e-3;

/// Balls grown around missed points ([`grow_to_points`]): this many
/// cells, or this many sampling gaps (so that the balls along a chain of
/// points overlap), whichever is larger.
const GROW_CELLS: f64 = 1.5;
const GROW_GAPS: f64 = 0.6;

/// One level's evolution, anchored to the data, with the distance computed
/// on the band's blocks first (the evolution adds blocks as the band moves),
/// so its cost shows as such; records the distance's size.
fn solve_level<const D: usize>(
    data: &LevelData,
    band: &mut NarrowBand<D>,
    d: &mut BandDistance<D>,
    params: &ReconstructParams,
    report: &mut Report,
    hook: Hook,
) -> Result<()> {
    let LevelData {
        input,
        sampling,
        fits,
    } = *data;
    report.time("distance", || d.cover(band));
    let h = band.spec().spacing;
    let (cells, sides) = report.time("anchors", || {
        let (reach, beside) = (2.0 * h.max(sampling), h.max(sampling));
        (
            DataCells::new(*band.spec(), input.all_vertices()),
            fits.map(|f| TangentSides::new(f, band, reach, beside)),
        )
    });
    let anchors = Anchors {
        cells: Some(&cells),
        sides: sides.as_ref(),
    };
    evolve_level(band, d, &anchors, params, report, hook)?;
    report.distance_blocks = d.grid().blocks().len();
    report.distance_bytes = d.memory_bytes();
    Ok(())
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

/// Typical gap between neighbouring data ([`sampling_gap`] over every
/// datum vertex).
fn sampling_spacing(input: &Input) -> f64 {
    let verts: Vec<DVec3> = input.all_vertices().collect();
    if verts.len() < 2 {
        return 0.0;
    }
    sampling_gap(&verts, &KdTree::new(&verts))
}

/// The offset that moves `input` near the origin (see [`centre::offset`]).
fn centring<const D: usize>(input: &Input) -> DVec3 {
    let (lo, hi) = bounds::<D>(input);
    centre::offset(lo, hi)
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
    // Dense arrays live on the coarsest level only: d (f64), tags and
    // labels (u8 each), the band's first dense φ (f64), headroom. Finer
    // levels hold blocks near the surface plus 3 block tables (u32 per
    // block); the dense output field needs φ, d and flags per fine node.
    coarsen(&spec, 1 << (levels - 1)).check_memory(32)?;
    if params.full_field {
        spec.check_memory(24)?;
    }
    // Band keys are u32: block index and node index inside the block.
    let blocks: usize = spec.dims.iter().map(|n| n.div_ceil(BLOCK)).product();
    if blocks.saturating_mul(BLOCK.pow(D as u32)) > u32::MAX as usize {
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
) -> Result<NarrowBand<D>> {
    let h = d.spec.spacing;
    let auto = 3.0 * h.max(sampling);
    let epsilon = params.epsilon.unwrap_or(auto);
    let bbox: Option<BoundingBox<D>> = params.bounding_box.then(|| {
        let (lo, hi) = bounds::<D>(input);
        (lo.map(|x| x - 2.0 * h), hi.map(|x| x + 2.0 * h))
    });
    let run_tag = |field: &Field<D>| {
        tag(
            field,
            epsilon,
            params.epsilon.is_none(),
            h,
            bbox.as_ref(),
            params.keep_topology,
        )
    };
    let mut tagging = report.time("tagging", || run_tag(d));
    // Oriented normals may show that the flood got in through holes; the
    // sealed tagging replaces the plain one only if it then keeps much
    // more inside (elsewhere sealing only adds doubt: scattered normals of
    // noisy data would seal stray nodes).
    if input.is_oriented() {
        let reach = HOLE_REACH * bounds_diagonal::<D>(input);
        let inside = tagging.inside();
        let sealed = report.time("tagging", || {
            seal_with_normals(d, |l| !inside[l], input, epsilon, reach, 0.5)
        });
        if let Some((sealed_d, count)) = sealed {
            let with_seal = report.time("tagging", || run_tag(&sealed_d));
            if with_seal.inside_count() as f64 > FLOODED * tagging.inside_count() as f64 {
                tagging = with_seal;
                report.sealed_nodes = count;
            }
        }
        // ε grown until its contour closed a hole also closes every
        // concavity narrower than itself: webs between a thin part and
        // the body, which the evolution does not open again.
        let grown = params.epsilon.is_none() && tagging.epsilon > epsilon;
        if grown && report.sealed_nodes == 0 {
            let tag_at = |field: &Field<D>| {
                tag(
                    field,
                    epsilon,
                    false,
                    h,
                    bbox.as_ref(),
                    params.keep_topology,
                )
            };
            let sealed = report.time("tagging", || {
                holes_sealed_at(epsilon, d, &tagging, input, tag_at)
            });
            if let Some((with_seal, count)) = sealed {
                tagging = with_seal;
                report.sealed_nodes = count;
            }
        }
    }
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
        let mut band = NarrowBand::from_inside(d.spec, &inside, params.band * h)?;
        reinitialize(&mut band);
        Ok(band)
    })
}

/// The tagging at the starting `epsilon` (by `tag_at`) with the hole
/// that `grown` (the tagging at a grown ε) closed sealed by the oriented
/// normals, and the count of sealed nodes; `None` if the normals do not
/// seal it or the flood still takes much of the inside. The nodes in
/// question are those the starting ε floods and the grown one keeps: the
/// concavities it filled, outside by the normals' winding number, and
/// the inside behind the hole, however deep.
fn holes_sealed_at<const D: usize>(
    epsilon: f64,
    d: &Field<D>,
    grown: &Tagging,
    input: &Input,
    tag_at: impl Fn(&Field<D>) -> Tagging,
) -> Option<(Tagging, usize)> {
    let plain = tag_at(d).inside();
    let kept = grown.inside();
    let flooded = |l: usize| !plain[l] && kept[l];
    let (sealed_d, count) =
        seal_with_normals(d, flooded, input, epsilon, f64::INFINITY, MOUTH_WINDING)?;
    let with_seal = tag_at(&sealed_d);
    let keeps = with_seal.inside_count() as f64 >= SEALED_KEEPS * grown.inside_count() as f64;
    keeps.then_some((with_seal, count))
}

/// How far from the data (share of the bounding box diagonal) oriented
/// normals seal the inside against the flood: the harness's missing
/// patches reach 6% of the diagonal.
const HOLE_REACH: f64 = 0.1;

/// Sealing is kept when it keeps this many times the inside the plain
/// tagging does (the flood through a hole takes most of the inside).
const FLOODED: f64 = 1.3;

/// Winding number above which a node the starting ε floods but the grown
/// ε kept is sealed inside. The outside of a closed part (a concavity the
/// grown ε filled) reads about 0; across a hole it falls from 1/2 inside
/// to 0 in the plane of the missing patch, so sealing only above 1/2
/// starts the fill dented (harness holes, our `eval` CD: box +25%,
/// fandisk +35%, torus +68% with two stray pieces), 0.25 dents the
/// bunny's (+7%); 0.05 and 0.1 score the same within 0.4%.
const MOUTH_WINDING: f64 = 0.1;

/// The tagging at the starting ε with the holes sealed replaces the one
/// at a grown ε if it keeps at least this share of that one's inside (it
/// keeps less only by the concavities the grown ε filled; a flood that
/// the seal did not stop takes most of it).
const SEALED_KEEPS: f64 = 0.8;

fn bounds_diagonal<const D: usize>(input: &Input) -> f64 {
    let (lo, hi) = bounds::<D>(input);
    (0..D).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt()
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

/// Convection, minimal surface flow, and a last convection that settles
/// the zero set onto the data.
fn evolve_level<const D: usize>(
    band: &mut NarrowBand<D>,
    d: &mut BandDistance<D>,
    anchors: &Anchors<D>,
    params: &ReconstructParams,
    report: &mut Report,
    hook: Hook,
) -> Result<()> {
    let conv = EvolveParams {
        max_steps: params.convection_steps,
        tolerance: params.tolerance,
        keep_topology: params.keep_topology,
        ..Default::default()
    };
    let stats = report.time("convection", || {
        evolve(band, d, Motion::Convection, &conv, anchors, hook)
    });
    let cancelled = stats.cancelled;
    report.convection.push(stats);
    if cancelled {
        return Err(LevelsetError::Cancelled);
    }
    let flow = EvolveParams {
        max_steps: params.steps,
        ..conv
    };
    let stats = report.time("flow", || {
        evolve(
            band,
            d,
            Motion::MinimalSurface { p: params.p },
            &flow,
            anchors,
            hook,
        )
    });
    let cancelled = stats.cancelled;
    report.flow.push(stats);
    if cancelled {
        return Err(LevelsetError::Cancelled);
    }
    // The flow smooths, and where d > 0 between samples its curvature term
    // also pulls the surface slightly inside the data; a last convection
    // puts the zero set back on the data where there are data, leaving
    // the flow's shape where the surface spans gaps.
    let stats = report.time("settle", || {
        evolve(band, d, Motion::Convection, &conv, anchors, hook)
    });
    let cancelled = stats.cancelled;
    report.settle.push(stats);
    if cancelled {
        return Err(LevelsetError::Cancelled);
    }
    Ok(())
}

/// The input with at most one point per cube of side `cell` (the first
/// in input order): coarse levels need no more, and dense scans have many
/// points per coarse cell. Distances change by at most √3·cell/2.
fn thinned(input: &Input, cell: f64) -> Input {
    let mut seen = rustc_hash::FxHashSet::default();
    seen.reserve(input.points.len());
    let kept: Vec<usize> = (0..input.points.len())
        .filter(|&i| seen.insert((input.points[i] / cell).floor().as_i64vec3().to_array()))
        .collect();
    let normals = if input.normals.is_empty() {
        Vec::new()
    } else {
        kept.iter().map(|&i| input.normals[i]).collect()
    };
    Input {
        points: kept.iter().map(|&i| input.points[i]).collect(),
        normals,
        segments: input.segments.clone(),
        triangles: input.triangles.clone(),
    }
}

/// Cells around the data where finer levels compute the exact distance.
const FINE_EXACT_CELLS: f64 = 2.0;

/// Distance on a finer level, computed block by block as the band needs
/// it: exact within `band_cells` cells of the data (where the surface
/// settles and accuracy matters), the coarsest level's distance
/// interpolated elsewhere (its error there, O(coarse h), only affects how
/// fast far-away parts move). No work or memory off the band.
fn refined_distance<const D: usize>(
    input: &Input,
    surfels: &[[DVec3; 3]],
    spec: GridSpec<D>,
    coarse: Arc<Field<D>>,
    band_cells: f64,
) -> Result<BandDistance<D>> {
    let mut data = data_set::<D>(input, surfels);
    // Each point lies in its own surfel (its centroid), whose reach (its
    // box grown by the radius) holds the point's ball: with a surfel per
    // point the points themselves can never be nearer, and are left out
    // (half the exact distances at 437k points).
    if surfels.len() == input.points.len() {
        data.points.clear();
    }
    data.validate()?;
    let radius = band_cells * spec.spacing;
    let bins = DataBins::new(&data, &spec, radius);
    BandDistance::new(
        spec,
        Box::new(move |coord, values| {
            exact_block(&data, &bins, &spec, radius, coord, values);
            for (local, v) in values.iter_mut().enumerate() {
                if !v.is_finite() {
                    *v = interpolate(&coarse, spec.position(block_node::<D>(coord, local)));
                }
            }
        }),
    )
}

/// Global index of node `local` of block `coord`.
fn block_node<const D: usize>(coord: [usize; D], local: usize) -> [usize; D] {
    let bits = BLOCK.trailing_zeros() as usize;
    std::array::from_fn(|a| coord[a] * BLOCK + ((local >> (bits * a)) & (BLOCK - 1)))
}

/// Per block of the grid, the data whose reach (box grown by the radius)
/// touches it: compressed rows, block linear index axis 0 fastest.
struct DataBins {
    start: Vec<u32>,
    items: Vec<u32>,
}

impl DataBins {
    fn new<const D: usize>(data: &DataSet<D>, spec: &GridSpec<D>, radius: f64) -> Self {
        let dims = spec.dims.map(|n| n.div_ceil(BLOCK));
        let blocks: usize = dims.iter().product();
        let linear = |c: [usize; D]| (0..D).rev().fold(0, |l, a| l * dims[a] + c[a]);
        let ranges: Vec<Option<([usize; D], [usize; D])>> = (0..data.len())
            .map(|i| {
                spec.node_box(data.datum_bounds(i), radius)
                    .map(|(lo, hi)| (lo.map(|x| x / BLOCK), hi.map(|x| x / BLOCK)))
            })
            .collect();
        let mut count = vec![0u32; blocks + 1];
        for &(lo, hi) in ranges.iter().flatten() {
            for_each_in_box(lo, hi, |&c| count[linear(c) + 1] += 1);
        }
        for b in 0..blocks {
            count[b + 1] += count[b];
        }
        let mut next = count.clone();
        let mut items = vec![0u32; count[blocks] as usize];
        for (i, r) in ranges.iter().enumerate() {
            if let Some((lo, hi)) = *r {
                for_each_in_box(lo, hi, |&c| {
                    let b = linear(c);
                    items[next[b] as usize] = i as u32;
                    next[b] += 1;
                });
            }
        }
        DataBins {
            start: count,
            items,
        }
    }
}

/// Exact distances on block `coord` at the nodes in reach of a datum (as
/// the grid crate's exact band: a point reaches the nodes within `radius`,
/// a segment or triangle those of its box grown by `radius`); other nodes
/// get infinity. Ties go to the smaller datum index.
fn exact_block<const D: usize>(
    data: &DataSet<D>,
    bins: &DataBins,
    spec: &GridSpec<D>,
    radius: f64,
    coord: [usize; D],
    values: &mut [f64],
) {
    let dims = spec.dims.map(|n| n.div_ceil(BLOCK));
    let b = (0..D).rev().fold(0, |l, a| l * dims[a] + coord[a]);
    let mut best = vec![(f64::INFINITY, u32::MAX); Block::<D>::LEN];
    let (block_lo, block_hi): ([usize; D], [usize; D]) = (
        coord.map(|c| c * BLOCK),
        std::array::from_fn(|a| coord[a] * BLOCK + BLOCK - 1),
    );
    let r2 = radius * radius;
    let bits = BLOCK.trailing_zeros() as usize;
    for &i in &bins.items[bins.start[b] as usize..bins.start[b + 1] as usize] {
        let bounds = data.datum_bounds(i as usize);
        let Some((lo, hi)) = spec.node_box(bounds, radius) else {
            continue;
        };
        // The datum lies in the ball around its box's centre through the
        // box's corners: a node farther from that ball than its best datum
        // so far cannot take this one (surfels: most exact distances).
        let centre: [f64; D] = std::array::from_fn(|a| 0.5 * (bounds.0[a] + bounds.1[a]));
        let ball = (0..D)
            .map(|a| (0.5 * (bounds.1[a] - bounds.0[a])).powi(2))
            .sum::<f64>()
            .sqrt();
        let beyond = |p: &[f64; D], best: f64| {
            let to_centre = (0..D)
                .map(|a| (p[a] - centre[a]).powi(2))
                .sum::<f64>()
                .sqrt();
            let gap = (to_centre - ball) * (1.0 - BOUND_SLACK);
            gap > 0.0 && gap * gap > best * (1.0 + BOUND_SLACK)
        };
        let lo: [usize; D] = std::array::from_fn(|a| lo[a].max(block_lo[a]));
        let hi: [usize; D] = std::array::from_fn(|a| hi[a].min(block_hi[a]));
        if (0..D).any(|a| lo[a] > hi[a]) {
            continue;
        }
        let point = data.points.get(i as usize);
        for_each_in_box(lo, hi, |&idx| {
            let p = spec.position(idx);
            let local = (0..D).fold(0, |l, a| l | ((idx[a] - block_lo[a]) << (bits * a)));
            if point.is_none() && beyond(&p, best[local].0) {
                return;
            }
            let d2 = data.distance_squared(i as usize, &p);
            // Points reach a ball (with slack for rounding, as the grid's band).
            if point.is_some() && d2 > r2 * (1.0 + 1e-12) {
                return;
            }
            let cur = &mut best[local];
            if d2 < cur.0 || (d2 == cur.0 && i < cur.1) {
                *cur = (d2, i);
            }
        });
    }
    for (local, (v, &(_, i))) in values.iter_mut().zip(&best).enumerate() {
        *v = if i == u32::MAX {
            f64::INFINITY
        } else {
            data.distance(i as usize, &spec.position(block_node::<D>(coord, local)))
        };
    }
}

/// Relative slack of the bound that skips exact distances in
/// [`exact_block`]: far above rounding, far below any real gap.
const BOUND_SLACK: f64 = 1e-9;

fn data_set<const D: usize>(input: &Input, surfels: &[[DVec3; 3]]) -> DataSet<D> {
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
            .chain(surfels)
            .map(|t| t.each_ref().map(project))
            .collect(),
    }
}

/// Unsigned distance from every node to the data (grid crate: exact near
/// the data, closest-datum sweeping elsewhere; O(nodes + data)).
fn unsigned_distance<const D: usize>(
    input: &Input,
    surfels: &[[DVec3; 3]],
    spec: GridSpec<D>,
) -> Result<Field<D>> {
    Ok(distance::unsigned_distance(&data_set::<D>(input, surfels), &spec)?.field)
}
