//! `surfrecon reconstruct`: a closed surface (2D: closed curves) from points,
//! curves and triangle patches. Level-set method by default (no normals
//! needed); `--method svm` fits an SVM implicit surface to oriented points;
//! `--method convection` interpolates the points by geometric convection.

use crate::commands::reconstruct_convection::{self, ConvectionArgs};
use crate::commands::reconstruct_curves;
use crate::commands::reconstruct_svm::{self, SvmArgs};
use crate::context::Context;
use anyhow::Context as _;
use serde_json::json;
use std::path::{Path, PathBuf};
use surfrecon_geom::data_fit::data_fit;
use surfrecon_geom::{io, Geometry, TriMesh};
use surfrecon_levelset::{reconstruct_2d, reconstruct_3d, Input, ReconstructParams, Report};

/// Reconstruction method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Method {
    /// Level-set method: distance, tagging, convection, minimal surface flow.
    Levelset,
    /// SVM implicit surface (needs or estimates normals).
    Svm,
    /// Geometric convection through the Delaunay tetrahedralization: a mesh
    /// interpolating the points.
    Convection,
}

#[derive(clap::Args)]
pub struct Args {
    /// Input file: points, polylines and/or triangles (ply, obj, off, stl, xyz).
    pub input: PathBuf,
    /// Output mesh (3D) or polylines (2D); format by extension.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Reconstruction method.
    #[arg(long, value_enum, default_value_t = Method::Levelset)]
    pub method: Method,
    /// Grid cells along the longest axis of the data [default: from the sampling density].
    #[arg(long)]
    pub resolution: Option<usize>,
    /// Offset of the initial outer distance contour, in data units [default: from the sampling density].
    #[arg(long)]
    pub epsilon: Option<f64>,
    /// Exponent of the weighted area energy (∫ d^p ds)^(1/p), p ≥ 1.
    #[arg(long, default_value_t = 1.0)]
    pub p: f64,
    /// Maximum minimal surface flow steps per resolution level.
    #[arg(long, default_value_t = 100)]
    pub steps: usize,
    /// Narrow band half-width in cells.
    #[arg(long, default_value_t = 3.0)]
    pub band: f64,
    /// Resolution levels, coarse to fine [default: automatic].
    #[arg(long)]
    pub levels: Option<usize>,
    /// Treat everything outside the data's bounding box as exterior (for very non-uniform data).
    #[arg(long)]
    pub bounding_box: bool,
    /// Let tagging and evolution change the topology (open handles narrower
    /// than ε, split or drop components) [default: the topology of the
    /// initial outer contour is kept].
    #[arg(long)]
    pub free_topology: bool,
    /// Use the points as given: no outlier removal, no noise smoothing.
    #[arg(long)]
    pub no_cleaning: bool,
    /// Keep the surface as the level set left it: no snapping onto the
    /// points, no fairing of the patches over gaps.
    #[arg(long)]
    pub no_refine: bool,
    /// Evolve stacks of parallel contour slices in 3D like any data,
    /// instead of interpolating between the slices' 2D reconstructions.
    #[arg(long)]
    pub no_slices: bool,
    /// Treat crossing curves like any data (level set or SVM) instead of
    /// spanning them with a Hermite fit of the normals the crossings imply.
    #[arg(long)]
    pub no_curve_network: bool,
    /// Also write the signed distance field (.nrrd or .vtk).
    #[arg(long, value_name = "F.nrrd")]
    pub field: Option<PathBuf>,
    /// Also write the thin shell of the field (nodes next to the surface).
    #[arg(long, value_name = "S")]
    pub shell: Option<PathBuf>,
    /// Reconstruct closed curves in the xy plane (automatic when every z is equal).
    #[arg(long = "2d")]
    pub two_d: bool,
    #[command(flatten)]
    pub svm: SvmArgs,
    #[command(flatten)]
    pub convection: ConvectionArgs,
}

pub fn run(args: Args, ctx: &Context) -> anyhow::Result<()> {
    let geometry = io::read(&args.input)?;
    let network = (!args.no_curve_network)
        .then(|| reconstruct_curves::detect(&geometry))
        .flatten();
    let spinner = ctx.spinner("reconstructing");
    let result = match (network, args.method) {
        (Some(network), _) => reconstruct_curves::run(&args, &geometry, &network, ctx),
        (None, Method::Levelset) => run_levelset(&args, &geometry, ctx),
        (None, Method::Svm) => run_svm(&args, &geometry, ctx),
        (None, Method::Convection) => reconstruct_convection::run(&args, &geometry, ctx),
    };
    spinner.finish_and_clear();
    result
}

