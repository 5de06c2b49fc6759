//! A log as `identify` computes with it: runs of evenly sampled joint angles (and applied
//! torques) of a built arm; `files::log` reads them from CSV.

use std::path::PathBuf;

/// One run of a log: evenly sampled angles (and torques) from one release or excitation.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// The `run` column's value (empty without the column).
    pub name: String,
    /// Sample times, s.
    pub t: Vec<f64>,
    /// Joint angles, sample-major: `q[i * n + j]` is joint j at sample i, rad.
    pub q: Vec<f64>,
    /// Applied joint torques, sample-major as `q`, N·m; None for a free swing.
    pub tau: Option<Vec<f64>>,
    /// The file line (1-based) of each sample.
    pub lines: Vec<usize>,
    /// The sampling interval (the median of the run's intervals), s.
    pub dt: f64,
}

impl Run {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether the run has no samples (never true for a run read from a file).
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// The duration from the first to the last sample, s.
    pub fn duration(&self) -> f64 {
        self.t.last().copied().unwrap_or(0.0) - self.t.first().copied().unwrap_or(0.0)
    }
}

/// A log file: its runs in file order.
#[derive(Debug, Clone, PartialEq)]
pub struct Log {
    /// The file (for messages).
    pub path: PathBuf,
    /// Number of joints.
    pub dof: usize,
    /// The runs.
    pub runs: Vec<Run>,
}
