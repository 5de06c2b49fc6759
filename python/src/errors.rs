//! springfit's one error type as Python exceptions.
//!
//! `springfit.Error` carries the message the command line prints after `springfit: error: `, and
//! the `file` and `field` it names (None where the error has none). Its subclasses follow
//! [`springfit::ErrorKind`] (what the CLI's exit codes follow) and then the variant, so a caller
//! can catch "fix the input" apart from "the design cannot be met".

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use springfit::Error;

create_exception!(
    springfit,
    SpringfitError,
    PyException,
    "Every error springfit raises: `str(e)` is the command line's message; `e.file` and `e.field` what it names (or None)."
);
create_exception!(
    springfit,
    BadInputError,
    SpringfitError,
    "The input files, settings or arguments are wrong: fix them and call again (the CLI's exit code 2)."
);
create_exception!(
    springfit,
    NotMetError,
    SpringfitError,
    "The input is well formed but the design cannot be met: an infeasible fit, a numerical method that did not converge (exit code 1)."
);
create_exception!(springfit, FileError, BadInputError, "A file could not be read or written.");
create_exception!(
    springfit,
    ParseError,
    BadInputError,
    "A TOML or CSV file does not parse, or has an unknown key or a value of the wrong type (`e.line`, `e.column`)."
);
create_exception!(
    springfit,
    InvalidError,
    BadInputError,
    "A value in a file parsed but is not acceptable (`e.file`, `e.field`)."
);
create_exception!(
    springfit,
    SettingError,
    BadInputError,
    "A setting or argument given through the API is not acceptable (`e.field`): a wrong array shape, NaN, an unknown key."
);
create_exception!(springfit, PlotError, BadInputError, "A plot could not be drawn or written.");
create_exception!(springfit, InfeasibleError, NotMetError, "The fit's constraints cannot all be met.");
create_exception!(
    springfit,
    NoPartError,
    NotMetError,
    "An element of the fitted bill has no spring within the design's [parts] envelope (the message names the limit and the setting that would keep a part possible)."
);
create_exception!(
    springfit,
    NumericalError,
    NotMetError,
    "A numerical method failed (a log map that did not converge, a singular mass matrix)."
);

/// The command line's words in library messages and what a Python caller writes instead: the
/// library's messages advise the command line's flags (the output folders' refusals above all),
/// and a Python caller passes the folder and `overwrite_edits=True` to `write` instead.
const PYTHON_WORDS: &[(&str, &str)] = &[
    ("pass --overwrite-edits", "pass overwrite_edits=True"),
    ("choose another --out", "write to another folder"),
    ("pass --out with a folder", "write to a folder"),
];

/// A library message in a Python caller's words ([`PYTHON_WORDS`]).
pub fn python_words(message: &str) -> String {
    PYTHON_WORDS.iter().fold(message.to_string(), |m, (cli, py)| m.replace(cli, py))
}

/// The Python exception for a library error, with `file`, `field`, `line` and `column` set.
pub fn to_py(e: Error) -> PyErr {
    let file = match &e {
        Error::Io { path, .. } | Error::Plot { path, .. } | Error::Parse { path, .. } | Error::Invalid { path, .. } => {
            Some(path.display().to_string())
        }
        _ => None,
    };
    build(&e, python_words(&e.to_string()), file)
}

/// The error as the command line shows it for a design: errors that carry no file of their own
/// (infeasible, numerical) are prefixed with the design's path, as the CLI's context does.
pub fn in_design(e: Error, path: &std::path::Path) -> PyErr {
    match e {
        Error::Infeasible { .. } | Error::Numerical { .. } => {
            let message = python_words(&format!("{}: {e}", path.display()));
            build(&e, message, Some(path.display().to_string()))
        }
        other => to_py(other),
    }
}

fn build(e: &Error, message: String, file: Option<String>) -> PyErr {
    let (field, line, column) = match e {
        Error::Parse { line, column, .. } => (None, Some(*line), Some(*column)),
        Error::Invalid { field, .. } | Error::Setting { field, .. } => (Some(field.clone()), None, None),
        Error::Infeasible { constraint, .. } => (Some(constraint.clone()), None, None),
        _ => (None, None, None),
    };
    let err = match e {
        Error::Io { .. } => FileError::new_err(message),
        Error::Parse { .. } => ParseError::new_err(message),
        Error::Invalid { .. } => InvalidError::new_err(message),
        Error::Setting { .. } => SettingError::new_err(message),
        Error::Plot { .. } => PlotError::new_err(message),
        Error::Infeasible { .. } => InfeasibleError::new_err(message),
        Error::NoPart { .. } => NoPartError::new_err(message),
        Error::Numerical { .. } => NumericalError::new_err(message),
    };
    Python::attach(|py| {
        let value = err.value(py);
        // Setting attributes on a fresh exception instance cannot fail short of memory exhaustion;
        // if it did, the exception still carries its message.
        let _ = value.setattr("file", file);
        let _ = value.setattr("field", field);
        let _ = value.setattr("line", line);
        let _ = value.setattr("column", column);
    });
    err
}

/// A library result as a Python result.
pub trait IntoPy<T> {
    /// Converts the error (see [`to_py`]).
    fn py(self) -> PyResult<T>;
}

impl<T> IntoPy<T> for springfit::Result<T> {
    fn py(self) -> PyResult<T> {
        self.map_err(to_py)
    }
}

/// An [`Error::Setting`] for the API's own arguments.
pub fn setting(field: impl Into<String>, reason: impl Into<String>) -> PyErr {
    to_py(Error::Setting { field: field.into(), reason: reason.into() })
}

/// Registers the exception classes in the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("Error", py.get_type::<SpringfitError>())?;
    m.add("BadInputError", py.get_type::<BadInputError>())?;
    m.add("NotMetError", py.get_type::<NotMetError>())?;
    m.add("FileError", py.get_type::<FileError>())?;
    m.add("ParseError", py.get_type::<ParseError>())?;
    m.add("InvalidError", py.get_type::<InvalidError>())?;
    m.add("SettingError", py.get_type::<SettingError>())?;
    m.add("PlotError", py.get_type::<PlotError>())?;
    m.add("InfeasibleError", py.get_type::<InfeasibleError>())?;
    m.add("NumericalError", py.get_type::<NumericalError>())?;
    m.add("NoPartError", py.get_type::<NoPartError>())?;
    Ok(())
}
