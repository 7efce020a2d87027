//! [`Method::LevelSet`](crate::Method::LevelSet): the level-set method in
//! 3D, or closed curves in 2D for planar data.

use crate::error::{Classify, Result};
use crate::report::*;
use crate::{data_fit_report, FieldOutput, LevelSetOptions, Output, OutputField};
use surfrecon_geom::progress::Hook;
use surfrecon_geom::{Geometry, TriMesh};
use surfrecon_levelset::flow::EvolveStats;
use surfrecon_levelset::{reconstruct_2d_with, reconstruct_3d_with, ReconstructParams};

const CONTEXT: &str = "level-set reconstruction failed";

pub(crate) fn params(o: &LevelSetOptions, resolution: Option<usize>) -> ReconstructParams {
    ReconstructParams {
        resolution,
        epsilon: o.epsilon,
        p: o.p,
        steps: o.steps,
        band: o.band,
        levels: o.levels,
        bounding_box: o.bounding_box,
        clean: o.cleaning,
        keep_topology: !o.free_topology,
        refine: o.refine,
        slices: o.slices,
        // A thin shell needs only the nodes next to the surface.
        full_field: o.field == FieldOutput::Full,
        ..Default::default()
    }
}

/// Whether every datum lies in one plane z = const (2D data).
pub fn is_planar(input: &Geometry) -> bool {
    let mut zs = input.points.positions.iter().map(|v| v.z);
    match zs.next() {
        Some(z0) => zs.all(|z| z == z0),
        None => false,
    }
}

pub(crate) fn run(
    input: &Geometry,
    o: &LevelSetOptions,
    resolution: Option<usize>,
    data_fit: bool,
    hook: Hook,
) -> Result<Output> {
    let data = surfrecon_levelset::Input::from_geometry(input);
    let params = params(o, resolution);
    let two_d = o.two_d || is_planar(input);
    let counts = DataCounts {
        points: data.points.len(),
        segments: data.segments.len(),
        triangles: data.triangles.len(),
    };
    if two_d {
        let r = reconstruct_2d_with(&data, &params, hook).map_err(|e| e.within(CONTEXT))?;
        let field = (o.field != FieldOutput::None).then(|| OutputField::Two(r.dense_field()));
        let output_counts = OutputCounts {
            vertices: r.curves.vertices.len(),
            triangles: None,
            curves: Some(r.curves.lines.len()),
        };
        let report = report(&r.report, counts, 2, output_counts, None);
        Ok(Output {
            mesh: TriMesh::default(),
            curves: Some(r.curves),
            field,
            report: Report::LevelSet(Box::new(report)),
        })
    } else {
        let r = reconstruct_3d_with(&data, &params, hook).map_err(|e| e.within(CONTEXT))?;
        let field = (o.field != FieldOutput::None).then(|| OutputField::Three(r.dense_field()));
        let fit = data_fit.then(|| data_fit_report(&r.mesh, input));
        let report = report(&r.report, counts, 3, OutputCounts::mesh(&r.mesh), fit);
        Ok(Output {
            mesh: r.mesh,
            curves: None,
            field,
            report: Report::LevelSet(Box::new(report)),
        })
    }
}

fn report(
    r: &surfrecon_levelset::Report,
    data: DataCounts,
    dimension: usize,
    output_counts: OutputCounts,
    data_fit: Option<DataFitReport>,
) -> LevelSetReport {
    let evolutions = |v: &[EvolveStats]| v.iter().map(evolve_report).collect();
    LevelSetReport {
        method: "levelset",
        dimension,
        data,
        grid: GridReport {
            dims: r.dims.clone(),
            spacing: r.spacing,
            nodes: r.dims.iter().product(),
            levels: r.levels,
        },
        cleaning: CleaningReport::from(&r.cleaning),
        epsilon: r.epsilon,
        surfels: r.surfels,
        densified: r.densified,
        tagging: TaggingReport {
            heap_pops: r.heap_pops,
            inside_nodes: r.tagged_inside,
            removed_components: r.removed_components,
            grown_to_points: r.grown_to_points,
            restored_near_points: r.restored_near_points,
            reopened_near_points: r.reopened_near_points,
            sealed_by_normals: r.sealed_nodes,
            lone_nodes: r.lone_nodes,
            joined_parts: r.joined_parts,
        },
        band_nodes: r.band_nodes,
        band: BandReport {
            nodes: r.band_nodes,
            blocks: r.band_blocks,
            block_nodes: surfrecon_grid::sparse::BLOCK.pow(dimension as u32),
        },
        convection: evolutions(&r.convection),
        flow: evolutions(&r.flow),
        settle: evolutions(&r.settle),
        refine: RefineReport {
            snapped: r.refine.snapped,
            snapped_to_planes: r.refine.snapped_to_planes,
            snapped_to_edges: r.refine.snapped_to_edges,
            faired: r.refine.faired,
            max_fairing_shift: r.refine.max_fairing_shift,
            fitted_to_rim: r.refine.fitted_to_rim,
            reached_far_points: r.refine.reached_far_points,
            uncrossed: r.refine.uncrossed,
        },
        slices: r.slices.map(|(axis, count)| SlicesReport { axis, count }),
        timings: r
            .timings
            .iter()
            .map(|(stage, seconds)| StageTime {
                stage: stage.clone(),
                seconds: *seconds,
            })
            .collect(),
        seconds_total: r.timings.iter().map(|(_, t)| t).sum(),
        output_counts,
        data_fit,
    }
}

fn evolve_report(s: &EvolveStats) -> EvolveReport {
    EvolveReport {
        steps: s.steps,
        converged: s.converged,
        stopped_by: if s.converged {
            "convergence"
        } else {
            "step cap"
        },
        last_change: s.last_change,
        energy: s.energy,
        max_band: s.max_band,
    }
}