fn run_svm(args: &Args, geometry: &Geometry, ctx: &Context) -> anyhow::Result<()> {
    if args.field.is_some() || args.shell.is_some() || args.two_d {
        anyhow::bail!("--field, --shell and --2d apply to --method levelset only");
    }
    let (mesh, summary) = match args.resolution {
        None => reconstruct_svm::reconstruct(&geometry.points, &args.svm, ctx)?,
        Some(n) => {
            reconstruct_svm::reconstruct_with_resolution(&geometry.points, &args.svm, Some(n), ctx)?
        }
    };
    let (vertices, triangles) = (mesh.vertices.len(), mesh.triangles.len());
    let fit = data_fit_json(ctx, &mesh, geometry);
    io::write(&args.output, &Geometry::from_mesh(mesh))
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    ctx.say(format!(
        "reconstructed a surface with {vertices} vertices, {triangles} triangles (svm) -> {}",
        args.output.display()
    ));
    ctx.emit_json(&json!({
        "command": "reconstruct",
        "method": "svm",
        "input": args.input,
        "output": args.output,
        "output_counts": {"vertices": vertices, "triangles": triangles},
        "svm": summary,
        "data_fit": fit,
    }));
    Ok(())
}

fn params(args: &Args) -> ReconstructParams {
    ReconstructParams {
        resolution: args.resolution,
        epsilon: args.epsilon,
        p: args.p,
        steps: args.steps,
        band: args.band,
        levels: args.levels,
        bounding_box: args.bounding_box,
        clean: !args.no_cleaning,
        keep_topology: !args.free_topology,
        refine: !args.no_refine,
        slices: !args.no_slices,
        // The shell needs only the nodes next to the surface (in the band).
        full_field: args.field.is_some(),
        ..Default::default()
    }
}

fn run_levelset(args: &Args, geometry: &Geometry, ctx: &Context) -> anyhow::Result<()> {
    let input = Input::from_geometry(geometry);
    let planar = is_planar(&input);
    let two_d = args.two_d || planar;
    if planar && !args.two_d {
        ctx.say("all z coordinates are equal: reconstructing closed curves in 2D");
    }
    let is_obj = args
        .output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    if two_d && !is_obj {
        anyhow::bail!(
            "2D reconstruction gives closed curves, which only OBJ stores here: use an .obj output instead of {}",
            args.output.display()
        );
    }
    let spinner = ctx.spinner("reconstructing");
    let (output, report, counts, fit) = if two_d {
        let r = reconstruct_2d(&input, &params(args)).context("level-set reconstruction failed")?;
        write_field_outputs(args, || r.dense_field())?;
        let counts = json!({"vertices": r.curves.vertices.len(), "curves": r.curves.lines.len()});
        (
            Geometry::from_polylines(r.curves),
            r.report,
            counts,
            serde_json::Value::Null,
        )
    } else {
        let r = reconstruct_3d(&input, &params(args)).context("level-set reconstruction failed")?;
        write_field_outputs(args, || r.dense_field())?;
        let counts =
            json!({"vertices": r.mesh.vertices.len(), "triangles": r.mesh.triangles.len()});
        let fit = data_fit_json(ctx, &r.mesh, geometry);
        (Geometry::from_mesh(r.mesh), r.report, counts, fit)
    };
    spinner.finish_and_clear();
    io::write(&args.output, &output)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    summarize(args, &input, &report, (counts, fit), two_d, ctx);
    Ok(())
}

/// Whether every datum lies in one plane z = const (2D data).
fn is_planar(input: &Input) -> bool {
    let mut zs = input
        .points
        .iter()
        .chain(input.segments.iter().flatten())
        .chain(input.triangles.iter().flatten())
        .map(|v| v.z);
    match zs.next() {
        Some(z0) => zs.all(|z| z == z0),
        None => false,
    }
}

/// `field` gives the dense φ (the reconstruction keeps it sparse): called
/// only when a field or shell file is asked for.
fn write_field_outputs<const D: usize>(
    args: &Args,
    field: impl FnOnce() -> surfrecon_grid::Field<D>,
) -> anyhow::Result<()> {
    if args.field.is_none() && args.shell.is_none() {
        return Ok(());
    }
    let field = &field();
    if let Some(path) = &args.field {
        surfrecon_grid::field_io::write_field(path, field)
            .with_context(|| format!("cannot write field {}", path.display()))?;
    }
    if let Some(path) = &args.shell {
        write_shell(path, field)?;
    }
    Ok(())
}

