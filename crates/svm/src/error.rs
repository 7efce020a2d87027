//! The one error type of surfrecon-svm.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum SvmError {
    /// Input that cannot be fitted (too few points, non-finite values, ...).
    #[error("{0}")]
    InvalidInput(String),
    /// A parameter outside its valid range.
    #[error("invalid parameter {name}: {message}")]
    InvalidParameter { name: &'static str, message: String },
    /// Not named `source`: the message already holds it, and a source
    /// would be printed again after it.
    #[error("{}: {error}", path.display())]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    /// A model file that is not in the documented format.
    #[error("{}: byte {byte}: {message}", path.display())]
    Format {
        path: PathBuf,
        byte: u64,
        message: String,
    },
    /// The progress hook asked to stop.
    #[error("cancelled")]
    Cancelled,
    #[error(transparent)]
    Geom(#[from] surfrecon_geom::GeomError),
    #[error(transparent)]
    Grid(#[from] surfrecon_grid::GridError),
}

pub type Result<T, E = SvmError> = std::result::Result<T, E>;

/// Error unless `value` is finite and strictly positive.
pub(crate) fn require_positive(name: &'static str, value: f64) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(SvmError::InvalidParameter {
            name,
            message: format!("must be a positive finite number, got {value}"),
        })
    }
}

/// Error unless `value` is finite and not negative.
pub(crate) fn require_non_negative(name: &'static str, value: f64) -> Result<()> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(SvmError::InvalidParameter {
            name,
            message: format!("must be a non-negative finite number, got {value}"),
        })
    }
}
