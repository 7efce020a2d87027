//! [`Method::Svm`](crate::Method::Svm): fit a multi-scale SVM implicit
//! surface to oriented points (normals from the input, or estimated and
//! oriented) and mesh its zero set by surface-following marching cubes.

use crate::error::{Classify, Error, ErrorKind, Result};
use crate::report::*;
use crate::stack::{EndCaps, Interpolated, StackSamples};
use crate::{check, data_fit_report, Loss, Output, SvmC, SvmOptions};
use std::time::Instant;
use surfrecon_geom::aabb::offset_to_origin;
use surfrecon_geom::metrics::{topology, Topology};
use surfrecon_geom::normals::estimate_oriented_sheet_normals;
use surfrecon_geom::progress::Hook;
use surfrecon_geom::spatial::KdTree;
use surfrecon_geom::{DVec3, Geometry, PointCloud, TriMesh};
use surfrecon_levelset::cleaning::{clean_points_with_normals, dropped_points};
use surfrecon_levelset::reach::reach_far_points;
use surfrecon_levelset::refine::{refine_surface, undo_crossing_moves, RefineOptions, RefineStats};
use surfrecon_svm::mesh::{mesh_model, MeshOptions, MeshReport};
use surfrecon_svm::noise::estimate_noise_unoriented;
use surfrecon_svm::selection::{select_parameters, SelectionOptions};
use surfrecon_svm::{FitOptions, SvmModel};

/// Meshing resolution when none is given.
pub const DEFAULT_RESOLUTION: usize = 200;