fn write_shell<const D: usize>(
    path: &Path,
    field: &surfrecon_grid::Field<D>,
) -> anyhow::Result<()> {
    let shell = surfrecon_grid::shell::Shell::from_field(field);
    surfrecon_grid::shell::write_shell(path, &shell)
        .with_context(|| format!("cannot write shell {}", path.display()))
}

fn summarize(
    args: &Args,
    input: &Input,
    report: &Report,
    (counts, fit): (serde_json::Value, serde_json::Value),
    two_d: bool,
    ctx: &Context,
) {
    let dims: Vec<String> = report.dims.iter().map(|d| d.to_string()).collect();
    let total: f64 = report.timings.iter().map(|(_, t)| t).sum();
    ctx.say(format!(
        "reconstructed {} on a {} grid (h = {:.4}, {} level(s)) in {:.2} s -> {}",
        match (two_d, report.slices) {
            (true, _) => "closed curves".to_string(),
            (false, None) => "a closed surface".to_string(),
            (false, Some((axis, count))) => format!(
                "a closed surface between {count} contour slices across {}",
                ["x", "y", "z"][axis]
            ),
        },
        dims.join("x"),
        report.spacing,
        report.levels,
        total,
        args.output.display()
    ));
    for (stage, t) in &report.timings {
        ctx.detail(format!("  {stage:<12} {t:8.3} s"));
    }
    let stages: Vec<serde_json::Value> = report
        .timings
        .iter()
        .map(|(s, t)| json!({"stage": s, "seconds": t}))
        .collect();
    let steps = |v: &[surfrecon_levelset::flow::EvolveStats]| -> Vec<serde_json::Value> {
        v.iter()
            .map(|s| {
                json!({
                    "steps": s.steps,
                    "converged": s.converged,
                    "stopped_by": if s.converged { "convergence" } else { "step cap" },
                    "last_change": s.last_change,
                    "energy": s.energy,
                    "max_band": s.max_band,
                })
            })
            .collect()
    };
    ctx.emit_json(&json!({
        "command": "reconstruct",
        "method": "levelset",
        "input": args.input,
        "output": args.output,
        "dimension": if two_d { 2 } else { 3 },
        "data": {"points": input.points.len(), "segments": input.segments.len(), "triangles": input.triangles.len()},
        "grid": {"dims": report.dims, "spacing": report.spacing, "nodes": report.dims.iter().product::<usize>(), "levels": report.levels},
        "cleaning": {"outliers_removed": report.cleaning.outliers, "projected": report.cleaning.projected, "rms_shift": report.cleaning.rms_shift},
        "epsilon": report.epsilon,
        "surfels": report.surfels,
        "densified": report.densified,
        "tagging": {"heap_pops": report.heap_pops, "inside_nodes": report.tagged_inside, "removed_components": report.removed_components, "grown_to_points": report.grown_to_points, "restored_near_points": report.restored_near_points, "sealed_by_normals": report.sealed_nodes},
        "band_nodes": report.band_nodes,
        "band": {"nodes": report.band_nodes, "blocks": report.band_blocks, "block_nodes": surfrecon_grid::sparse::BLOCK.pow(if two_d { 2 } else { 3 })},
        "convection": steps(&report.convection),
        "flow": steps(&report.flow),
        "settle": steps(&report.settle),
        "refine": {"snapped": report.refine.snapped, "faired": report.refine.faired, "max_fairing_shift": report.refine.max_fairing_shift},
        "slices": report.slices.map(|(axis, count)| json!({"axis": axis, "count": count})),
        "timings": stages,
        "seconds_total": total,
        "output_counts": counts,
        "data_fit": fit,
    }));
}

/// With `--json`: how closely `mesh` reaches every input datum (points,
/// curve and patch vertices); null otherwise (it costs a pass over the data).
pub fn data_fit_json(ctx: &Context, mesh: &TriMesh, geometry: &Geometry) -> serde_json::Value {
    if !ctx.json {
        return serde_json::Value::Null;
    }
    match data_fit(mesh, &geometry.points.positions) {
        Ok(fit) => serde_json::to_value(fit).unwrap_or_default(),
        Err(e) => json!({"error": e.to_string()}),
    }
}
