//! Progress reporting on stderr: a spinner per step that takes longer than a moment on a
//! terminal, or plain lines where stderr is a file or a pipe (`--progress lines`: a batch
//! scheduler's log shows each step and, for counted steps, how many items are done and about how
//! long the rest will take).

use std::io::IsTerminal;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

/// How progress is shown (`--progress`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Mode {
    /// Bars and spinners when stderr is a terminal, plain lines otherwise.
    Auto,
    /// Spinners and bars that redraw one line (shown only on a terminal).
    Bars,
    /// One plain line per step, and for counted steps a line at least every
    /// [`LINE_INTERVAL`] with the count, the time elapsed and an estimate of the time left.
    Lines,
    /// Nothing.
    None,
}

/// Seconds between two count lines of a counted step in [`Mode::Lines`] (the last item's line is
/// always printed): often enough for a scheduler's log to show the run is alive, rarely enough
/// that an hour's sweep writes a few hundred lines.
pub const LINE_INTERVAL: Duration = Duration::from_secs(10);

/// Progress of a command: bars, lines or nothing (`--quiet`, `--progress none`).
pub struct Progress {
    quiet: bool,
    mode: Mode,
}

/// One running step; finishing it clears the spinner.
pub struct Step {
    bar: Option<ProgressBar>,
    lines: Option<Lines>,
    started: Instant,
}

/// A counted step shown as lines: the count is shared by the worker threads that finish items.
struct Lines {
    message: String,
    total: u64,
    done: AtomicU64,
    last: Mutex<Instant>,
}

impl Progress {
    /// Progress in `mode`; `quiet` shows nothing whatever the mode. `Auto` is resolved here:
    /// bars on a terminal, lines otherwise.
    pub fn new(quiet: bool, mode: Mode) -> Self {
        let mode = match mode {
            Mode::Auto if std::io::stderr().is_terminal() => Mode::Bars,
            Mode::Auto => Mode::Lines,
            m => m,
        };
        Progress { quiet, mode: if quiet { Mode::None } else { mode } }
    }

    /// Starts a step with a message.
    pub fn step(&self, message: &str) -> Step {
        if self.mode == Mode::Lines {
            eprintln!("springfit: {message} …");
        }
        let bar = (self.mode == Mode::Bars).then(|| {
            let bar = ProgressBar::new_spinner();
            bar.set_style(ProgressStyle::with_template("{spinner} {msg} {elapsed}").expect("static template"));
            bar.set_message(message.to_string());
            bar.enable_steady_tick(Duration::from_millis(120));
            bar
        });
        Step { bar, lines: None, started: Instant::now() }
    }

    /// Starts a step counting `total` units, with the count, the elapsed time and an estimate of
    /// the time left.
    pub fn counted(&self, message: &str, total: u64) -> Step {
        let started = Instant::now();
        let lines = (self.mode == Mode::Lines).then(|| {
            eprintln!("springfit: {message}: {total} to do …");
            Lines { message: message.to_string(), total, done: AtomicU64::new(0), last: Mutex::new(started) }
        });
        let bar = (self.mode == Mode::Bars).then(|| {
            let bar = ProgressBar::new(total);
            bar.set_style(
                ProgressStyle::with_template("{msg}: {pos} of {len} done, {elapsed} elapsed, about {eta} left")
                    .expect("static template"),
            );
            bar.set_message(message.to_string());
            bar.enable_steady_tick(Duration::from_millis(500));
            bar
        });
        Step { bar, lines, started }
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

/// A duration as a reader scans it: `42 s`, `3 min 20 s`, `2 h 05 min`.
fn human(d: Duration) -> String {
    let s = d.as_secs();
    match s {
        0..60 => format!("{s} s"),
        60..3600 => format!("{} min {:02} s", s / 60, s % 60),
        _ => format!("{} h {:02} min", s / 3600, (s % 3600) / 60),
    }
}

impl Lines {
    /// Counts one item; prints the count line when [`LINE_INTERVAL`] has passed since the last
    /// one, or when this was the last item. The time left assumes the items still to do take as
    /// long on average as those done.
    fn inc(&self, started: Instant) {
        let done = self.done.fetch_add(1, Ordering::Relaxed) + 1;
        let now = Instant::now();
        let mut last = self.last.lock().unwrap_or_else(|p| p.into_inner());
        if done < self.total && now.duration_since(*last) < LINE_INTERVAL {
            return;
        }
        *last = now;
        let elapsed = now.duration_since(started);
        let left = elapsed.mul_f64(self.total.saturating_sub(done) as f64 / done as f64);
        eprintln!(
            "springfit: {}: {done} of {} done, {} elapsed, about {} left",
            self.message,
            self.total,
            human(elapsed),
            human(left)
        );
    }
}

impl Step {
    /// Counts one unit done (for [`Progress::counted`] steps).
    pub fn inc(&self) {
        if let Some(bar) = &self.bar {
            bar.inc(1);
        }
        if let Some(lines) = &self.lines {
            lines.inc(self.started);
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
