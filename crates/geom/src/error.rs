//! The one error type of surfrecon-geom.

use std::fmt;
use std::path::PathBuf;

/// Where in an input file a problem was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Location {
    /// 1-based line of a text file.
    Line(usize),
    /// Byte offset into a binary file.
    Byte(u64),
    /// The file as a whole (e.g. empty, or counts that do not add up).
    File,
}

impl Location {
    /// "line 3: " or "byte 80: "; nothing for the file as a whole.
    fn prefix(&self) -> String {
        match self {
            Location::File => String::new(),
            other => format!("{other}: "),
        }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(l) => write!(f, "line {l}"),
            Location::Byte(b) => write!(f, "byte {b}"),
            Location::File => write!(f, "file"),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum GeomError {
    #[error("{}: {error}", path.display())]
    Io {
        path: PathBuf,
        // Not a `source`: the message already shows it, so `{:#}` chains
        // would print it twice.
        error: std::io::Error,
    },
    /// Malformed content: names the file, the position and the problem.
    #[error("{}: {}{message}", path.display(), location.prefix())]
    Parse {
        path: PathBuf,
        location: Location,
        message: String,
    },
    #[error("{}: unknown file format {format:?} (supported: ply, obj, off, stl, xyz)", path.display())]
    UnknownFormat { path: PathBuf, format: String },
    /// Input that parses but cannot be used (no points, degenerate data, ...).
    #[error("{0}")]
    InvalidInput(String),
}

pub type Result<T, E = GeomError> = std::result::Result<T, E>;
