//! `surfrecon sculpt`: CSG with spheres, boxes, cylinders, meshes or other
//! fields on a distance field of any kind, keeping the new sharp edges in
//! offset and unified fields.

use crate::context::Context;
use anyhow::{bail, Context as _};
use std::path::{Path, PathBuf};
use surfrecon_distfield::format::AnyField;
use surfrecon_distfield::query::MeshQuery;
use surfrecon_distfield::sculpt::{Operation, Tool};
use surfrecon_geom::{io, DVec3};

#[derive(clap::Args)]
pub struct Args {
    /// Field to sculpt: .nrrd or .vtk (3D), .odf or .udf.
    pub input: PathBuf,
    /// Output field, of the input's kind (.nrrd/.vtk, .odf or .udf).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Add TOOL (union). Steps apply in the order given on the command
    /// line. TOOL is `sphere:x,y,z,r`, `box:x0,y0,z0,x1,y1,z1`,
    /// `cylinder:x0,y0,z0,x1,y1,z1,r` (flat caps at the two end points), a
    /// closed mesh file, or another field file.
    #[arg(long, value_name = "TOOL", action = clap::ArgAction::Append)]
    pub union: Vec<String>,
    /// Carve TOOL away (subtraction).
    #[arg(long, value_name = "TOOL", action = clap::ArgAction::Append)]
    pub subtract: Vec<String>,
    /// Keep only what lies inside TOOL (intersection).
    #[arg(long, value_name = "TOOL", action = clap::ArgAction::Append)]
    pub intersect: Vec<String>,
}

pub fn run(args: Args, matches: &clap::ArgMatches, ctx: &Context) -> anyhow::Result<()> {
    let steps = ordered_steps(&args, matches)?;
    let mut field = AnyField::read(&args.input)?;
    let mut reports = Vec::new();
    for (operation, spec) in steps {
        let tool = load_tool(&spec)?;
        let spinner = ctx.spinner(&format!("{operation:?} {spec}"));
        let r = field
            .sculpt(operation, &tool)
            .with_context(|| format!("cannot apply {spec}"))?;
        spinner.finish_and_clear();
        ctx.detail(format!("{operation:?} {spec}: {r:?}"));
        reports.push(serde_json::json!({
            "operation": format!("{operation:?}").to_lowercase(),
            "tool": spec,
            "changed_samples": r.changed,
            "cells": r.cells,
            "edge_points": r.edge_points,
            "edge_points_kept": r.kept,
            "directed_distances": r.directed,
            "dropped": r.dropped,
            "samples_moved_onto_corners": r.snapped,
            "samples_turned": r.turned,
            "feature_points_repicked": r.repicked,
            "feature_points_repaired": r.repaired,
            "samples_moved_into_thin_walls": r.thin,
            "samples_raised_to_settle_faces": r.settled,
            "samples_set_to_straighten_floating_edges": r.straightened,
            "further_feature_points": r.further,
            "corner_sets": r.corner_sets,
            "samples_fitted": r.fitted,
        }));
    }
    field.write(&args.output)?;
    ctx.say_wrote(&args.output, None);
    ctx.emit_json(&serde_json::json!({
        "command": "sculpt",
        "input": args.input,
        "output": args.output,
        "steps": reports,
        "seconds": ctx.elapsed(),
    }));
    Ok(())
}

/// The (operation, tool) steps in command-line order.
fn ordered_steps(
    args: &Args,
    matches: &clap::ArgMatches,
) -> anyhow::Result<Vec<(Operation, String)>> {
    let mut steps: Vec<(usize, Operation, String)> = Vec::new();
    for (id, operation, tools) in [
        ("union", Operation::Union, &args.union),
        ("subtract", Operation::Subtract, &args.subtract),
        ("intersect", Operation::Intersect, &args.intersect),
    ] {
        let indices = matches.indices_of(id).into_iter().flatten();
        steps.extend(indices.zip(tools).map(|(i, t)| (i, operation, t.clone())));
    }
    if steps.is_empty() {
        bail!("nothing to do: give at least one --union, --subtract or --intersect TOOL");
    }
    steps.sort_by_key(|s| s.0);
    Ok(steps.into_iter().map(|(_, o, t)| (o, t)).collect())
}

fn load_tool(spec: &str) -> anyhow::Result<Tool> {
    let numbers = |text: &str, count: usize, form: &str| -> anyhow::Result<Vec<f64>> {
        let values: Vec<f64> = text
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .with_context(|| format!("{spec}: expected {form}"))?;
        if values.len() != count || values.iter().any(|v| !v.is_finite()) {
            bail!("{spec}: expected {form} ({count} finite numbers)");
        }
        Ok(values)
    };
    let v = |x: &[f64]| DVec3::new(x[0], x[1], x[2]);
    let tool = if let Some(rest) = spec.strip_prefix("sphere:") {
        let x = numbers(rest, 4, "sphere:x,y,z,r")?;
        Tool::Sphere {
            centre: v(&x),
            radius: x[3],
        }
    } else if let Some(rest) = spec.strip_prefix("box:") {
        let x = numbers(rest, 6, "box:x0,y0,z0,x1,y1,z1")?;
        Tool::Box {
            min: v(&x[..3]),
            max: v(&x[3..]),
        }
    } else if let Some(rest) = spec.strip_prefix("cylinder:") {
        let x = numbers(rest, 7, "cylinder:x0,y0,z0,x1,y1,z1,r")?;
        Tool::Cylinder {
            a: v(&x[..3]),
            b: v(&x[3..6]),
            radius: x[6],
        }
    } else {
        Tool::Surface(Box::new(surface_of(Path::new(spec))?))
    };
    tool.check()?;
    Ok(tool)
}

/// A tool file: a field (its surface) or a closed mesh.
fn surface_of(path: &Path) -> anyhow::Result<MeshQuery> {
    if !path.exists() {
        bail!(
            "{}: no such file (a tool is sphere:..., box:..., cylinder:... or a file)",
            path.display()
        );
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let is_field =
        surfrecon_distfield::format::sniff(path)?.is_some() || ext == "nrrd" || ext == "vtk";
    let mesh = if is_field {
        AnyField::read(path)?.surface()
    } else {
        let mesh = io::read(path)?.to_mesh();
        surfrecon_distfield::check_mesh(&mesh)
            .with_context(|| format!("{} cannot be a tool", path.display()))?;
        mesh
    };
    if mesh.triangles.is_empty() {
        bail!("{}: the tool has no surface", path.display());
    }
    Ok(MeshQuery::new(&mesh)?)
}
