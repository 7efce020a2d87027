//! [`Method::Svm`](crate::Method::Svm): fit a multi-scale SVM implicit
//! surface to oriented points (normals from the input, or estimated and
//! oriented) and mesh its zero set by surface-following marching cubes.

use crate::error::{Classify, Error, ErrorKind, Result};
use crate::report::*;
use crate::stack::with_stack_samples;
use crate::{check, data_fit_report, Loss, Output, SvmC, SvmOptions};
use std::time::Instant;
use surfrecon_geom::aabb::offset_to_origin;
use surfrecon_geom::normals::estimate_oriented_sheet_normals;
use surfrecon_geom::progress::Hook;
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::{DVec3, Geometry, PointCloud};
use surfrecon_levelset::cleaning::clean_points_with_normals;
use surfrecon_levelset::refine::{refine_surface, RefineOptions};
use surfrecon_svm::mesh::{mesh_model, MeshOptions};
use surfrecon_svm::noise::estimate_noise_unoriented;
use surfrecon_svm::selection::{select_parameters, SelectionOptions};
use surfrecon_svm::{FitOptions, SvmModel};

/// Meshing resolution when none is given.
pub const DEFAULT_RESOLUTION: usize = 200;

pub(crate) fn run(
    input: &Geometry,
    o: &SvmOptions,
    resolution: Option<usize>,
    data_fit: bool,
    hook: Hook,
) -> Result<Output> {
    let given_points = crate::require_points(input, "fit")?;
    let started = Instant::now();
    // Far from the origin the fit and the mesh grid lose the data's
    // precision (eight points a few units apart near 2e16 ran for half a
    // minute): they run on the data moved near it, exactly, and the mesh
    // and model are moved back.
    let bounds = given_points.bounds();
    let by = offset_to_origin(bounds.min.to_array(), bounds.max.to_array());
    let moved_points = (by != DVec3::ZERO).then(|| moved(given_points, -by));
    let input_points = moved_points.as_ref().unwrap_or(given_points);
    // Only noisy points are used cleaned: dropping the few stray points of
    // clean data cut thin tips off (spikes: a cone's tip as a second
    // piece), and the fit keeps strays out by itself.
    let cleaning = (o.cleaning && o.model_in.is_none())
        .then(|| cleaned_if_noisy(input_points))
        .flatten();
    let points = cleaning
        .as_ref()
        .map_or(input_points, |(cleaned, _)| cleaned);
    // Contour slices: the fit also gets the surface the contours'
    // normals describe between and past them (see `stack`).
    let stacked = o
        .model_in
        .is_none()
        .then(|| with_stack_samples(points))
        .flatten();
    let points = stacked.as_ref().unwrap_or(points);
    // Smoothed points look less noisy than they were measured: the fit
    // keeps the raw points' noise as the floor of its finest width
    // (without it 1% noise gave handles or pieces on 4 of the 7 harness
    // shapes).
    let noise_floor = match cleaning {
        Some(_) => {
            let raw = &input_points.positions;
            estimate_noise_unoriented(raw, &KdTree::new(raw))
        }
        None => 0.0,
    };
    let mut normals_estimated = None;
    let (model, fit) = match &o.model_in {
        Some(path) => (
            SvmModel::load(path)
                .map_err(|e| e.within(&format!("cannot load model {}", path.display())))?
                .translated(-by),
            SvmFit::Loaded {
                loaded: path.display().to_string(),
            },
        ),
        None => {
            if points.normals.is_none() {
                normals_estimated = Some(o.normal_k);
            }
            let (model, mut fit) = fit_model(points, o, noise_floor, hook)?;
            if let Some(path) = &o.model_out {
                model
                    .translated(by)
                    .save(path)
                    .map_err(|e| e.within(&format!("cannot write model {}", path.display())))?;
            }
            fit.cleaning = cleaning.as_ref().map(|(_, report)| *report);
            (model, SvmFit::Fitted(Box::new(fit)))
        }
    };
    let fit_seconds = started.elapsed().as_secs_f64();
    let model = if o.drop_levels > 0 {
        model.without_finest(o.drop_levels)
    } else {
        model
    };
    check(hook, "mesh")?;
    let opts = MeshOptions {
        resolution: resolution.unwrap_or(DEFAULT_RESOLUTION),
        ..Default::default()
    };
    let (mut mesh, m) = mesh_model(&model, &points.positions, points.bounds(), &opts)
        .map_err(|e| e.within("meshing the SVM implicit surface failed"))?;
    // Points the cleaning found clean are exact samples: the mesh goes onto
    // them as the level set's does (between samples, and up to sharp
    // edges), instead of staying on the smooth kernel sum. Not for smoothed
    // points (0.25% noise: 4% worse), points not checked (`--no-cleaning`)
    // nor a loaded model's mesh.
    let exact = o.cleaning && o.model_in.is_none() && cleaning.is_none();
    let refined = exact.then(|| {
        let options = RefineOptions {
            fair_gaps: false,
            exact_points: true,
        };
        refine_surface(&mut mesh, &points.positions, m.spacing, options)
    });
    mesh.vertices.iter_mut().for_each(|v| *v += by);
    let svm = SvmSummary {
        method: "svm",
        fit,
        centres: model.centre_count(),
        levels_used: model.levels.len(),
        fit_seconds,
        mesh_seconds: started.elapsed().as_secs_f64() - fit_seconds,
        mesh: SvmMeshReport {
            grid_dims: m.grid_dims,
            spacing: m.spacing,
            cells_visited: m.cells_visited,
            nodes_evaluated: m.nodes_evaluated,
            specks_removed: m.specks_removed,
            thin_joins: m.thin_joins,
            snapped: refined.map_or(0, |r| r.snapped),
            snapped_to_planes: refined.map_or(0, |r| r.snapped_to_planes),
            vertices: mesh.vertices.len(),
            triangles: mesh.triangles.len(),
        },
    };
    let report = SvmReport {
        method: "svm",
        svm,
        output_counts: OutputCounts::mesh(&mesh),
        data_fit: data_fit.then(|| data_fit_report(&mesh, input)),
        normals_estimated,
    };
    Ok(Output {
        mesh,
        curves: None,
        field: None,
        report: Report::Svm(Box::new(report)),
    })
}

