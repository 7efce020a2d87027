//! surfrecon-grid: the fields every surfrecon method reads and writes.
//!
//! One generic code path for 2D and 3D: [`GridSpec<D>`] places nodes at
//! `origin + spacing * index`, [`Field<D>`] stores one `f64` per node.
//! Tools over grids (each in its own module): fast-sweeping distance,
//! unsigned distance to points/segments/triangles, signed distance of a
//! closed mesh, marching squares/cubes, inside pieces and the paths that
//! join them, sparse narrow-band storage, field files (NRRD, VTK), thin
//! shells, and the simple point test of digital topology.

pub mod distance;
pub mod error;
pub mod field_io;
pub mod marching;
pub mod pieces;
pub mod sdf;
pub mod shell;
mod simd;
pub mod sparse;
pub mod spec;
pub mod sweep;
pub mod topology;

pub use error::GridError;
pub use spec::{Field, Field2, Field3, GridSize, GridSpec};
