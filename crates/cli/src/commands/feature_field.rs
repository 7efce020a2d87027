//! `surfrecon distance --kind odf|udf`: distance fields that keep the
//! sharp edges and corners of a closed mesh (surfrecon-distfield).

use super::distance::{Args, Kind};
use crate::context::Context;
use anyhow::{bail, Context as _};
use std::time::Instant;
use surfrecon_distfield::format::{write_odf, write_udf};
use surfrecon_distfield::offset::{build_odf, OdfOptions, Weights};
use surfrecon_distfield::unified::{build_udf, UdfOptions};
use surfrecon_geom::io;
use surfrecon_grid::GridSize;

pub fn run(args: &Args, size: GridSize, ctx: &Context) -> anyhow::Result<()> {
    let kind = if args.kind == Kind::Odf { "odf" } else { "udf" };
    check_options(args, kind)?;
    let t_read = Instant::now();
    let geometry = io::read(&args.input)?;
    if !geometry.is_mesh() {
        bail!(
            "--kind {kind} needs a closed triangle mesh, but {} has no triangles",
            args.input.display()
        );
    }
    let mesh = geometry.to_mesh();
    let read_secs = t_read.elapsed().as_secs_f64();
    let spinner = ctx.spinner("computing the field");
    let t_compute = Instant::now();
    let cannot = || format!("cannot build the {kind} of {}", args.input.display());
    let (spec, counts, t_write) = if args.kind == Kind::Odf {
        let options = OdfOptions {
            size,
            padding: args.padding,
            feature_angle_deg: args.feature_angle,
            weights: Weights {
                distance: args.lambda_distance,
                spring: args.lambda_spring,
                ortho: args.lambda_ortho,
            },
            iterations: args.iterations,
        };
        let (field, r) = build_odf(&mesh, &options).with_context(cannot)?;
        let t_write = Instant::now();
        write_odf(&args.output, &field)?;
        let counts = serde_json::json!({
            "feature_cells": r.feature_cells,
            "candidates": r.candidates,
            "samples_moved": r.moved,
            "samples_aligned": r.aligned,
            "smoothed": r.smoothed,
            "repair_places": r.repair_places,
            "repair_moves": r.repaired,
            "energy_before": r.energy_before,
            "energy_after": r.energy_after,
        });
        (field.spec, counts, t_write)
    } else {
        let options = UdfOptions {
            size,
            padding: args.padding,
            threshold: args.threshold,
            feature_angle_deg: args.feature_angle,
        };
        let (field, r) = build_udf(&mesh, &options).with_context(cannot)?;
        let t_write = Instant::now();
        write_udf(&args.output, &field)?;
        let counts = serde_json::json!({
            "boundary_cells": r.boundary_cells,
            "feature_cells": r.feature_cells,
            "directed_distances": r.directed,
            "feature_points": r.feature_points,
            "sharp_cells": r.sharp_cells,
            "cells_repicked": r.repicked,
            "cells_repaired": r.repaired,
            "sample_positions": r.positions,
            "directed_dropped": r.directed_dropped,
        });
        (field.spec, counts, t_write)
    };
    spinner.finish_and_clear();
    let compute_secs = t_write.duration_since(t_compute).as_secs_f64();
    let write_secs = t_write.elapsed().as_secs_f64();
    ctx.say(format!(
        "{kind} on a {} grid (spacing {:.6}): {counts}",
        spec.dims_string(),
        spec.spacing
    ));
    ctx.say_wrote(&args.output, Some(format!("compute {compute_secs:.2} s")));
    ctx.emit_json(&serde_json::json!({
        "command": "distance",
        "kind": kind,
        "input": args.input,
        "output": args.output,
        "signed": true,
        "dims": spec.dims.to_vec(),
        "spacing": spec.spacing,
        "origin": spec.origin.to_vec(),
        kind: counts,
        "seconds": {"read": read_secs, "compute": compute_secs, "write": write_secs, "total": ctx.elapsed()},
    }));
    Ok(())
}

/// Options that do not apply to feature-keeping fields, and the output's
/// extension.
fn check_options(args: &Args, kind: &str) -> anyhow::Result<()> {
    if args.band.is_some() || args.two_d || args.allow_open {
        bail!("--kind {kind} takes neither --band, --2d nor --allow-open: it needs a closed mesh in 3D and computes distances near the surface by itself");
    }
    let ext = args
        .output
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("");
    if !ext.eq_ignore_ascii_case(kind) {
        bail!(
            "{}: a --kind {kind} field is written to a .{kind} file",
            args.output.display()
        );
    }
    if !(args.feature_angle > 0.0 && args.feature_angle < 180.0) {
        bail!(
            "--feature-angle must lie between 0 and 180 degrees, not {}",
            args.feature_angle
        );
    }
    Ok(())
}
