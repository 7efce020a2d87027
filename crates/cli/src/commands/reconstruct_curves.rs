//! The curve-network path of `surfrecon reconstruct`: when the input is
//! curves that cross each other (polylines, or points that lie along
//! curves), the surface spanning them comes from a Hermite fit of the
//! normals the crossings imply, not from a level set, whose weighted-area
//! flow would shrink the film between sparse curves into tubes around them.

use crate::commands::reconstruct::{data_fit_json, Args};
use crate::context::Context;
use anyhow::Context as _;
use serde_json::json;
use std::time::Instant;
use surfrecon_geom::curves::{chain_points, curves_from_polylines, CurveNetwork};
use surfrecon_geom::{io, Geometry, Polylines};
use surfrecon_levelset::slices::detect_slices;
use surfrecon_levelset::Input;
use surfrecon_svm::curve_network::{reconstruct_from_curves, CurveFitOptions};
use surfrecon_svm::hermite::MAX_SAMPLES;

/// A network needs this many curves with implied normals (parallel
/// contour stacks have none and keep the level-set path).
const MIN_CROSSED_CURVES: usize = 2;
/// Denser networks (a wireframe mesh, where every vertex is a crossing)
/// exceed the Hermite fit's dense system and are treated as data like any
/// other: at that density the level set no longer collapses between them.
const MAX_CROSSINGS: usize = MAX_SAMPLES / 2;

/// The input as a crossing curve network, if it is one: only curves (or
/// points along curves), no triangles, not a stack of parallel contour
/// slices (contours within one plane may touch, which is no crossing), and
/// curves that cross.
pub fn detect(geometry: &Geometry) -> Option<CurveNetwork> {
    if !geometry.triangles.is_empty() || detect_slices(&Input::from_geometry(geometry)).is_some() {
        return None;
    }
    let curves = if geometry.lines.is_empty() {
        chain_points(&geometry.points.positions)?
    } else {
        curves_from_polylines(&Polylines {
            vertices: geometry.points.positions.clone(),
            lines: geometry.lines.clone(),
        })
    };
    let network = CurveNetwork::new(curves);
    let fits = network.crossings.len() <= MAX_CROSSINGS;
    (fits && network.crossed_curves() >= MIN_CROSSED_CURVES).then_some(network)
}

pub fn run(
    args: &Args,
    geometry: &Geometry,
    network: &CurveNetwork,
    ctx: &Context,
) -> anyhow::Result<()> {
    if args.field.is_some() || args.shell.is_some() || args.two_d {
        anyhow::bail!(
            "--field, --shell and --2d apply to the level-set path, not to curve networks (add --no-curve-network)"
        );
    }
    let start = Instant::now();
    let options = CurveFitOptions {
        resolution: args.resolution,
        ..Default::default()
    };
    let (mesh, report) = reconstruct_from_curves(network, &options)
        .context("curve-network reconstruction failed")?;
    let seconds = start.elapsed().as_secs_f64();
    let (vertices, triangles) = (mesh.vertices.len(), mesh.triangles.len());
    let fit = data_fit_json(ctx, &mesh, geometry);
    io::write(&args.output, &Geometry::from_mesh(mesh))
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    ctx.say(format!(
        "reconstructed a closed surface spanning {} curves ({} crossings) with {vertices} vertices in {seconds:.2} s -> {}",
        report.curves,
        report.crossings,
        args.output.display()
    ));
    ctx.emit_json(&json!({
        "command": "reconstruct",
        "method": "curve-network",
        "path": "curve network: Hermite fit of the normals implied by the crossings",
        "input": args.input,
        "output": args.output,
        "curve_network": {
            "curves": report.curves,
            "crossings": report.crossings,
            "curves_with_normals": report.curves_with_normals,
            "samples": report.samples,
            "samples_with_normals": report.samples_with_normals,
            "samples_with_in_plane_normals": report.samples_with_in_plane_normals,
            "sample_step": report.sample_step,
            "resolution": report.resolution,
        },
        "seconds_total": seconds,
        "output_counts": {"vertices": vertices, "triangles": triangles},
        "data_fit": fit,
    }));
    Ok(())
}
