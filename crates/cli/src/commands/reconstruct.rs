//! `surfrecon reconstruct`: a closed surface (2D: closed curves) from points,
//! curves and triangle patches. Level-set method by default (no normals
//! needed); `--method svm` fits an SVM implicit surface to oriented points;
//! `--method convection` interpolates the points by geometric convection;
//! crossing curve networks are spanned by a Hermite fit. A thin layer over
//! the facade (`surfrecon::reconstruct_with`): flags to options, progress
//! to the spinner, the output and field files, the summary.

use crate::commands::reconstruct_convection::ConvectionArgs;
use crate::commands::reconstruct_svm::{self, SvmArgs};
use crate::context::Context;
use anyhow::Context as _;
use serde_json::json;
use std::path::{Path, PathBuf};
use surfrecon::{io, ControlFlow, Geometry, OutputField, Progress, Report};

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
    /// Use the points as given: no outlier removal, no noise smoothing
    /// (level set and svm).
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
    /// On crossing curves, leave pieces of the surface apart even where
    /// the curves show nothing between them (by default such pieces are
    /// joined by a neck: sections of one object give one solid).
    #[arg(long)]
    pub keep_pieces: bool,
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
    check_flags(&args, &geometry, ctx)?;
    let options = options(&args, ctx.json);
    let spinner = ctx.spinner("reconstructing");
    let hook = |p: Progress| {
        spinner.set_message(match p.total {
            0 => format!("reconstructing: {}", p.stage),
            n => format!("reconstructing: {} {}/{n}", p.stage, p.done),
        });
        ControlFlow::Continue(())
    };
    let output = surfrecon::reconstruct_with(&geometry, &options, &hook);
    spinner.finish_and_clear();
    let mut output = output?;
    if let Some(field) = output.field.take() {
        write_field_outputs(&args, &field)?;
    }
    let mut report = output.report.clone();
    if let Report::LevelSet(r) = &report {
        if r.dimension == 2 && !args.two_d {
            ctx.say("all z coordinates are equal: reconstructing closed curves in 2D");
        }
    }
    if let Report::Svm(r) = &report {
        reconstruct_svm::say_fit(&args.svm, r, ctx);
    }
    let clock = std::time::Instant::now();
    io::write(&args.output, &output.into_geometry())
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    if let Report::Convection(r) = &mut report {
        r.convection.seconds.output += clock.elapsed().as_secs_f64();
    }
    summarize(&args, &report, ctx);
    Ok(())
}

/// Flags that do not apply to the path the data take, refused before the
/// run (only then is the curve-network test made here too).
fn check_flags(args: &Args, geometry: &Geometry, ctx: &Context) -> anyhow::Result<()> {
    let levelset_only = args.field.is_some() || args.shell.is_some() || args.two_d;
    let planar = args.method == Method::Levelset && surfrecon::is_planar(geometry);
    let needs_obj = (args.two_d || planar) && !is_obj(&args.output);
    let network = (levelset_only || needs_obj)
        && !args.no_curve_network
        && surfrecon::detect_curve_network(geometry).is_some();
    if network && levelset_only {
        anyhow::bail!(
            "--field, --shell and --2d apply to the level-set path, not to curve networks (add --no-curve-network)"
        );
    }
    if network {
        return Ok(());
    }
    if args.method != Method::Levelset && levelset_only {
        anyhow::bail!("--field, --shell and --2d apply to --method levelset only");
    }
    if args.method == Method::Convection && geometry.points.positions.is_empty() {
        anyhow::bail!("{} has no points to reconstruct from", args.input.display());
    }
    if args.method == Method::Levelset && needs_obj {
        if planar && !args.two_d {
            ctx.say("all z coordinates are equal: reconstructing closed curves in 2D");
        }
        anyhow::bail!(
            "2D reconstruction gives closed curves, which only OBJ stores here: use an .obj output instead of {}",
            args.output.display()
        );
    }
    Ok(())
}

fn is_obj(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"))
}

/// The facade's options for the flags.
fn options(args: &Args, data_fit: bool) -> surfrecon::Options {
    let method = match args.method {
        Method::Levelset => surfrecon::Method::LevelSet(surfrecon::LevelSetOptions {
            epsilon: args.epsilon,
            p: args.p,
            steps: args.steps,
            band: args.band,
            levels: args.levels,
            bounding_box: args.bounding_box,
            free_topology: args.free_topology,
            cleaning: !args.no_cleaning,
            refine: !args.no_refine,
            slices: !args.no_slices,
            two_d: args.two_d,
            field: match (&args.field, &args.shell) {
                (Some(_), _) => surfrecon::FieldOutput::Full,
                (None, Some(_)) => surfrecon::FieldOutput::Band,
                (None, None) => surfrecon::FieldOutput::None,
            },
        }),
        Method::Svm => surfrecon::Method::Svm(surfrecon::SvmOptions {
            cleaning: !args.no_cleaning,
            ..args.svm.options()
        }),
        Method::Convection => surfrecon::Method::Convection(args.convection.options()),
    };
    surfrecon::Options {
        method,
        resolution: args.resolution,
        curve_network: !args.no_curve_network,
        join_pieces: !args.keep_pieces,
        // With --json only: it costs a pass over the data.
        data_fit,
    }
}

