//! Progress reporting on stderr: a spinner per step that takes longer than a moment.

use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

/// Progress of a command: silent with `--quiet` or when stderr is not a terminal.
pub struct Progress {
    quiet: bool,
}

/// One running step; finishing it clears the spinner.
pub struct Step {
    bar: Option<ProgressBar>,
    started: Instant,
}

impl Progress {
    pub fn new(quiet: bool) -> Self {
        Progress { quiet }
    }

    /// Starts a step with a message.
    pub fn step(&self, message: &str) -> Step {
        let bar = (!self.quiet).then(|| {
            let bar = ProgressBar::new_spinner();
            bar.set_style(ProgressStyle::with_template("{spinner} {msg} {elapsed}").expect("static template"));
            bar.set_message(message.to_string());
            bar.enable_steady_tick(Duration::from_millis(120));
            bar
        });
        Step { bar, started: Instant::now() }
    }

    /// Starts a step counting `total` units, with the count, the elapsed time and an estimate of
    /// the time left.
    pub fn counted(&self, message: &str, total: u64) -> Step {
        let bar = (!self.quiet).then(|| {
            let bar = ProgressBar::new(total);
            bar.set_style(
                ProgressStyle::with_template("{msg}: {pos} of {len} done, {elapsed} elapsed, about {eta} left")
                    .expect("static template"),
            );
            bar.set_message(message.to_string());
            bar.enable_steady_tick(Duration::from_millis(500));
            bar
        });
        Step { bar, started: Instant::now() }
    }

    /// Runs `job` with its stages shown as spinners (see [`Spinners`]).
    pub fn run<T>(&self, job: impl FnOnce(springfit::progress::Progress<'_>) -> T) -> T {
        let spinners = Spinners { progress: self, step: Mutex::new(None) };
        job(springfit::progress::Progress::to(&spinners))
    }

    /// Prints a warning on stderr, `springfit: warning: …`, even when quiet (a warning is about
    /// the input, like an error).
    pub fn warn(&self, w: impl std::fmt::Display) {
        eprintln!("springfit: warning: {w}");
    }

    /// Prints a line of results to stdout unless quiet. A closed stdout (`springfit … | head`)
    /// is not an error worth a panic: the line is dropped.
    pub fn say(&self, line: impl AsRef<str>) {
        if !self.quiet {
            use std::io::Write;
            let _ = writeln!(std::io::stdout(), "{}", line.as_ref());
        }
    }
}

impl Step {
    /// Counts one unit done (for [`Progress::counted`] steps).
    pub fn inc(&self) {
        if let Some(bar) = &self.bar {
            bar.inc(1);
        }
    }

    /// Ends the step and returns its duration in seconds.
    pub fn finish(self) -> f64 {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
        self.started.elapsed().as_secs_f64()
    }
}

/// The library's [`springfit::progress::Observer`] on the command line: each stage a spinner
/// (a counted stage a bar) that the next stage, or the end of the job, clears.
struct Spinners<'a> {
    progress: &'a Progress,
    step: Mutex<Option<Step>>,
}

impl Spinners<'_> {
    /// Ends the current step and starts `next`.
    fn replace(&self, next: Option<Step>) {
        // A panic cannot happen while the lock is held, so a poisoned lock still holds a step.
        let mut step = self.step.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(s) = std::mem::replace(&mut *step, next) {
            s.finish();
        }
    }
}

impl springfit::progress::Observer for Spinners<'_> {
    fn stage(&self, name: &str) {
        self.replace(Some(self.progress.step(name)));
    }

    fn counted(&self, name: &str, total: usize) {
        self.replace(Some(self.progress.counted(name, total as u64)));
    }

    fn item_done(&self) {
        if let Some(s) = &*self.step.lock().unwrap_or_else(|p| p.into_inner()) {
            s.inc();
        }
    }
}

impl Drop for Spinners<'_> {
    fn drop(&mut self) {
        self.replace(None);
    }
}
