//! surfrecon-geom: the geometry every surfrecon method reads and writes.
//!
//! - Plain types: [`PointCloud`] (positions, optional normals and scalars),
//!   [`Polylines`] (curves), [`TriMesh`] (indexed triangles), [`Aabb`], and
//!   [`Geometry`], the union a file may hold. All coordinates are `f64`
//!   ([`DVec3`] from glam, re-exported).
//! - File formats in [`io`]: PLY (ascii, binary LE/BE), OBJ, OFF, STL, XYZ,
//!   chosen by extension; outputs are written atomically ([`io::write_atomic`]).
//! - [`spatial::KdTree`]: k-nearest and radius queries shared by all methods.
//! - [`curves`]: curve networks (polylines or points along curves), their
//!   crossings and the surface normals they imply.
//! - [`normals`]: plane-fit estimation and globally consistent orientation.
//! - [`fairing`]: smooth (bi-Laplacian) fills for unsupported mesh parts.
//! - [`intersections`]: exact self-intersection test of triangle meshes.
//! - [`metrics`]: Chamfer, Hausdorff, F-score, normal consistency, topology.
//! - [`data_fit`]: how closely a mesh reaches the data it was built from.
//! - [`progress`]: the progress-and-cancel hook long computations call.
//! - [`render`]: PNG previews of meshes and point clouds.
//! - [`shapes`]: analytic test shapes and uniform surface sampling.

pub mod aabb;
pub mod curves;
pub mod data_fit;
pub mod disjoint_sets;
pub mod error;
pub mod fairing;
pub mod geometry;
pub mod intersections;
pub mod io;
pub mod linalg;
pub mod metrics;
pub mod normals;
pub mod progress;
pub mod render;
pub mod shapes;
pub mod spatial;

pub use aabb::Aabb;
pub use error::{GeomError, Location};
pub use geometry::{Geometry, PointCloud, Polylines, TriMesh};
pub use glam::DVec3;
