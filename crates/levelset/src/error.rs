//! The one error type of surfrecon-levelset.

use surfrecon_grid::GridError;

/// Why a reconstruction could not run.
#[derive(Debug, thiserror::Error)]
pub enum LevelsetError {
    /// Input that cannot be reconstructed (no data, non-finite values, ...).
    #[error("{0}")]
    InvalidInput(String),
    /// A parameter out of its valid range.
    #[error("invalid parameter {name}: {message}")]
    InvalidParameter { name: &'static str, message: String },
    /// The grid could not be built (too large, degenerate).
    /// The progress hook asked to stop.
    #[error("cancelled")]
    Cancelled,
    #[error(transparent)]
    Grid(#[from] GridError),
}

/// Result with [`LevelsetError`].
pub type Result<T, E = LevelsetError> = std::result::Result<T, E>;
