//! The `--method svm` part of `surfrecon reconstruct`: fit a multi-scale
//! SVM implicit surface to oriented points (normals from the input, or
//! estimated and oriented) and mesh its zero set by surface-following
//! marching cubes. `reconstruct.rs` flattens [`SvmArgs`] into its arguments
//! and calls [`reconstruct`] (or [`reconstruct_with_resolution`]).

use crate::context::Context;
use anyhow::Context as _;
use serde_json::json;
use std::path::PathBuf;
use surfrecon_geom::normals::{estimate_normals, orient_normals};
use surfrecon_geom::{DVec3, PointCloud, TriMesh};
use surfrecon_svm::mesh::{mesh_model, MeshOptions};
use surfrecon_svm::selection::{select_parameters, SelectionOptions};
use surfrecon_svm::{FitOptions, FitReport, Loss, SvmModel};

/// Residual penalty of the SVM fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LossArg {
    /// ε-insensitive (robust to outliers; the paper's choice).
    Epsilon,
    /// Squared loss (least squares; for comparison).
    Squared,
}

/// SVM-specific flags of `surfrecon reconstruct --method svm`.
#[derive(clap::Args, Clone, Debug)]
pub struct SvmArgs {
    /// Box constraint C relative to each level's local residual, or "auto"
    /// to choose C and ε by validation on held-out points.
    #[arg(long = "svm-c", default_value = "1", value_parser = parse_c)]
    pub svm_c: CSetting,
    /// Width of the ε-insensitive tube, relative to the bounding-box
    /// diagonal; raised to the estimated noise level of the input.
    #[arg(long = "svm-epsilon", default_value_t = 5e-4)]
    pub svm_epsilon: f64,
    /// Fitting accuracy relative to the diagonal: refinement stops when all
    /// proposed base points are fitted within it; raised to twice the
    /// estimated noise level of the input.
    #[arg(long = "svm-accuracy", default_value_t = 1e-3)]
    pub svm_accuracy: f64,
    /// Residual penalty.
    #[arg(long, value_enum, default_value_t = LossArg::Epsilon)]
    pub loss: LossArg,
    /// Leave out the K finest levels when meshing (smoother, no re-fit).
    #[arg(long = "drop-levels", default_value_t = 0, value_name = "K")]
    pub drop_levels: usize,
    /// Also save the fitted model (binary .svm format) to this file.
    #[arg(long = "model-out", value_name = "M.svm")]
    pub model_out: Option<PathBuf>,
    /// Mesh a model saved earlier instead of fitting (the input points
    /// still seed the surface-following meshing).
    #[arg(long = "model-in", value_name = "M.svm")]
    pub model_in: Option<PathBuf>,
    /// Neighbours used to estimate normals when the input has none.
    #[arg(long = "svm-normal-k", default_value_t = 12)]
    pub svm_normal_k: usize,
}

/// A fixed C or selection by validation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CSetting {
    Fixed(f64),
    Auto,
}

fn parse_c(s: &str) -> Result<CSetting, String> {
    if s.eq_ignore_ascii_case("auto") {
        return Ok(CSetting::Auto);
    }
    match s.parse::<f64>() {
        Ok(c) if c.is_finite() && c > 0.0 => Ok(CSetting::Fixed(c)),
        _ => Err(format!("expected a positive number or \"auto\", got {s:?}")),
    }
}

/// Default grid resolution for meshing when none is given.
const DEFAULT_RESOLUTION: usize = 200;

/// Fit and mesh `points` with the default meshing resolution.
pub fn reconstruct(
    points: &PointCloud,
    args: &SvmArgs,
    ctx: &Context,
) -> anyhow::Result<(TriMesh, serde_json::Value)> {
    reconstruct_with_resolution(points, args, None, ctx)
}

/// Fit (or load) a model for `points` and mesh it with `resolution` cells
/// along the longest axis; returns the mesh and a JSON summary (timings,
/// centres per level, chosen parameters).
pub fn reconstruct_with_resolution(
    points: &PointCloud,
    args: &SvmArgs,
    resolution: Option<usize>,
    ctx: &Context,
) -> anyhow::Result<(TriMesh, serde_json::Value)> {
    if points.positions.is_empty() {
        anyhow::bail!("the input has no points to fit");
    }
    let started = ctx.elapsed();
    let (model, fit_summary) = match &args.model_in {
        Some(path) => (
            load_model(path, ctx)?,
            json!({"loaded": path.display().to_string()}),
        ),
        None => fit_model(points, args, ctx)?,
    };
    let fitted = ctx.elapsed();
    let model = if args.drop_levels > 0 {
        ctx.detail(format!(
            "leaving out the {} finest level(s)",
            args.drop_levels
        ));
        model.without_finest(args.drop_levels)
    } else {
        model
    };
    let opts = MeshOptions {
        resolution: resolution.unwrap_or(DEFAULT_RESOLUTION),
        ..Default::default()
    };
    let spinner = ctx.spinner("meshing the zero set");
    let (mesh, mesh_report) = mesh_model(&model, &points.positions, points.bounds(), &opts)
        .context("meshing the SVM implicit surface failed")?;
    spinner.finish_and_clear();
    ctx.say(format!(
        "svm: {} kernel centres in {} levels; mesh {} vertices, {} triangles",
        model.centre_count(),
        model.levels.len(),
        mesh.vertices.len(),
        mesh.triangles.len()
    ));
    let summary = json!({
        "method": "svm",
        "fit": fit_summary,
        "centres": model.centre_count(),
        "levels_used": model.levels.len(),
        "fit_seconds": fitted - started,
        "mesh_seconds": ctx.elapsed() - fitted,
        "mesh": {
            "grid_dims": mesh_report.grid_dims,
            "spacing": mesh_report.spacing,
            "cells_visited": mesh_report.cells_visited,
            "specks_removed": mesh_report.specks_removed,
            "nodes_evaluated": mesh_report.nodes_evaluated,
            "vertices": mesh.vertices.len(),
            "triangles": mesh.triangles.len(),
        },
    });
    Ok((mesh, summary))
}

