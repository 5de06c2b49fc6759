//! The optional progress callback of long calls: `progress(stage: str)` called with the same
//! stage names the command line shows, from whichever thread reaches a stage (the call runs
//! without the GIL and takes it back for the callback). An exception raised by the callback is
//! kept and raised when the call returns.

use std::sync::Mutex;

use pyo3::prelude::*;

/// A callback, or nothing.
pub struct Progress {
    callback: Option<Py<PyAny>>,
    raised: Mutex<Option<PyErr>>,
}

impl Progress {
    /// Wraps the `progress` argument.
    pub fn new(callback: Option<Py<PyAny>>) -> Progress {
        Progress { callback, raised: Mutex::new(None) }
    }

    /// Reports a stage.
    pub fn stage(&self, name: &str) {
        let Some(cb) = &self.callback else { return };
        Python::attach(|py| {
            if let Err(e) = cb.call1(py, (name,)) {
                let mut raised = self.raised.lock().unwrap_or_else(|p| p.into_inner());
                raised.get_or_insert(e);
            }
        });
    }

    /// The first exception the callback raised, if any.
    pub fn raised(&self) -> PyResult<()> {
        match self.raised.lock().unwrap_or_else(|p| p.into_inner()).take() {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }
}