fn write_field_outputs(args: &Args, field: &OutputField) -> anyhow::Result<()> {
    match field {
        OutputField::Two(f) => write_field_files(args, f),
        OutputField::Three(f) => write_field_files(args, f),
    }
}

fn write_field_files<const D: usize>(
    args: &Args,
    field: &surfrecon::Field<D>,
) -> anyhow::Result<()> {
    if let Some(path) = &args.field {
        surfrecon::field_io::write_field(path, field)
            .with_context(|| format!("cannot write field {}", path.display()))?;
    }
    if let Some(path) = &args.shell {
        let shell = surfrecon::shell::Shell::from_field(field);
        surfrecon::shell::write_shell(path, &shell)
            .with_context(|| format!("cannot write shell {}", path.display()))?;
    }
    Ok(())
}

/// The line on stderr and, with `--json`, the report with the command,
/// input and output added.
fn summarize(args: &Args, report: &Report, ctx: &Context) {
    let output = args.output.display();
    match report {
        Report::LevelSet(r) => say_levelset(r, args, ctx),
        Report::Svm(r) => ctx.say(format!(
            "reconstructed a surface with {} vertices, {} triangles (svm) -> {output}",
            r.output_counts.vertices,
            r.output_counts.triangles.unwrap_or(0)
        )),
        Report::Convection(r) => say_convection(r, ctx, &output.to_string()),
        Report::CurveNetwork(r) => ctx.say(format!(
            "reconstructed a closed surface spanning {} curves ({} crossings) with {} vertices in {:.2} s{} -> {output}",
            r.curve_network.curves,
            r.curve_network.crossings,
            r.output_counts.vertices,
            r.seconds_total,
            pieces_note(r.curve_network.joining.as_ref()),
        )),
    }
    if !ctx.json {
        return;
    }
    let mut value = serde_json::to_value(report).unwrap_or_default();
    if let Some(map) = value.as_object_mut() {
        map.insert("command".into(), json!("reconstruct"));
        map.insert("input".into(), json!(args.input));
        map.insert("output".into(), json!(args.output));
    }
    ctx.emit_json(&value);
}

fn say_convection(r: &surfrecon::ConvectionReport, ctx: &Context, output: &str) {
    let c = &r.convection;
    ctx.say(format!(
        "reconstructed a surface through {} of {} points{}, {} triangles (convection{}) -> {output}",
        c.kept_points,
        c.points,
        match c.curved_edges_split {
            0 => String::new(),
            n => format!(" and {n} vertices on curved edges"),
        },
        r.output_counts.triangles.unwrap_or(0),
        match c.boundary_edges {
            0 => String::new(),
            b => format!(", {b} boundary edges"),
        },
    ));
    if c.sampling_holes_opened > 0 {
        ctx.say(format!(
            "left {} hole(s) in the sampling open (no sample inside; --cover-holes covers them)",
            c.sampling_holes_opened
        ));
    }
}

fn say_levelset(r: &surfrecon::LevelSetReport, args: &Args, ctx: &Context) {
    let dims: Vec<String> = r.grid.dims.iter().map(|d| d.to_string()).collect();
    ctx.say(format!(
        "reconstructed {} on a {} grid (h = {:.4}, {} level(s)) in {:.2} s -> {}",
        match (r.dimension == 2, &r.slices) {
            (true, _) => "closed curves".to_string(),
            (false, None) => "a closed surface".to_string(),
            (false, Some(s)) => format!(
                "a closed surface between {} contour slices across {}",
                s.count,
                ["x", "y", "z"][s.axis]
            ),
        },
        dims.join("x"),
        r.grid.spacing,
        r.grid.levels,
        r.seconds_total,
        args.output.display()
    ));
    for t in &r.timings {
        ctx.detail(format!("  {:<12} {:8.3} s", t.stage, t.seconds));
    }
}

/// What joining the pieces of a curve-network surface did, for the summary.
fn pieces_note(joining: Option<&surfrecon::JoinReport>) -> String {
    let Some(j) = joining else {
        return String::new();
    };
    let mut parts = Vec::new();
    if j.pieces_joined > 0 {
        parts.push(format!(
            "{} piece(s) joined to the rest by a neck",
            j.pieces_joined
        ));
    }
    if j.pieces_left_apart > 0 {
        parts.push(format!("{} piece(s) left apart", j.pieces_left_apart));
    }
    if parts.is_empty() {
        String::new()
    } else {
        format!(" ({})", parts.join(", "))
    }
}
