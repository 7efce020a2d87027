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
//!    boundary edges left are reported.
//!
//! 5. thin parts: where two fronts met across a part thinner than the
//!    sampling, the small swept tetrahedra spanning it are put back inside
//!    when that leaves fewer pieces (a stand-in for the paper's 2D
//!    convection of the sheets).
//!
//! With `Params::rho > 0` the input is first decimated by the paper's
//! geometric and topological-disk criteria ([`decimate`]), before the
//! triangulation rather than on the fly.
//!
//! Not done yet (see the paper): decimation on the fly during the
//! convection, thin parts by 2D convection, dynamic insertion and removal.

pub mod decimate;
pub mod dynamic;
mod error;
pub mod gabriel;
pub mod manifold;
mod reconstruct;
pub mod surface;
pub mod thin;

pub use dynamic::{DynamicSurface, UpdateStats};
pub use error::{ConvectionError, Result};
pub use reconstruct::{reconstruct, Params, Reconstruction, Report, Timings};
pub use surface::OrientedFacet;
