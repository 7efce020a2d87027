//! Exact incremental 3D Delaunay tetrahedralization: the kernel under
//! geometric convection, and the `surfrecon tetrahedralize` command.
//!
//! Build with [`Triangulation::bulk_load`] (points in a biased randomized
//! insertion order sorted along a Hilbert curve, then Bowyer–Watson
//! insertion), then edit with [`Triangulation::insert`] and
//! [`Triangulation::remove`]. Query with [`Triangulation::locate`],
//! [`Triangulation::finite_tets`], [`Triangulation::neighbors`],
//! [`Triangulation::incident_tets`], [`Triangulation::hull_facets`] and
//! [`Triangulation::volume`]; [`Triangulation::validate`] checks every
//! invariant exactly.
//!
//! All decisions use exact adaptive predicates ([`predicates`]) with a
//! symbolic perturbation, so lattices, cospherical and coplanar inputs give
//! a valid triangulation, never a flat tetrahedron or a hang. The hull is
//! closed by *ghost* tetrahedra joining each hull facet to a vertex at
//! infinity, so every facet has two sides. Storage is four flat arrays
//! (vertices and neighbours per tetrahedron, a point and one incident
//! tetrahedron per vertex); no allocation per cell.

mod build;
mod error;
mod insert;
mod order;
pub mod predicates;
mod remove;
mod triangulation;
mod validate;

pub use error::{DelaunayError, Result};
pub use glam::DVec3;
pub use order::{brio_order, hilbert_index, hilbert_keys};
pub use triangulation::{Changes, Location, TetId, Triangulation, VertexId};
