//! Crossing curve networks: when the input is curves that cross each other
//! (polylines, or points that lie along curves), the surface spanning them
//! comes from a Hermite fit of the normals the crossings imply, not from a
//! level set, whose weighted-area flow would shrink the film between sparse
//! curves into tubes around them.

use crate::error::{Classify, Result};
use crate::report::*;
use crate::{data_fit_report, Output};
use std::time::Instant;
use surfrecon_geom::curves::{chain_points, curves_from_polylines, CurveNetwork};
use surfrecon_geom::{Geometry, Polylines};
use surfrecon_levelset::slices::detect_slices;
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
    let input = surfrecon_levelset::Input::from_geometry(geometry);
    if !geometry.triangles.is_empty() || detect_slices(&input).is_some() {
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

pub(crate) fn run(
    input: &Geometry,
    network: &CurveNetwork,
    options: &crate::Options,
    data_fit: bool,
) -> Result<Output> {
    let start = Instant::now();
    let options = CurveFitOptions {
        resolution: options.resolution,
        join_pieces: options.join_pieces,
        ..Default::default()
    };
    let (mesh, r) = reconstruct_from_curves(network, &options)
        .map_err(|e| e.within("curve-network reconstruction failed"))?;
    let seconds_total = start.elapsed().as_secs_f64();
    let report = CurveNetworkReport {
        method: "curve-network",
        path: "curve network: Hermite fit of the normals implied by the crossings",
        curve_network: r,
        seconds_total,
        output_counts: OutputCounts::mesh(&mesh),
        data_fit: data_fit.then(|| data_fit_report(&mesh, input)),
    };
    Ok(Output {
        mesh,
        curves: None,
        field: None,
        report: Report::CurveNetwork(Box::new(report)),
    })
}
