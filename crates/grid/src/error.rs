//! The one error type of surfrecon-grid.

#[derive(Debug, thiserror::Error)]
pub enum GridError {
    /// A grid that would not fit in memory, refused before allocating.
    #[error("grid of {dims} nodes needs about {need_mb:.0} MB but this machine has {have_mb:.0} MB available; try {suggestion}")]
    TooLarge {
        dims: String,
        need_mb: f64,
        have_mb: f64,
        suggestion: String,
    },
    #[error("invalid grid: {0}")]
    Invalid(String),
    /// A field or shell file that cannot be used: names the file, where in
    /// it (when known) and the problem.
    #[error("{}: {message}", path.display())]
    FieldFile {
        path: std::path::PathBuf,
        message: String,
    },
    /// Reading or writing a field or shell file failed.
    #[error("{}: {error}", path.display())]
    FieldIo {
        path: std::path::PathBuf,
        // Not a `source`: the message already shows it, so `{:#}` chains
        // would print it twice.
        error: std::io::Error,
    },
    #[error(transparent)]
    Geom(#[from] surfrecon_geom::GeomError),
    /// Data or a mesh that a computation cannot use (empty, non-finite
    /// coordinates, bad indices, an open mesh where a closed one is needed).
    #[error("invalid input: {0}")]
    InvalidInput(String),
}
