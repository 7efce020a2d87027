//! [`Method::Convection`](crate::Method::Convection): geometric convection
//! over the exact Delaunay tetrahedralization of the points.

use crate::error::{Classify, Result};
use crate::report::*;
use crate::{check, data_fit_report, ConvectionOptions, Output};
use surfrecon_convection::holes::HoleRule;
use surfrecon_convection::{reconstruct, Params};
use surfrecon_geom::progress::Hook;
use surfrecon_geom::Geometry;
use surfrecon_levelset::cleaning::is_noisy;
use surfrecon_levelset::slices::detect_slices;

pub(crate) fn params(o: &ConvectionOptions) -> Params {
    Params {
        normal_k: o.normal_k,
        pockets: o.pockets,
        thin_size: if o.thin_parts {
            Params::default().thin_size
        } else {
            0.0
        },
        max_hole_edges: o.fill_holes,
        brush: o.brush,
        rho: o.rho,
        rho_geometric: o.rho_geom,
        rho_topo: o.rho_topo,
        decimate_on_the_fly: o.decimate_on_the_fly,
        refine_alpha: o.refine_alpha,
        refine_gamma: o.refine_gamma,
        open_holes: o.open_holes.then(HoleRule::default),
        edge_flips: o.edge_flips,
        split_curved_edges: o.split_curved_edges,
        ..Params::default()
    }
}

pub(crate) fn run(
    input: &Geometry,
    o: &ConvectionOptions,
    data_fit: bool,
    hook: Hook,
) -> Result<Output> {
    let points = crate::require_points(input, "reconstruct from")?;
    check(hook, "convection")?;
    // Flips that lower the bending take bevels off clean samples but follow
    // the noise of noisy ones (harness, noise 0.25%: Chamfer +7%). The
    // decimation's front keeps the first points it meets, on a noisy sheet
    // the outermost ones (harness, noise 0.25%: Chamfer +1-9% against
    // input order): noisy points are decimated in input order. Curved
    // edges are split on clean samples only: on noisy ones the normals
    // turn with the noise, which the new vertices would amplify.
    let asks_clean = o.edge_flips || o.decimate_on_the_fly || o.split_curved_edges;
    let noisy_input = asks_clean && is_noisy(&points.positions);
    // A stack of contour slices samples the surface on its planes only:
    // every gap between two slices would pass for an unsampled hole (a
    // two-torus's slices fell apart into bands), so none is opened.
    let sliced_input = o.open_holes && is_a_slice_stack(&points.positions);
    let params = Params {
        edge_flips: o.edge_flips && !noisy_input,
        decimate_on_the_fly: o.decimate_on_the_fly && !noisy_input,
        split_curved_edges: o.split_curved_edges && !noisy_input,
        open_holes: params(o).open_holes.filter(|_| !sliced_input),
        ..params(o)
    };
    let r = reconstruct(&points.positions, points.normals.as_deref(), &params)
        .map_err(|e| e.within("convection reconstruction failed"))?;
    let output_counts = OutputCounts {
        vertices: r.report.kept_points + r.report.curved_edges_split,
        ..OutputCounts::mesh(&r.mesh)
    };
    let report = ConvectionReport {
        method: "convection",
        convection: r.report,
        noisy_input,
        sliced_input,
        output_counts,
        data_fit: data_fit.then(|| data_fit_report(&r.mesh, input)),
    };
    Ok(Output {
        mesh: r.mesh,
        curves: None,
        field: None,
        report: Report::Convection(Box::new(report)),
    })
}

/// Whether the points lie on a few parallel planes (contour slices).
fn is_a_slice_stack(points: &[surfrecon_geom::DVec3]) -> bool {
    let input = surfrecon_levelset::Input {
        points: points.to_vec(),
        ..Default::default()
    };
    detect_slices(&input).is_some()
}