/// `points` moved by `by`.
fn moved(points: &PointCloud, by: DVec3) -> PointCloud {
    let mut moved = points.clone();
    moved.positions.iter_mut().for_each(|p| *p += by);
    moved
}

/// Normals, parameters (given or selected) and the fit.
fn fit_model(
    points: &PointCloud,
    o: &SvmOptions,
    noise_floor: f64,
    hook: Hook,
) -> Result<(SvmModel, SvmFitReport)> {
    check(hook, "normals")?;
    let normals = normals_for(points, o.normal_k);
    let mut opts = FitOptions {
        loss: match o.loss {
            Loss::Epsilon => surfrecon_svm::Loss::EpsilonInsensitive,
            Loss::Squared => surfrecon_svm::Loss::Squared,
        },
        epsilon: o.epsilon,
        accuracy: o.accuracy,
        reorient_normals: points.normals.is_none(),
        noise_floor,
        ..Default::default()
    };
    opts.validate()
        .map_err(|e| e.within("invalid SVM parameters"))?;
    let mut selection = None;
    opts.c = match o.c {
        SvmC::Fixed(c) if c.is_finite() && c > 0.0 => c,
        SvmC::Fixed(c) => {
            return Err(Error::new(
                ErrorKind::InvalidInput,
                format!("invalid SVM parameters: C must be a positive number, got {c}"),
            ))
        }
        SvmC::Auto => {
            check(hook, "selection")?;
            // ε: the given tube and a wider one, which suits noisy data.
            let candidates = SelectionOptions {
                epsilon_values: vec![opts.epsilon, 4.0 * opts.epsilon],
                ..Default::default()
            };
            let s = select_parameters(&points.positions, &normals, &opts, &candidates)
                .map_err(|e| e.within("parameter selection failed"))?;
            opts.epsilon = s.epsilon;
            let trials = s.trials.iter().map(|t| SvmTrial {
                c: t.c,
                epsilon: t.epsilon,
                validation_error: t.error,
            });
            selection = Some(trials.collect());
            s.c
        }
    };
    let (model, report) = surfrecon_svm::fit_with(&points.positions, &normals, &opts, hook)
        .map_err(|e| e.within("SVM fit failed"))?;
    let fit = SvmFitReport {
        c: opts.c,
        epsilon: opts.epsilon,
        accuracy: opts.accuracy,
        loss: format!("{:?}", opts.loss),
        selection,
        seconds: report.seconds,
        diameter: report.diameter,
        spacing: report.spacing,
        noise_estimate: report.noise,
        isolated_samples: report.isolated,
        normals_flipped: report.normals_flipped,
        epsilon_used: report.epsilon,
        accuracy_used: report.tolerance,
        min_width: report.min_width,
        levels: report.levels,
        cleaning: None,
    };
    Ok((model, fit))
}

/// Noisy points with outliers removed and noise smoothed as the level set
/// cleans them (along their normals, if given, each keeping its input
/// point's normal); `None` for points the cleaning finds not noisy. The
/// fit's own noise estimate sees one scan's smoothness, not the
/// misregistration between overlapping scans, which it then follows
/// within ε (the ten merged raw bunny scans: CD-L1 8.6e-5 as given,
/// 6.5e-5 cleaned).
fn cleaned_if_noisy(points: &PointCloud) -> Option<(PointCloud, CleaningReport)> {
    let given = points.normals.as_deref().unwrap_or(&[]);
    let (positions, normals, stats) = clean_points_with_normals(&points.positions, given, 3);
    if stats.projected == 0 {
        return None;
    }
    let cleaned = PointCloud {
        positions,
        normals: points.normals.is_some().then_some(normals),
        scalars: None,
    };
    Some((cleaned, CleaningReport::from(&stats)))
}

/// The input's normals, or normals estimated from `k` neighbours (on
/// thin parts from the point's own side) and oriented consistently
/// outward.
fn normals_for(points: &PointCloud, k: usize) -> Vec<DVec3> {
    if let Some(n) = &points.normals {
        return n.clone();
    }
    estimate_oriented_sheet_normals(&points.positions, k)
}
