//! The facade's progress hook for a Python call: with the GIL released the
//! computation runs on the calling thread; at each progress report the hook
//! takes the GIL back briefly to run Python's signal handlers (Ctrl-C), to
//! ask the `cancel` event whether it is set, and to call `progress`.

use pyo3::prelude::*;
use std::sync::Mutex;
use surfrecon::{ControlFlow, Progress};

/// What a Python caller passed to watch a run.
pub struct Watch {
    /// Any object with `is_set()` (threading.Event).
    pub cancel: Option<Py<PyAny>>,
    /// Called as progress(stage, done, total); `False` cancels.
    pub progress: Option<Py<PyAny>>,
    /// The Python exception that stopped the run (KeyboardInterrupt, or
    /// one the callback raised), re-raised in place of `Cancelled`.
    pub raised: Mutex<Option<PyErr>>,
}

impl Watch {
    pub fn new(cancel: Option<Py<PyAny>>, progress: Option<Py<PyAny>>) -> Self {
        Watch {
            cancel,
            progress,
            raised: Mutex::new(None),
        }
    }

    /// The hook body: Break when Python says stop.
    pub fn report(&self, p: Progress) -> ControlFlow<()> {
        Python::attach(|py| match self.should_stop(py, p) {
            Ok(false) => ControlFlow::Continue(()),
            Ok(true) => ControlFlow::Break(()),
            Err(e) => {
                *self.raised.lock().unwrap_or_else(|p| p.into_inner()) = Some(e);
                ControlFlow::Break(())
            }
        })
    }

    fn should_stop(&self, py: Python<'_>, p: Progress) -> PyResult<bool> {
        py.check_signals()?;
        if let Some(cancel) = &self.cancel {
            if cancel.call_method0(py, "is_set")?.is_truthy(py)? {
                return Ok(true);
            }
        }
        if let Some(progress) = &self.progress {
            let answer = progress.call1(py, (p.stage, p.done, p.total))?;
            // None (no return) continues; only an explicit False stops.
            if !answer.is_none(py) && !answer.is_truthy(py)? {
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// The exception that stopped the run, if Python raised one.
    pub fn take_raised(&self) -> Option<PyErr> {
        self.raised.lock().unwrap_or_else(|p| p.into_inner()).take()
    }
}
