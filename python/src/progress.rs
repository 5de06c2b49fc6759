//! The optional progress callback of long calls: `progress(stage: str)` called with the same
//! stage names the command line shows, from whichever thread reaches a stage (the call runs
//! without the GIL and takes it back for the callback); a counted stage (the sweep's items) is
//! told as `"<stage>: k of N done"` after each item. An exception raised by the callback is kept
//! and raised when the call returns. It is the library's [`springfit::progress::Observer`], so
//! the jobs report to it as they report to the command line's spinners.

use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use pyo3::prelude::*;

/// A callback, or nothing.
pub struct Progress {
    callback: Option<Py<PyAny>>,
    raised: Mutex<Option<PyErr>>,
    /// The counted stage: its name and number of items.
    counted: Mutex<(String, usize)>,
    done: AtomicUsize,
}

impl Progress {
    /// Wraps the `progress` argument.
    pub fn new(callback: Option<Py<PyAny>>) -> Progress {
        Progress {
            callback,
            raised: Mutex::new(None),
            counted: Mutex::new((String::new(), 0)),
            done: AtomicUsize::new(0),
        }
    }

    /// The library's progress reporting to this callback.
    pub fn observer(&self) -> springfit::progress::Progress<'_> {
        springfit::progress::Progress::to(self)
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

impl springfit::progress::Observer for Progress {
    fn stage(&self, name: &str) {
        Progress::stage(self, name);
    }

    fn counted(&self, name: &str, total: usize) {
        *self.counted.lock().unwrap_or_else(|p| p.into_inner()) = (name.to_string(), total);
        self.done.store(0, Ordering::Relaxed);
    }

    fn item_done(&self) {
        let k = self.done.fetch_add(1, Ordering::Relaxed) + 1;
        let text = {
            let counted = self.counted.lock().unwrap_or_else(|p| p.into_inner());
            format!("{}: {k} of {} done", counted.0, counted.1)
        };
        Progress::stage(self, &text);
    }
}
