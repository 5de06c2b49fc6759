//! How a long call tells its caller how far it has got, without printing anything itself.
//!
//! Every long call of the library (a fit, a sweep, a simulation, the jobs of [`crate::jobs`])
//! takes one [`Progress`]: the stage names it passes are the ones `springfit` shows beside its
//! spinners, so the command line's progress bars and the Python package's `progress(stage)`
//! callback see the same steps. A caller that does not care passes [`Progress::none()`]; one
//! that does implements [`Observer`] once (the CLI's spinners, Python's callback) and passes
//! [`Progress::to`] it.

/// What a caller wants to hear about a long call. Every method has a silent default, so an
/// observer implements only what it shows. An observer is shared with the worker threads of a
/// parallel step (hence `Sync`): [`Observer::item_done`] may come from any of them.
pub trait Observer: Sync {
    /// A stage begins (`"solving"`, `"as-built Monte Carlo builds"`); the previous one, if any,
    /// has ended.
    fn stage(&self, _name: &str) {}

    /// A stage of `total` items begins (the sweep's items), counted by
    /// [`Observer::item_done`]. By default it is told as a plain stage.
    fn counted(&self, name: &str, _total: usize) {
        self.stage(name);
    }

    /// One item of the current counted stage is done.
    fn item_done(&self) {}
}

/// Where a long call reports its stages: to an [`Observer`], or nowhere. Cheap to copy, so a
/// call hands it on to the calls it makes.
#[derive(Clone, Copy, Default)]
pub struct Progress<'a> {
    observer: Option<&'a dyn Observer>,
}

impl<'a> Progress<'a> {
    /// Reports nowhere: for callers that only want the result (tests, benches, inner calls whose
    /// stages would only clutter the caller's own).
    pub fn none() -> Progress<'static> {
        Progress { observer: None }
    }

    /// Reports to `observer`.
    pub fn to(observer: &'a dyn Observer) -> Progress<'a> {
        Progress { observer: Some(observer) }
    }

    /// A stage begins.
    pub fn stage(&self, name: &str) {
        if let Some(o) = self.observer {
            o.stage(name);
        }
    }

    /// A stage of `total` items begins.
    pub fn counted(&self, name: &str, total: usize) {
        if let Some(o) = self.observer {
            o.counted(name, total);
        }
    }

    /// One item of the current counted stage is done.
    pub fn item_done(&self) {
        if let Some(o) = self.observer {
            o.item_done();
        }
    }
}

impl std::fmt::Debug for Progress<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.observer.is_some() { "Progress(observed)" } else { "Progress(none)" })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    struct Record(Mutex<Vec<String>>);

    impl Observer for Record {
        fn stage(&self, name: &str) {
            self.0.lock().unwrap().push(name.to_string());
        }
    }

    #[test]
    fn an_observer_hears_stages_and_counted_stages_as_stages_by_default() {
        let record = Record(Mutex::new(Vec::new()));
        let p = Progress::to(&record);
        p.stage("a");
        p.counted("b", 3);
        p.item_done();
        Progress::none().stage("unheard");
        assert_eq!(*record.0.lock().unwrap(), ["a", "b"]);
    }
}
