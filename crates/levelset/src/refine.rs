//! Final touches on the extracted surface, where the grid's resolution
//! limits it: vertices near the data move onto the data's local fit, and
//! the patches spanning gaps in scanned data are faired.
//!
//! The evolved zero set lies on the data only to a fraction of a cell and
//! spans holes with a minimal surface, which sags into the body. Snapping
//! ([`project_onto_points`]) places the supported vertices between the
//! samples; fairing ([`fair`]) replaces each sagging patch with the
//! smoothest fill that meets the surrounding surface with its slope. Both
//! only move vertices, so the mesh stays watertight and manifold.

use crate::cleaning::{project_onto_points, SurfaceFit};
use surfrecon_geom::fairing::{area_weighted_normals, fair, FairingOptions};
use surfrecon_geom::{DVec3, TriMesh};

/// Vertices within this many cells of a data point are supported: they
/// are snapped, the others may be faired.
pub const SUPPORT_CELLS: f64 = 2.0;

/// Data points per local fit when snapping.
const SNAP_NEIGHBOURS: usize = 16;

/// Gaps are faired only when at least this share of the vertices is
/// supported: a scan with holes. Sparse data (a few curves, slices) give
/// no reliable slopes to continue, and keep the paper's weighted minimal
/// surface.
const SUPPORTED_SHARE: f64 = 0.75;

/// What [`refine_surface`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RefineStats {
    /// Vertices moved onto the data's local fit.
    pub snapped: usize,
    /// Vertices of faired gap patches.
    pub faired: usize,
    /// Largest distance a faired vertex moved (world units).
    pub max_fairing_shift: f64,
}

/// Snap `mesh` onto `points` (the cleaned point data) and, when
/// `fair_gaps` and the data cover most of the surface, fair the patches
/// over the gaps. `spacing` is the grid spacing the mesh came from.
pub fn refine_surface(
    mesh: &mut TriMesh,
    points: &[DVec3],
    spacing: f64,
    fair_gaps: bool,
) -> RefineStats {
    let mut stats = RefineStats::default();
    if points.is_empty() || mesh.vertices.is_empty() {
        return stats;
    }
    let reach = SUPPORT_CELLS * spacing;
    let computed;
    let normals = match &mesh.normals {
        Some(n) => n,
        None => {
            computed = area_weighted_normals(&mesh.vertices, &mesh.triangles);
            &computed
        }
    };
    let fit = SurfaceFit {
        dim: 3,
        reach,
        neighbours: SNAP_NEIGHBOURS,
    };
    let projection = project_onto_points(&mut mesh.vertices, normals, points, &fit);
    stats.snapped = projection.moved;
    if !fair_gaps {
        return stats;
    }
    // Unsupported vertices did not move, so their support stands.
    let free: Vec<bool> = projection.supported.iter().map(|s| !s).collect();
    let unsupported = free.iter().filter(|&&f| f).count();
    if unsupported as f64 > (1.0 - SUPPORTED_SHARE) * free.len() as f64 {
        return stats;
    }
    let faired = fair(mesh, &free, &FairingOptions::default());
    stats.faired = faired.moved;
    stats.max_fairing_shift = faired.max_shift;
    stats
}
