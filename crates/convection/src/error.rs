//! What can go wrong in a convection reconstruction.

use surfrecon_delaunay::DelaunayError;

/// Errors of the convection crate. Bad input maps to one of these; no input
/// panics.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConvectionError {
    /// The points span no tetrahedron (fewer than 4, all coplanar or
    /// collinear, non-finite coordinates, ...).
    /// (Its message holds the Delaunay error's; not also given as the
    /// source, or error chains print it twice.)
    #[error("cannot tetrahedralize the points: {0}")]
    Delaunay(DelaunayError),
    #[error("{normals} normals given for {points} points")]
    NormalCount { points: usize, normals: usize },
    #[error("normal {index} is zero or not finite")]
    BadNormal { index: usize },
    #[error("parameter {name} = {value} is out of range ({range})")]
    BadParameter {
        name: &'static str,
        value: f64,
        range: &'static str,
    },
}

impl From<DelaunayError> for ConvectionError {
    fn from(e: DelaunayError) -> Self {
        ConvectionError::Delaunay(e)
    }
}

pub type Result<T> = std::result::Result<T, ConvectionError>;
