//! surfrecon-python: the Python module `surfrecon` (numpy in, numpy out)
//! over the facade crate. Arrays of float32 or float64 in any memory order
//! come in; float64 vertices and int64 faces go out. Every call releases
//! the GIL while it computes; reconstructions check for Ctrl-C and an
//! optional `cancel` event through the facade's progress hook. Errors are
//! `ValueError` (bad arrays or options, with the command line's messages),
//! `OSError` (files) or `RuntimeError`, never a crash.

mod arrays;
mod errors;
mod functions;
mod hook;

use pyo3::prelude::*;

#[pymodule]
#[pyo3(name = "surfrecon")]
fn surfrecon_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("Cancelled", m.py().get_type::<errors::Cancelled>())?;
    m.add_function(wrap_pyfunction!(functions::reconstruct, m)?)?;
    m.add_function(wrap_pyfunction!(functions::distance, m)?)?;
    m.add_function(wrap_pyfunction!(functions::extract, m)?)?;
    m.add_function(wrap_pyfunction!(functions::evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(functions::read, m)?)?;
    m.add_function(wrap_pyfunction!(functions::write, m)?)?;
    m.add_function(wrap_pyfunction!(functions::write_shell, m)?)?;
    m.add_function(wrap_pyfunction!(functions::read_shell, m)?)?;
    m.add_function(wrap_pyfunction!(functions::morph, m)?)?;
    Ok(())
}
