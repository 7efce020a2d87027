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
    #[error(transparent)]
    Geom(#[from] surfrecon_geom::GeomError),
}