fn load_model(path: &std::path::Path, ctx: &Context) -> anyhow::Result<SvmModel> {
    let model =
        SvmModel::load(path).with_context(|| format!("cannot load model {}", path.display()))?;
    ctx.detail(format!(
        "loaded model {} ({} centres)",
        path.display(),
        model.centre_count()
    ));
    Ok(model)
}

/// Normals, parameters (given or selected), the fit, and the optional save.
fn fit_model(
    points: &PointCloud,
    args: &SvmArgs,
    ctx: &Context,
) -> anyhow::Result<(SvmModel, serde_json::Value)> {
    let normals = normals_for(points, args.svm_normal_k, ctx);
    let mut opts = FitOptions {
        loss: match args.loss {
            LossArg::Epsilon => Loss::EpsilonInsensitive,
            LossArg::Squared => Loss::Squared,
        },
        epsilon: args.svm_epsilon,
        accuracy: args.svm_accuracy,
        ..Default::default()
    };
    opts.validate().context("invalid SVM parameters")?;
    let mut selection = serde_json::Value::Null;
    opts.c = match args.svm_c {
        CSetting::Fixed(c) => c,
        CSetting::Auto => {
            let spinner = ctx.spinner("choosing C and ε by validation");
            // ε: the given tube and a wider one, which suits noisy data.
            let candidates = SelectionOptions {
                epsilon_values: vec![opts.epsilon, 4.0 * opts.epsilon],
                ..Default::default()
            };
            let s = select_parameters(&points.positions, &normals, &opts, &candidates)
                .context("parameter selection failed")?;
            spinner.finish_and_clear();
            ctx.say(format!(
                "svm: C = {}, ε = {} chosen by validation",
                s.c, s.epsilon
            ));
            opts.epsilon = s.epsilon;
            selection = json!(s
                .trials
                .iter()
                .map(|t| json!({"c": t.c, "epsilon": t.epsilon, "validation_error": t.error}))
                .collect::<Vec<_>>());
            s.c
        }
    };
    let spinner = ctx.spinner("fitting the SVM implicit surface");
    let (model, report) =
        surfrecon_svm::fit(&points.positions, &normals, &opts).context("SVM fit failed")?;
    spinner.finish_and_clear();
    log_levels(&report, ctx);
    if let Some(path) = &args.model_out {
        model
            .save(path)
            .with_context(|| format!("cannot write model {}", path.display()))?;
        ctx.detail(format!("model saved to {}", path.display()));
    }
    let summary = json!({
        "c": opts.c,
        "epsilon": opts.epsilon,
        "accuracy": opts.accuracy,
        "loss": format!("{:?}", opts.loss),
        "selection": selection,
        "seconds": report.seconds,
        "diameter": report.diameter,
        "spacing": report.spacing,
        "noise_estimate": report.noise,
        "isolated_samples": report.isolated,
        "epsilon_used": report.epsilon,
        "accuracy_used": report.tolerance,
        "min_width": report.min_width,
        "levels": report.levels.iter().map(|l| json!({
            "width": l.width,
            "candidates": l.candidates,
            "base_points": l.base_points,
            "centres": l.centres,
            "inconsistent": l.inconsistent,
            "sweeps": l.sweeps,
            "seconds": l.seconds,
        })).collect::<Vec<_>>(),
    });
    Ok((model, summary))
}

fn log_levels(report: &FitReport, ctx: &Context) {
    for (i, l) in report.levels.iter().enumerate() {
        ctx.detail(format!(
            "level {i}: width {:.4}, {} candidates, {} base points, {} centres, {} sweeps, {:.2} s",
            l.width, l.candidates, l.base_points, l.centres, l.sweeps, l.seconds
        ));
    }
}

/// The input's normals, or normals estimated from `k` neighbours and
/// oriented consistently outward.
fn normals_for(points: &PointCloud, k: usize, ctx: &Context) -> Vec<DVec3> {
    if let Some(n) = &points.normals {
        return n.clone();
    }
    ctx.say(format!(
        "svm: no normals in the input; estimating them from {k} neighbours"
    ));
    let mut normals = estimate_normals(&points.positions, k);
    orient_normals(&points.positions, &mut normals, k);
    normals
}
