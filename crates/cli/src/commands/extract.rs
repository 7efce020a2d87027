//! `surfrecon extract`: the isosurface of a field file as a triangle mesh
//! (3D fields, marching cubes) or as curves (2D fields, marching squares).

use crate::context::Context;
use anyhow::{bail, Context as _};
use std::path::PathBuf;
use surfrecon_geom::{io, metrics, Geometry};
use surfrecon_grid::field_io::{read_field, AnyField};
use surfrecon_grid::marching::{marching_cubes, marching_squares};
use surfrecon_grid::{Field2, Field3};

#[derive(clap::Args)]
pub struct Args {
    /// Field file: .nrrd or .vtk (2D or 3D), or an offset (.odf) or
    /// unified (.udf) distance field.
    pub input: PathBuf,
    /// Output: a mesh (.ply, .obj, .off, .stl) for a 3D field, curves
    /// (.obj, written as `l` lines) for a 2D field.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Field value of the extracted level set.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub iso: f64,
}

pub fn run(args: Args, ctx: &Context) -> anyhow::Result<()> {
    if !args.iso.is_finite() {
        bail!("--iso must be a finite number, not {}", args.iso);
    }
    if surfrecon_distfield::format::sniff(&args.input)?.is_some() {
        return feature_surface(&args, ctx);
    }
    surfrecon_distfield::format::check_field_extension(&args.input)?;
    let field = read_field(&args.input)?;
    check_crosses(&field, args.iso, &args)?;
    let spinner = ctx.spinner("extracting");
    let (geometry, summary) = match &field {
        AnyField::D3(f) => surface(f, args.iso, ctx),
        AnyField::D2(f) => curves(f, args.iso, ctx),
    };
    spinner.finish_and_clear();
    write_output(&args, &field, &geometry)?;
    ctx.say_wrote(&args.output, None);
    ctx.emit_json(&serde_json::json!({
        "command": "extract",
        "input": args.input,
        "output": args.output,
        "dimension": field.dimension(),
        "dims": field.dims(),
        "iso": args.iso,
        "result": summary,
        "seconds": ctx.elapsed(),
    }));
    Ok(())
}

/// The surface of an offset or unified field: marching cubes on its
/// offset grid with its stored crossings and feature fans.
fn feature_surface(args: &Args, ctx: &Context) -> anyhow::Result<()> {
    if args.iso != 0.0 {
        bail!("{}: offset and unified fields store their sharp features for the surface itself (iso 0) only", args.input.display());
    }
    let (mesh, report) = match surfrecon_distfield::format::AnyField::read(&args.input)? {
        surfrecon_distfield::format::AnyField::Offset(f) => f.extract(),
        surfrecon_distfield::format::AnyField::Unified(f) => f.extract(),
        surfrecon_distfield::format::AnyField::Regular(_) => unreachable!("sniffed as odf/udf"),
    };
    if mesh.triangles.is_empty() {
        bail!(
            "{}: the field has no surface (it never changes sign)",
            args.input.display()
        );
    }
    let mut summary = mesh_summary(&mesh, ctx);
    summary["fans"] = report.fans.into();
    summary["fans_refused"] = report.fans_refused.into();
    summary["flips"] = report.flips.into();
    summary["merged"] = report.merged.into();
    summary["collapsed"] = report.collapsed.into();
    summary["joined"] = report.joined.into();
    let format = io::Format::from_path(&args.output)?;
    if !format.stores_triangles() {
        bail!(
            "{}: format {format} cannot hold a triangle mesh",
            args.output.display()
        );
    }
    io::write(&args.output, &Geometry::from_mesh(mesh))
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    ctx.say_wrote(&args.output, None);
    ctx.emit_json(&serde_json::json!({
        "command": "extract",
        "input": args.input,
        "output": args.output,
        "dimension": 3,
        "iso": 0.0,
        "result": summary,
        "seconds": ctx.elapsed(),
    }));
    Ok(())
}

/// Marching cubes; prints and returns the counts and topology.
fn surface(field: &Field3, iso: f64, ctx: &Context) -> (Geometry, serde_json::Value) {
    let mesh = marching_cubes(field, iso);
    let summary = mesh_summary(&mesh, ctx);
    (Geometry::from_mesh(mesh), summary)
}

/// Prints and returns a mesh's counts and topology.
fn mesh_summary(mesh: &surfrecon_geom::TriMesh, ctx: &Context) -> serde_json::Value {
    let topo = metrics::topology(mesh);
    let shape = if topo.watertight {
        "closed"
    } else {
        "open where it meets the grid boundary"
    };
    ctx.say(format!(
        "{} triangles, {} vertices, {} component(s), {shape}",
        mesh.triangles.len(),
        mesh.vertices.len(),
        topo.components
    ));
    serde_json::json!({
        "vertices": mesh.vertices.len(),
        "triangles": mesh.triangles.len(),
        "watertight": topo.watertight,
        "components": topo.components,
        "euler": topo.euler,
    })
}

/// Marching squares; prints and returns the curve counts.
fn curves(field: &Field2, iso: f64, ctx: &Context) -> (Geometry, serde_json::Value) {
    let curves = marching_squares(field, iso);
    let closed = curves
        .lines
        .iter()
        .filter(|l| l.len() > 2 && l.first() == l.last())
        .count();
    ctx.say(format!(
        "{} curve(s) ({closed} closed), {} vertices",
        curves.lines.len(),
        curves.vertices.len()
    ));
    let summary = serde_json::json!({
        "vertices": curves.vertices.len(),
        "curves": curves.lines.len(),
        "closed_curves": closed,
    });
    (Geometry::from_polylines(curves), summary)
}

/// Refuse a level that the field never crosses: the result would be empty.
fn check_crosses(field: &AnyField, iso: f64, args: &Args) -> anyhow::Result<()> {
    let (lo, hi) = field
        .values()
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    if !(lo < iso && hi >= iso) {
        bail!(
            "{}: the field never crosses iso {iso} (values range from {lo} to {hi}); choose --iso inside that range",
            args.input.display()
        );
    }
    Ok(())
}

fn write_output(args: &Args, field: &AnyField, geometry: &Geometry) -> anyhow::Result<()> {
    let format = io::Format::from_path(&args.output)?;
    if field.dimension() == 2 && !format.stores_lines() {
        bail!(
            "{}: a 2D field gives curves, which only .obj files hold (format {format} cannot)",
            args.output.display()
        );
    }
    io::write(&args.output, geometry)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    Ok(())
}
