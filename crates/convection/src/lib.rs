//! Surface reconstruction by geometric convection (Chaine's method) over an
//! exact 3D Delaunay tetrahedralization: the mesh interpolates the input
//! points, with no grid and no smoothing.
//!
//! Entry point: [`reconstruct`] (points, optional normals, [`Params`]) gives
//! a [`Reconstruction`]: a manifold [`surfrecon_geom::TriMesh`] whose
//! vertices are the input points by input index, and a [`Report`] of counts
//! and per-stage seconds. Stages:
//! 1. the Delaunay tetrahedralization (`surfrecon-delaunay`, exact);
//! 2. convection ([`surface`]): a pseudo-surface starts as the convex hull,
//!    facets oriented inward, and every facet violating the oriented Gabriel
//!    property ([`gabriel`]) is replaced by the other facets of the Delaunay
//!    tetrahedron behind it; coupled facets (one triangle with both
//!    orientations) that violate it collapse, which changes the topology;
//! 3. pockets: facets nearly perpendicular to the point normals at all
//!    three vertices (given, or estimated by a plane fit) are opened too;
//! 4. output ([`manifold`]): sheets of coupled facets left at convergence
//!    are left out, faces where the surface pinches are removed
//!    so the mesh is manifold, optionally short holes are closed; the
//!    boundary edges left are reported; then ([`flips`]) edges are flipped
//!    across Delaunay tetrahedra where that lowers the surface's bending
//!    (bevels across sharp edges go, the vertices stay the points);
//!    finally ([`curved`]) edges where the smooth surface bends away from
//!    its chords get a new vertex on a cubic curve from the vertex
//!    normals (not across sharp edges, not with decimation).
//!
//! 5. thin parts ([`thin`]): the paper's 2D convection over the sheets of
//!    coupled facets keeps the sheets of parts thinner than the sampling
//!    and eats membranes across the outside; the kept sheets are thickened
//!    with the small swept tetrahedra around them (pinches closed, stray
//!    points attached, pieces bridged, holes through thin plates closed by
//!    a topology-controlled growth, see `tunnels`), kept when that leaves
//!    fewer pieces.
//!
//! With `Params::rho > 0` the input is first decimated by the paper's
//! geometric and topological-disk criteria, before the triangulation: in
//! input order ([`decimate`]), or on the fly in the order a convection
//! front from the hull reaches the points, without a triangulation
//! ([`front`], `Params::decimate_on_the_fly`). A [`decimate::Brush`] varies
//! the radius locally.
//!
//! Dynamic correction ([`dynamic`]): a [`DynamicSurface`] inserts and
//! removes points and updates the Gabriel pseudo-surface locally (the same
//! facets as a run from scratch); [`dynamic::apply_brush`] re-decides the
//! points under a brush and applies the difference; [`refine()`] puts
//! decimated points back where triangles are poorly shaped (ratio α) or
//! the density jumps (γ), each a local update (`Params::refine_alpha`,
//! `Params::refine_gamma` in [`reconstruct`]).
//!
//! [`DynamicSurface::reconstruction`] makes the mesh after edits (pockets,
//! thin parts and the output stage re-run globally on the kept-up-to-date
//! Gabriel surface, the same mesh as [`reconstruct`] from scratch); with
//! refinement, [`reconstruct`] makes its mesh that way on the refined
//! triangulation.
//!
//! Not done yet (see the paper): pockets and thin parts updated locally by
//! the dynamic update itself; the front's decimation as the default (it
//! costs several times the input-order pass at scale, see BENCHMARKS.md).

pub mod curved;
pub mod decimate;
pub mod dynamic;
mod error;
mod fill;
pub mod flips;
pub mod front;
pub mod gabriel;
pub mod holes;
mod live_tree;
pub mod manifold;
mod reconstruct;
pub mod refine;
pub mod surface;
pub mod thin;
mod tunnels;

pub use dynamic::{DynamicSurface, UpdateStats};
pub use error::{ConvectionError, Result};
pub use reconstruct::{reconstruct, Params, Reconstruction, Report, Timings};
pub use refine::{refine, Quality, RefineStats};
pub use surface::OrientedFacet;
