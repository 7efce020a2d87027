//! Progress reports and cancellation for long computations: every method
//! calls a [`Hook`] between its stages and inside its iterations; the hook
//! returns [`ControlFlow::Break`] to cancel, and the method then stops at
//! that point and returns its `Cancelled` error.

pub use std::ops::ControlFlow;

/// Where a long computation is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Progress {
    /// The stage running, as named in the method's report timings
    /// ("distance", "flow", "fit level", ...).
    pub stage: &'static str,
    /// Work done in this stage so far (steps, levels), out of `total`.
    pub done: usize,
    /// Upper bound on `done` (0 when unknown).
    pub total: usize,
}

impl Progress {
    /// At the start of `stage`.
    pub fn stage(stage: &'static str) -> Self {
        Progress {
            stage,
            done: 0,
            total: 0,
        }
    }
}

/// Called with each [`Progress`]; `Break` cancels the computation.
pub type Hook<'a> = &'a dyn Fn(Progress) -> ControlFlow<()>;

/// A hook that reports nowhere and never cancels.
pub fn no_progress(_: Progress) -> ControlFlow<()> {
    ControlFlow::Continue(())
}
