//! Isosurfaces: marching cubes (3D → indexed triangle mesh) and marching
//! squares (2D → polylines), our own implementation.
//!
//! Both classify a node as positive when its value is `>= iso` (so a value
//! exactly at iso is never "on" the surface and cannot create degenerate or
//! non-manifold pieces), place one shared vertex per sign-changing edge by
//! linear interpolation, and resolve ambiguous faces/cells with the
//! asymptotic decider computed only from the face's four values, so cells
//! sharing a face always agree. See [`tables`] for how the cube cases are
//! generated and why the result is watertight and edge-manifold.

mod cubes;
mod lone;
mod squares;
pub mod tables;

pub use cubes::{cell_case, crossing_fraction, marching_cubes};
pub(crate) use cubes::{edge_vertex, loop_centre, Samples3};
pub use lone::settle_lone_nodes;
pub use squares::marching_squares;

#[cfg(test)]
pub(crate) mod tests;
