//! The facade's one error: what went wrong in words (the same one-line
//! messages as the command line), and of which kind, so that bindings can
//! map it (bad input or options, files, failures, cancellation).

use std::error::Error as StdError;

/// What kind of failure an [`Error`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ErrorKind {
    /// The data or an option cannot be used (empty, non-finite, out of range).
    InvalidInput,
    /// A file could not be read or written.
    Io,
    /// The computation could not complete (e.g. a grid too large for memory).
    Failed,
    /// The progress hook cancelled the run.
    Cancelled,
}

/// Why a facade call failed: `context` says what was being done, `source`
/// (if any) why; `{:#}` through anyhow, or [`Error::message`], joins them.
#[derive(Debug, thiserror::Error)]
#[error("{context}")]
pub struct Error {
    pub kind: ErrorKind,
    context: String,
    #[source]
    source: Option<Box<dyn StdError + Send + Sync>>,
}

impl Error {
    pub fn new(kind: ErrorKind, context: impl Into<String>) -> Self {
        Error {
            kind,
            context: context.into(),
            source: None,
        }
    }

    /// `context` caused by `source`, of kind `kind`.
    pub fn caused(
        kind: ErrorKind,
        context: impl Into<String>,
        source: impl StdError + Send + Sync + 'static,
    ) -> Self {
        Error {
            kind,
            context: context.into(),
            source: Some(Box::new(source)),
        }
    }

    pub fn cancelled() -> Self {
        Error::new(ErrorKind::Cancelled, "cancelled")
    }

    /// The whole chain on one line: "context: cause: cause".
    pub fn message(&self) -> String {
        let mut message = self.context.clone();
        let mut cause = self.source();
        while let Some(c) = cause {
            message.push_str(": ");
            message.push_str(&c.to_string());
            cause = c.source();
        }
        message
    }
}

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// How each method's errors map to a kind.
pub(crate) trait Classify: StdError + Send + Sync + Sized + 'static {
    fn kind(&self) -> ErrorKind;

    /// This error under `context`; cancellation drops the context.
    fn within(self, context: &str) -> Error {
        match self.kind() {
            ErrorKind::Cancelled => Error::cancelled(),
            kind => Error::caused(kind, context, self),
        }
    }
}

impl Classify for surfrecon_levelset::LevelsetError {
    fn kind(&self) -> ErrorKind {
        use surfrecon_levelset::LevelsetError as E;
        match self {
            E::InvalidInput(_) | E::InvalidParameter { .. } => ErrorKind::InvalidInput,
            E::Cancelled => ErrorKind::Cancelled,
            E::Grid(g) => g.kind(),
        }
    }
}

impl Classify for surfrecon_grid::GridError {
    fn kind(&self) -> ErrorKind {
        use surfrecon_grid::GridError as E;
        match self {
            E::InvalidInput(_) | E::Invalid(_) => ErrorKind::InvalidInput,
            E::FieldIo { .. } | E::FieldFile { .. } => ErrorKind::Io,
            E::Geom(g) => g.kind(),
            _ => ErrorKind::Failed,
        }
    }
}

impl Classify for surfrecon_geom::GeomError {
    fn kind(&self) -> ErrorKind {
        match self {
            surfrecon_geom::GeomError::InvalidInput(_) => ErrorKind::InvalidInput,
            _ => ErrorKind::Io,
        }
    }
}

impl Classify for surfrecon_svm::SvmError {
    fn kind(&self) -> ErrorKind {
        use surfrecon_svm::SvmError as E;
        match self {
            E::InvalidInput(_) | E::InvalidParameter { .. } => ErrorKind::InvalidInput,
            E::Io { .. } | E::Format { .. } => ErrorKind::Io,
            E::Cancelled => ErrorKind::Cancelled,
            E::Geom(g) => g.kind(),
            E::Grid(g) => g.kind(),
        }
    }
}

impl Classify for surfrecon_convection::ConvectionError {
    fn kind(&self) -> ErrorKind {
        match self {
            surfrecon_convection::ConvectionError::Delaunay(_) => ErrorKind::Failed,
            _ => ErrorKind::InvalidInput,
        }
    }
}
