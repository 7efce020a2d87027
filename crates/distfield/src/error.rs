//! The one error type of surfrecon-distfield.

#[derive(Debug, thiserror::Error)]
pub enum DistFieldError {
    /// A mesh these fields cannot be built from (empty, open, bad indices).
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
    /// Bad options (resolution, angles, weights).
    #[error("invalid option: {0}")]
    InvalidOption(String),
    /// An .odf/.udf file that cannot be read: the file and the problem.
    #[error("{}: {message}", path.display())]
    BadFile {
        path: std::path::PathBuf,
        message: String,
    },
    #[error("{}: {error}", path.display())]
    Io {
        path: std::path::PathBuf,
        error: std::io::Error,
    },
    #[error(transparent)]
    Grid(#[from] surfrecon_grid::GridError),
}
