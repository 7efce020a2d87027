//! surfrecon-distfield: distance fields that keep sharp edges and corners.
//!
//! A regular grid of distances rounds off every edge and corner of a CAD
//! shape to about a cell. Two representations from the offset/unified
//! distance field paper keep them:
//! - [`offset::OffsetField`] (ODF): one sample per grid node, free to move
//!   within its cell; samples near features are moved onto them by
//!   minimizing a fidelity + grid-regularity energy ([`offset::build_odf`]);
//! - [`unified::UnifiedField`] (UDF): the regular distances plus, only
//!   where needed, exact axis crossings, one feature point per cell, or a
//!   moved sample ([`unified::build_udf`]).
//!
//! Both extract to closed manifold meshes by marching cubes on the offset
//! grid with feature fans ([`extract`]), are stored in compact files
//! ([`format`]) and can be sculpted with CSG tools ([`sculpt`]). Sharp
//! edges and corners come from [`features`]; exact distances and ray hits
//! on the source mesh from [`query`].

pub mod error;
pub mod extract;
pub mod features;
pub mod format;
pub mod offset;
pub mod query;
mod refine;
pub mod sculpt;
pub mod sharp;
pub mod unified;

pub use error::DistFieldError;

use surfrecon_geom::TriMesh;
use surfrecon_grid::{GridSize, GridSpec};

/// Largest coordinate magnitude, and smallest extent, of a mesh the
/// fields support (as `reconstruct` does): cell volumes and squared
/// distances must stay normal f64 numbers (a sphere 5e-151 wide took
/// 500 times as long, computing in subnormals).
const MAX_COORDINATE: f64 = 1e100;
const MIN_EXTENT: f64 = 1e-100;

/// Refuse meshes a signed field cannot be built from: no triangles, bad
/// indices, non-finite coordinates, coordinates too large or a mesh too
/// small for f64 ([`MAX_COORDINATE`], [`MIN_EXTENT`]), or an open or
/// non-manifold surface.
pub fn check_mesh(mesh: &TriMesh) -> Result<(), DistFieldError> {
    if let Some(v) = mesh.vertices.iter().position(|v| !v.is_finite()) {
        return Err(DistFieldError::InvalidMesh(format!(
            "vertex {v} has a non-finite coordinate"
        )));
    }
    let largest = (mesh.vertices.iter())
        .map(|v| v.abs().max_element())
        .fold(0.0, f64::max);
    let extent = mesh.bounds().size().max_element();
    if largest > MAX_COORDINATE {
        return Err(DistFieldError::InvalidMesh(format!(
            "the mesh reaches coordinate {largest:e}; at most {MAX_COORDINATE:e} is supported: rescale it"
        )));
    }
    if extent > 0.0 && extent < MIN_EXTENT {
        return Err(DistFieldError::InvalidMesh(format!(
            "the mesh spans only {extent:e}; at least {MIN_EXTENT:e} is supported: rescale it"
        )));
    }
    let n = mesh.vertices.len() as u32;
    if let Some(t) = mesh
        .triangles
        .iter()
        .position(|t| t.iter().any(|&v| v >= n))
    {
        return Err(DistFieldError::InvalidMesh(format!(
            "triangle {t} refers to a vertex beyond the {n} vertices"
        )));
    }
    surfrecon_grid::sdf::check_closed(mesh).map_err(|e| match e {
        surfrecon_grid::GridError::InvalidInput(m) => DistFieldError::InvalidMesh(m),
        other => other.into(),
    })
}

/// The grid over a mesh's bounds with `padding` cells around it.
pub fn grid_for(
    mesh: &TriMesh,
    size: GridSize,
    padding: usize,
) -> Result<GridSpec<3>, DistFieldError> {
    let b = mesh.bounds();
    Ok(GridSpec::from_bounds(
        b.min.to_array(),
        b.max.to_array(),
        size,
        padding,
    )?)
}
