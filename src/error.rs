//! The one error type of the library.
//!
//! Every failure a user can meet carries what a person needs to fix it: the file, the field (or the
//! line and column for TOML syntax), and the reason. The library never prints or exits; the CLI maps
//! [`Error::kind`] to an exit code. Numbers a message would write out in hundreds of digits are
//! shown in scientific notation (`limits::tidy_numbers`).

use std::path::PathBuf;

use crate::limits::tidy_numbers as tidy;

/// What kind of failure an [`Error`] is, for callers that react differently (the CLI's exit codes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// The input files or the command line are wrong: fix them and run again.
    BadInput,
    /// The input is well formed but the design cannot be met (an infeasible fit, a numerical
    /// method that did not converge).
    NotMet,
}

/// Errors of springfit.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{}: {}", path.display(), explain(cause))]
    Io {
        /// The file or folder that could not be read or written, as the caller named it.
        path: PathBuf,
        /// The operating system's reason (kept out of the error chain so it prints once).
        cause: std::io::Error,
    },
    /// A TOML or CSV file does not parse, or has an unknown field or a value of the wrong type.
    #[error("{}{}: {}", path.display(), position(*line, *column), tidy(message))]
    Parse {
        /// The file that does not parse (a design, catalogue, cam file, URDF, sweep shard or fit
        /// summary).
        path: PathBuf,
        /// 1-based line of the problem (0 when the parser gave no position).
        line: usize,
        /// 1-based column of the problem (0 when the parser gave no position).
        column: usize,
        /// The parser's message in words, naming the dotted key where one is known.
        message: String,
    },
    /// A value parsed but is not acceptable (a negative mass, an equilibrium outside the region).
    #[error("{}: field `{field}`: {}", path.display(), tidy(reason))]
    Invalid {
        /// The file the value was read from.
        path: PathBuf,
        /// The value's dotted key as written in the file (`robot.links[1].mass`), or its column.
        field: String,
        /// Why the value is refused, with the limit or the expected value.
        reason: String,
    },
    /// Settings or arguments given through the API or the command line are not acceptable.
    #[error("setting `{field}`: {}", tidy(reason))]
    Setting {
        /// The setting as the caller wrote it: a key (`max_elements`) or an option (`--threads`).
        field: String,
        /// Why the value is refused.
        reason: String,
    },
    /// The fit's constraints cannot all be met.
    #[error("the fit is infeasible: {}: {}", tidy(constraint), tidy(reason))]
    Infeasible {
        /// What could not be met: the solver's constraint groups (equalities; inequalities),
        /// `smoothing`, or a Pareto run's budgets; `fit::hints::explain` picks its advice by it.
        constraint: String,
        /// Why, as the solver or the study found it, with advice appended (`; to fix: …`) where
        /// `fit::hints` has one.
        reason: String,
    },
    /// No spring meets an element's limits within the design's `[parts]` (the reason names the
    /// element, the limit, by how much, and the setting that would keep a part possible).
    #[error("{}: [parts]: {reason}", path.display())]
    NoPart {
        /// The design file whose `[parts]` section sets the limits.
        path: PathBuf,
        /// The element, the limit, by how much it is missed and the setting that would help.
        reason: String,
    },
    /// A numerical method failed (integrator step-size underflow, a singular mass matrix, a log
    /// map that did not converge, a solver that stopped early).
    #[error("{}: {}", tidy(context), tidy(reason))]
    Numerical {
        /// What was being computed (`tolerance-aware fit`, `scenario NAME run NAME: …`; the
        /// design's region check names the design file), callers adding their own part.
        context: String,
        /// How the method failed.
        reason: String,
    },
    /// A plot could not be drawn or written.
    #[error("plot {}: {}", path.display(), tidy(reason))]
    Plot {
        /// The figure's file (`.svg` or `.png`).
        path: PathBuf,
        /// The plotting library's reason.
        reason: String,
    },
}

impl Error {
    /// Classifies the error for the caller.
    pub fn kind(&self) -> ErrorKind {
        match self {
            Error::Io { .. }
            | Error::Parse { .. }
            | Error::Invalid { .. }
            | Error::Setting { .. }
            | Error::Plot { .. } => ErrorKind::BadInput,
            Error::Infeasible { .. } | Error::NoPart { .. } | Error::Numerical { .. } => ErrorKind::NotMet,
        }
    }

    /// Shorthand for an [`Error::Io`].
    pub fn io(path: impl Into<PathBuf>, cause: std::io::Error) -> Self {
        Error::Io { path: path.into(), cause }
    }

    /// Shorthand for an [`Error::Invalid`].
    pub fn invalid(path: impl Into<PathBuf>, field: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::Invalid { path: path.into(), field: field.into(), reason: reason.into() }
    }

    /// Shorthand for an [`Error::Numerical`].
    pub fn numerical(context: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::Numerical { context: context.into(), reason: reason.into() }
    }
}

/// `:line:column` of a parse error, or nothing when the parser gave no position.
fn position(line: usize, column: usize) -> String {
    if line == 0 { String::new() } else { format!(":{line}:{column}") }
}

/// The library's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// The operating system's reason in the words of springfit's other messages where the raw one
/// misleads or says little (a folder given where a file is read, a path that does not exist);
/// any other reason as the system gives it.
fn explain(cause: &std::io::Error) -> String {
    match cause.kind() {
        std::io::ErrorKind::NotFound => {
            "no such file (or a folder on its path is missing; relative paths start from the current folder)".into()
        }
        std::io::ErrorKind::IsADirectory => "is a folder: a file is expected here".into(),
        std::io::ErrorKind::PermissionDenied => {
            "permission denied (check the file's and its folder's permissions)".into()
        }
        _ => cause.to_string(),
    }
}
