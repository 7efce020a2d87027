//! Facade errors as Python exceptions: bad data or options → ValueError,
//! files → OSError, cancellation → surfrecon.Cancelled (a
//! KeyboardInterrupt raised by Ctrl-C passes through as itself), anything
//! else → RuntimeError. Messages are the command line's one line.

use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::PyErr;
use surfrecon::{Error, ErrorKind};

pyo3::create_exception!(
    surfrecon,
    Cancelled,
    pyo3::exceptions::PyException,
    "A run stopped by its `cancel` event or `progress` callback."
);

pub fn to_py(e: Error) -> PyErr {
    let message = e.message();
    match e.kind {
        ErrorKind::InvalidInput => PyValueError::new_err(message),
        ErrorKind::Io => PyOSError::new_err(message),
        ErrorKind::Cancelled => Cancelled::new_err(message),
        ErrorKind::Failed => PyRuntimeError::new_err(message),
    }
}

/// A ValueError with `message`.
pub fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// Geometry and field file errors: OSError, but bad data in memory
/// (InvalidInput) stays a ValueError.
pub fn geom(e: surfrecon::geom::GeomError) -> PyErr {
    match e {
        surfrecon::geom::GeomError::InvalidInput(m) => PyValueError::new_err(m),
        other => PyOSError::new_err(other.to_string()),
    }
}

pub fn grid(context: &str, e: surfrecon::grid::GridError) -> PyErr {
    use surfrecon::grid::GridError as G;
    let message = format!("{context}: {e}");
    match e {
        G::InvalidInput(_) | G::Invalid(_) => PyValueError::new_err(message),
        G::FieldIo { .. } | G::FieldFile { .. } | G::Geom(_) => PyOSError::new_err(message),
        _ => PyRuntimeError::new_err(message),
    }
}