/// Thin parts' tips up to this many mesh cells past the surface are
/// reached. The fit ends a cone thinner than its finest kernels far
/// shorter than the level set does (8 cells): its last samples sit inside
/// the ε tube of nothing (harness spikes: 12 cells on the clean +x needle,
/// 17 on the sparse −x cone of the non-uniform sample).
const MAX_TIP_CELLS: f64 = 24.0;

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
    let checked = (o.cleaning && o.model_in.is_none()).then(|| checked(input_points));
    let cleaning = checked.as_ref().and_then(Checked::noisy);
    let points = cleaning.map_or(input_points, |(cleaned, _)| cleaned);
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
    // Points the cleaning found clean are exact samples: the mesh goes onto
    // them as the level set's does (between samples, and up to sharp
    // edges), instead of staying on the smooth kernel sum. Not for smoothed
    // points (0.25% noise: 4% worse), points not checked (`--no-cleaning`)
    // nor a loaded model's mesh.
    let exact = checked.is_some() && cleaning.is_none();
    let settings = SurfaceSettings {
        o,
        by,
        noise_floor,
        data_noise: cleaning.map_or(0.0, |(_, report)| report.rms_shift),
        resolution: resolution.unwrap_or(DEFAULT_RESOLUTION),
        exact,
    };
    let plain = surface(points, &settings, hook)?;
    let mut mesh_seconds = plain.mesh_seconds;
    // Contour slices: the fit also gets the surface the contours'
    // normals describe between and past them (see `stack`).
    let (mut kept, contour_stack) = match o.model_in {
        None => with_contour_stack(points, plain, &settings, &mut mesh_seconds, hook)?,
        Some(_) => (plain, None),
    };
    if let (Some(path), SvmFit::Fitted(_)) = (&o.model_out, &kept.fit) {
        kept.model
            .translated(by)
            .save(path)
            .map_err(|e| e.within(&format!("cannot write model {}", path.display())))?;
    }
    if let SvmFit::Fitted(fit) = &mut kept.fit {
        fit.cleaning = cleaning.map(|(_, report)| *report);
    }
    // Not for contour stacks: their samples between the contours are
    // guesses, and the contours' own ends are no thin parts' tips.
    let reaching = Instant::now();
    let reached = match (&checked, contour_stack) {
        (Some(checked), None) if exact => reach_thin_parts(
            &mut kept.mesh,
            &checked.kept.positions,
            &input_points.positions,
            kept.meshing.spacing,
        ),
        _ => 0,
    };
    mesh_seconds += reaching.elapsed().as_secs_f64();
    let normals_estimated =
        (o.model_in.is_none() && points.normals.is_none()).then_some(o.normal_k);
    let Surface {
        fit,
        centres,
        levels_used,
        mut mesh,
        meshing: m,
        refined,
        ..
    } = kept;
    mesh.vertices.iter_mut().for_each(|v| *v += by);
    let svm = SvmSummary {
        method: "svm",
        fit,
        contour_stack,
        centres,
        levels_used,
        fit_seconds: started.elapsed().as_secs_f64() - mesh_seconds,
        mesh_seconds,
        mesh: SvmMeshReport {
            grid_dims: m.grid_dims,
            spacing: m.spacing,
            cells_visited: m.cells_visited,
            nodes_evaluated: m.nodes_evaluated,
            specks_removed: m.specks_removed,
            thin_joins: m.thin_joins,
            thin_samples_reached: m.thin_samples_reached,
            pinholes_filled: m.pinholes_filled,
            snapped: refined.map_or(0, |r| r.snapped),
            snapped_to_planes: refined.map_or(0, |r| r.snapped_to_planes),
            snapped_to_edges: refined.map_or(0, |r| r.snapped_to_edges),
            reached_far_points: reached,
            uncrossed: refined.map_or(0, |r| r.uncrossed),
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

/// What every surface of one run is made with.
#[derive(Clone, Copy)]
struct SurfaceSettings<'a> {
    o: &'a SvmOptions,
    /// The points' move towards the origin (undone on the model saved).
    by: DVec3,
    noise_floor: f64,
    /// The raw points' noise as the cleaning measured it (its RMS shift;
    /// 0 for points not cleaned): where the mesh may join across a pinch.
    /// Not `noise_floor`: that estimate reads lower (spikes, 0.25 % / 1 %
    /// noise: 0.016 / 0.037 against 0.019 / 0.061) and left the +x cone
    /// cut at its root at 0.25 %.
    data_noise: f64,
    resolution: usize,
    /// Refine the mesh onto the points (see `run`).
    exact: bool,
}

/// One model, fitted or loaded, and its mesh, near the origin.
struct Surface {
    /// As fitted or loaded: what `--model-out` saves.
    model: SvmModel,
    fit: SvmFit,
    /// Centres and levels of the model meshed (`--drop-levels` applied).
    centres: usize,
    levels_used: usize,
    mesh: TriMesh,
    meshing: MeshReport,
    refined: Option<RefineStats>,
    mesh_seconds: f64,
}

/// The model fitted to `points` (or loaded), meshed over them and, for
/// exact points, refined onto them.
fn surface(points: &PointCloud, s: &SurfaceSettings, hook: Hook) -> Result<Surface> {
    let o = s.o;
    let (model, fit) = match &o.model_in {
        Some(path) => (
            SvmModel::load(path)
                .map_err(|e| e.within(&format!("cannot load model {}", path.display())))?
                .translated(-s.by),
            SvmFit::Loaded {
                loaded: path.display().to_string(),
            },
        ),
        None => {
            let (model, fit) = fit_model(points, o, s.noise_floor, hook)?;
            (model, SvmFit::Fitted(Box::new(fit)))
        }
    };
    let started = Instant::now();
    let meshed = (o.drop_levels > 0).then(|| model.without_finest(o.drop_levels));
    let meshed = meshed.as_ref().unwrap_or(&model);
    check(hook, "mesh")?;
    let opts = MeshOptions {
        resolution: s.resolution,
        data_noise: s.data_noise,
        ..Default::default()
    };
    let (mut mesh, meshing) = mesh_model(meshed, &points.positions, points.bounds(), &opts)
        .map_err(|e| e.within("meshing the SVM implicit surface failed"))?;
    let refined = s.exact.then(|| {
        let options = RefineOptions {
            fair_gaps: false,
            exact_points: true,
        };
        let on_grid = mesh.vertices.clone();
        let mut stats = refine_surface(&mut mesh, &points.positions, &[], meshing.spacing, options);
        stats.uncrossed = undo_crossing_moves(&mut mesh, &on_grid);
        stats
    });
    Ok(Surface {
        centres: meshed.centre_count(),
        levels_used: meshed.levels.len(),
        model,
        fit,
        mesh,
        meshing,
        refined,
        mesh_seconds: started.elapsed().as_secs_f64(),
    })
}

/// For a stack of contour slices, the surface fitted with the samples the
/// contours' normals describe (see `stack`), else `plain`, and what
/// became of the samples (`None`: no stack). Those samples are guesses
/// (mid-gap curves, end caps), not data: a surface with more pieces or
/// more handles than the contours alone give is not what the contours
/// describe, and then the fit is tried again without the end caps, the
/// boldest guesses (a dome over a whole end section; on the harness's
/// slices they gave bunny its extra handles and spikes an end section
/// capped into a piece of its own), then also without the level set's
/// interpolated samples, and failing that `plain` is kept.
/// `mesh_seconds` grows by the meshing time of each surface made.
fn with_contour_stack(
    points: &PointCloud,
    plain: Surface,
    settings: &SurfaceSettings,
    mesh_seconds: &mut f64,
    hook: Hook,
) -> Result<(Surface, Option<ContourStack>)> {
    let Some(samples) = StackSamples::of(points) else {
        return Ok((plain, None));
    };
    // Not snapped: most of the points are guesses, and snapping onto them
    // and the contours left needles along the slices (harness slices: CD
    // 2-10 % higher, the bunny's farthest contour point 1.6 % of the
    // diagonal off against 0.7 %).
    let settings = SurfaceSettings {
        exact: false,
        ..*settings
    };
    let mut verdict = None;
    for (caps, interpolated, used) in [
        (EndCaps::Added, Interpolated::Added, ContourStack::Used),
        (
            EndCaps::Left,
            Interpolated::Added,
            ContourStack::UsedWithoutCaps,
        ),
        (
            EndCaps::Left,
            Interpolated::Left,
            ContourStack::UsedWithoutInterpolation,
        ),
    ] {
        let stacked = surface(&samples.joined(points, caps, interpolated), &settings, hook)?;
        *mesh_seconds += stacked.mesh_seconds;
        match stack_verdict(&plain.mesh, &stacked.mesh) {
            None => return Ok((stacked, Some(used))),
            Some(dropped) => verdict = verdict.or(Some(dropped)),
        }
    }
    Ok((plain, verdict))
}

/// Why the surface fitted with a contour stack's samples is not kept over
/// the one fitted to the contours alone: it has more pieces, or more
/// handles; `None` if it is kept.
fn stack_verdict(plain: &TriMesh, stacked: &TriMesh) -> Option<ContourStack> {
    let (plain, stacked) = (topology(plain), topology(stacked));
    if stacked.components > plain.components {
        Some(ContourStack::DroppedMorePieces)
    } else if twice_handles(&stacked) > twice_handles(&plain) {
        Some(ContourStack::DroppedMoreHandles)
    } else {
        None
    }
}

/// Twice the handles of a closed surface (each piece's Euler
/// characteristic is 2 − 2·handles). Counted per piece rather than by
/// the Euler characteristic alone, which also drops by 2 when two pieces
/// join into one: that is no handle.
fn twice_handles(t: &Topology) -> i64 {
    2 * t.components as i64 - t.euler
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

/// The input as the level set's cleaning finds it: its outliers dropped
/// and, if it is noisy, its noise smoothed (along the normals, if given,
/// each kept point keeping its input point's normal).
struct Checked {
    kept: PointCloud,
    report: CleaningReport,
}

impl Checked {
    /// The cleaned points, for points the cleaning finds noisy: the fit's
    /// own noise estimate sees one scan's smoothness, not the
    /// misregistration between overlapping scans, which it then follows
    /// within ε (the ten merged raw bunny scans: CD-L1 8.6e-5 as given,
    /// 6.5e-5 cleaned).
    fn noisy(&self) -> Option<(&PointCloud, &CleaningReport)> {
        (self.report.projected > 0).then_some((&self.kept, &self.report))
    }
}

/// `points` through the level set's cleaning (see [`Checked`]).
fn checked(points: &PointCloud) -> Checked {
    let given = points.normals.as_deref().unwrap_or(&[]);
    let (positions, normals, stats) = clean_points_with_normals(&points.positions, given, 3);
    let kept = PointCloud {
        positions,
        normals: points.normals.is_some().then_some(normals),
        scalars: None,
    };
    Checked {
        kept,
        report: CleaningReport::from(&stats),
    }
}

/// Pull the refined `mesh` (grid spacing `spacing`) onto the exact data
/// it ends short of (see [`reach_far_points`]): the tips of thin parts
/// and surface it misses. Only the `inliers` the cleaning kept may pull
/// the surface: the fit keeps stray points in its training set (their
/// bounded weights leave them no blob of their own) and they would pull
/// the surface towards them (harness outliers: two_torus 7% worse). The
/// points of `all` it dropped may still be a line's tip (a thin cone's
/// last sample lies farther from the rest than cleaning allows). Returns
/// the number of points reached.
fn reach_thin_parts(mesh: &mut TriMesh, inliers: &[DVec3], all: &[DVec3], spacing: f64) -> usize {
    let dropped = dropped_points(all, inliers);
    reach_far_points(mesh, inliers, &dropped, spacing, MAX_TIP_CELLS)
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

#[cfg(test)]
mod tests {
    use super::*;
    use surfrecon_geom::shapes::{icosphere, torus};

    /// `a` and `b` as one mesh of two pieces.
    fn both(a: &TriMesh, b: &TriMesh) -> TriMesh {
        let mut mesh = a.clone();
        mesh.append(b);
        mesh
    }

    #[test]
    fn stack_is_dropped_for_an_added_piece_or_handle_but_not_for_a_join() {
        let ball = icosphere(DVec3::ZERO, 1.0, 2);
        let far_ball = icosphere(DVec3::new(5.0, 0.0, 0.0), 1.0, 2);
        let two_balls = both(&ball, &far_ball);
        let ring = torus(1.0, 0.3, 24, 12);
        assert_eq!(stack_verdict(&ball, &ball), None);
        assert_eq!(
            stack_verdict(&ball, &two_balls),
            Some(ContourStack::DroppedMorePieces)
        );
        assert_eq!(
            stack_verdict(&ball, &ring),
            Some(ContourStack::DroppedMoreHandles)
        );
        // Two pieces joined into one: the Euler characteristic drops by
        // 2, but no handle is added.
        assert_eq!(stack_verdict(&two_balls, &ball), None);
        assert_eq!(stack_verdict(&ring, &ball), None);
    }
}
