//! What can go wrong when building or editing a triangulation.

/// Errors of the Delaunay crate. Every bad input maps to one of these; no
/// input panics or loops forever.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DelaunayError {
    #[error("a 3D Delaunay triangulation needs at least 4 points, got {count}")]
    TooFewPoints { count: usize },
    #[error("point {index} has a non-finite coordinate (NaN or infinity)")]
    NonFinite { index: usize },
    #[error("all {count} points are identical")]
    AllIdentical { count: usize },
    #[error("all {count} points are collinear: no tetrahedron can be formed")]
    AllCollinear { count: usize },
    #[error("all {count} points are coplanar: no tetrahedron can be formed")]
    AllCoplanar { count: usize },
    #[error("too many points or tetrahedra for 32-bit indices")]
    TooLarge,
    #[error("vertex {0} is not a vertex of the triangulation")]
    UnknownVertex(u32),
    #[error("removing vertex {0} would leave only coplanar points")]
    RemovalWouldFlatten(u32),
    #[error("internal error: {0}")]
    Internal(String),
}

pub type Result<T> = std::result::Result<T, DelaunayError>;
