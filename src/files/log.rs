//! Logs of a built arm's motion, the input of `springfit identify`.
//!
//! A CSV file with a header line and one line per sample:
//!
//! - `t`: time, s, strictly increasing within a run and evenly spaced (a sampling loop's jitter
//!   of up to [`JITTER`] of the interval is accepted; the samples are then taken as evenly spaced);
//! - `q1` … `qn`: the joint angles, rad, in the design's joint order (unwrapped: no jumps of 2π);
//! - optionally `tau1` … `taun`: the torque a motor applied to each joint at that time, N·m
//!   (without them the run is a free swing);
//! - optionally `run`: a name; consecutive lines with the same name are one run (a release, an
//!   excitation), each filtered on its own. Without it the file is one run.
//!
//! Every problem names the file, the line and the column: a header without `t` or with the
//! wrong number of joints, an unknown column, a field that is not a finite number, time that goes
//! back or stands still, a gap in the sampling, a run name that comes back after another run.

use std::path::Path;

use crate::csv::split_csv_line;
use crate::error::{Error, Result};
use crate::input::read_text;

pub use crate::identify::log::{Log, Run};

/// The largest deviation of one sampling interval from the run's median interval, as a fraction,
/// that still counts as even sampling.
pub const JITTER: f64 = 0.05;

/// The fewest samples a run may have.
pub const MIN_SAMPLES: usize = 16;

/// What each column of the header holds.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Column {
    Time,
    Run,
    Angle(usize),
    Torque(usize),
}

/// Reads a log of an arm with `dof` joints.
pub fn read(path: &Path, dof: usize) -> Result<Log> {
    parse(path, &read_text(path)?, dof)
}

/// Parses the text of a log (see [`read`]): the header says which column holds what, then
/// each line adds a sample to its run, then each run's sampling interval is checked.
pub fn parse(path: &Path, text: &str, dof: usize) -> Result<Log> {
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines.next().ok_or_else(|| bad_line(path, 1, "header", "the file is empty".into()))?;
    let header = Header::parse(path, header, dof)?;
    let mut runs: Vec<Run> = Vec::new();
    for (idx, line) in lines {
        header.add_line(path, idx + 1, line, &mut runs)?;
    }
    if runs.is_empty() {
        return Err(bad_line(path, 2, "row", "the log has no samples".into()));
    }
    for run in &mut runs {
        run.dt = even_interval(path, run)?;
    }
    Ok(Log { path: path.to_path_buf(), dof, runs })
}

/// An error on line `line` of the log, in column `field`.
fn bad_line(path: &Path, line: usize, field: &str, reason: String) -> Error {
    Error::invalid(path, format!("line {line}: {field}"), reason)
}

/// The header of a log: the columns' names and which holds the time, each joint's angle, the
/// torques (all joints' or none) and the run's name.
struct Header {
    names: Vec<String>,
    time: usize,
    angles: Vec<usize>,
    torques: Option<Vec<usize>>,
    run: Option<usize>,
}

impl Header {
    /// Reads the header of a log of an arm with `dof` joints: every column known and given
    /// once, `t` and every `q` present, torques for every joint or none.
    fn parse(path: &Path, header: &str, dof: usize) -> Result<Header> {
        let bad = |reason: String| bad_line(path, 1, "header", reason);
        let names = split_csv_line(header.trim_start_matches('\u{feff}').trim()).map_err(bad)?;
        let names: Vec<String> = names.iter().map(|n| n.trim().to_string()).collect();
        let expected = format!(
            "a log has columns t, q1…q{dof}, optionally tau1…tau{dof} and run (the design's robot has {dof} joints)"
        );
        let columns = columns(&names, &expected).map_err(bad)?;
        let position = |c: Column| columns.iter().position(|x| *x == c);
        let time = position(Column::Time).ok_or_else(|| bad(format!("no column `t`: {expected}")))?;
        let widest = columns
            .iter()
            .filter_map(|c| match c {
                Column::Angle(i) | Column::Torque(i) => Some(*i + 1),
                _ => None,
            })
            .max()
            .unwrap_or(0);
        if widest > dof {
            return Err(bad(format!(
                "the log has columns for {widest} joints but the design's robot has {dof}: {expected}"
            )));
        }
        let angles: Vec<usize> = (0..dof)
            .map(|j| position(Column::Angle(j)).ok_or_else(|| bad(format!("no column `q{}`: {expected}", j + 1))))
            .collect::<Result<_>>()?;
        let torques: Vec<Option<usize>> = (0..dof).map(|j| position(Column::Torque(j))).collect();
        let torques: Option<Vec<usize>> = match torques.iter().filter(|c| c.is_some()).count() {
            0 => None,
            k if k == dof => Some(torques.into_iter().flatten().collect()),
            _ => {
                let missing = (0..dof).find(|&j| torques[j].is_none()).unwrap_or(0);
                return Err(bad(format!(
                    "no column `tau{}`: torques are given for every joint or for none",
                    missing + 1
                )));
            }
        };
        Ok(Header { names, time, angles, torques, run: position(Column::Run) })
    }

    /// Adds line `ln` to its run: the last one when it has the same name, a new one otherwise
    /// (a name must not come back after another run); time must go forward within a run.
    fn add_line(&self, path: &Path, ln: usize, line: &str, runs: &mut Vec<Run>) -> Result<()> {
        let bad = |field: &str, reason: String| bad_line(path, ln, field, reason);
        let f = split_csv_line(line).map_err(|e| bad("row", e))?;
        if f.len() != self.names.len() {
            return Err(bad("row", format!("has {} fields, the header {}", f.len(), self.names.len())));
        }
        let num = |c: usize| -> Result<f64> {
            let text = f[c].trim();
            let v: f64 = text.parse().map_err(|_| bad(&self.names[c], format!("`{text}` is not a number")))?;
            if !v.is_finite() {
                return Err(bad(&self.names[c], format!("`{text}` is not a finite number")));
            }
            Ok(v)
        };
        let name = self.run.map(|c| f[c].trim().to_string()).unwrap_or_default();
        if runs.last().is_none_or(|r| r.name != name) {
            if runs.iter().any(|r| r.name == name) {
                return Err(bad(
                    "run",
                    format!("run `{name}` comes back after another run: a run's lines must be consecutive"),
                ));
            }
            runs.push(Run {
                name,
                t: Vec::new(),
                q: Vec::new(),
                tau: self.torques.as_ref().map(|_| Vec::new()),
                lines: Vec::new(),
                dt: 0.0,
            });
        }
        let t = num(self.time)?;
        // A run was pushed above when there was none.
        let Some(run) = runs.last_mut() else { return Ok(()) };
        if let (Some(&before), Some(&line_before)) = (run.t.last(), run.lines.last())
            && t <= before
        {
            return Err(bad("t", format!("time goes back or stands still: {t} after {before} on line {line_before}")));
        }
        run.t.push(t);
        run.lines.push(ln);
        for &c in &self.angles {
            run.q.push(num(c)?);
        }
        if let (Some(cols), Some(tau)) = (&self.torques, run.tau.as_mut()) {
            for &c in cols {
                tau.push(num(c)?);
            }
        }
        Ok(())
    }
}

/// What each named column holds (`t`, `run`, `q<i>`, `tau<i>`), each at most once; or why not.
fn columns(names: &[String], expected: &str) -> std::result::Result<Vec<Column>, String> {
    let mut columns = Vec::with_capacity(names.len());
    for name in names {
        let joint = |prefix: &str| name.strip_prefix(prefix).and_then(|i| i.parse::<usize>().ok()).filter(|i| *i >= 1);
        let c = match name.as_str() {
            "t" => Column::Time,
            "run" => Column::Run,
            _ => match (joint("q"), joint("tau")) {
                (Some(i), _) => Column::Angle(i - 1),
                (_, Some(i)) => Column::Torque(i - 1),
                _ => return Err(format!("unknown column `{name}`: {expected}")),
            },
        };
        if columns.contains(&c) {
            return Err(format!("column `{name}` appears twice"));
        }
        columns.push(c);
    }
    Ok(columns)
}

/// The sampling interval of a run (its median interval), or an error naming the first gap or
/// uneven interval.
fn even_interval(path: &Path, run: &Run) -> Result<f64> {
    let label = if run.name.is_empty() { "the log".to_string() } else { format!("run `{}`", run.name) };
    if run.len() < MIN_SAMPLES {
        return Err(Error::invalid(
            path,
            format!("line {}: t", run.lines[0]),
            format!("{label} has {} samples; a run needs at least {MIN_SAMPLES}", run.len()),
        ));
    }
    let mut dts: Vec<f64> = run.t.windows(2).map(|w| w[1] - w[0]).collect();
    dts.sort_by(f64::total_cmp);
    let dt = dts[dts.len() / 2];
    for (i, w) in run.t.windows(2).enumerate() {
        let step = w[1] - w[0];
        if (step - dt).abs() > JITTER * dt {
            let what = if step > dt {
                format!("a gap of {step} s after t = {} (line {})", w[0], run.lines[i])
            } else {
                format!("an interval of {step} s after t = {} (line {})", w[0], run.lines[i])
            };
            return Err(Error::invalid(
                path,
                format!("line {}: t", run.lines[i + 1]),
                format!(
                    "{what}, but {label} is sampled every {dt} s: the filters need even sampling; split the run \
                     there (a new `run` name) or log without dropouts"
                ),
            ));
        }
    }
    Ok(dt)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn log(text: &str) -> Result<Log> {
        parse(Path::new("swing.csv"), text, 2)
    }

    fn samples(name: &str, from: usize, count: usize) -> String {
        (from..from + count).map(|i| format!("{name},{},{},{}\n", i as f64 * 0.001, 0.1, 1.5)).collect()
    }

    #[test]
    fn runs_are_read_in_order_with_their_lines() {
        let text = format!("run,t,q1,q2\n{}{}", samples("a", 0, 20), samples("b", 0, 30));
        let l = log(&text).unwrap();
        assert_eq!(l.runs.len(), 2);
        assert_eq!((l.runs[0].name.as_str(), l.runs[0].len(), l.runs[1].len()), ("a", 20, 30));
        assert_eq!(l.runs[1].lines[0], 22);
        assert!((l.runs[0].dt - 0.001).abs() < 1e-15);
        assert_eq!(&l.runs[0].q[..2], &[0.1, 1.5]);
        assert!(l.runs[0].tau.is_none());
        // Torques, and no run column: one run.
        let text: String = std::iter::once("t,q1,q2,tau1,tau2\n".to_string())
            .chain((0..20).map(|i| format!("{},0,1,{},-{}\n", i as f64 * 0.01, i, i)))
            .collect();
        let l = log(&text).unwrap();
        assert_eq!(l.runs.len(), 1);
        assert_eq!(&l.runs[0].tau.as_ref().unwrap()[2..4], &[1.0, -1.0]);
    }

    fn error(text: &str) -> String {
        log(text).unwrap_err().to_string()
    }

    #[test]
    fn bad_logs_name_the_line_and_the_reason() {
        let ok = samples("a", 0, 20);
        // Time going back on line 12.
        let mut lines: Vec<String> = ok.lines().map(String::from).collect();
        lines[10] = "a,0.0005,0.1,1.5".into();
        let e = error(&format!("run,t,q1,q2\n{}\n", lines.join("\n")));
        assert!(e.contains("swing.csv") && e.contains("line 12: t") && e.contains("goes back"), "{e}");
        // A gap: samples 10 … 12 missing.
        let gap: String = samples("a", 0, 10) + &samples("a", 13, 10);
        let e = error(&format!("run,t,q1,q2\n{gap}"));
        assert!(e.contains("line 12: t") && e.contains("a gap of") && e.contains("every 0.001 s"), "{e}");
        // NaN in an angle.
        lines = ok.lines().map(String::from).collect();
        lines[4] = "a,0.004,NaN,1.5".into();
        let e = error(&format!("run,t,q1,q2\n{}\n", lines.join("\n")));
        assert!(e.contains("line 6: q1") && e.contains("not a finite number"), "{e}");
        // The wrong number of joints: three in the log, two in the design; one missing.
        let e = error("t,q1,q2,q3\n0,0,0,0\n");
        assert!(e.contains("line 1: header") && e.contains("3 joints") && e.contains("has 2"), "{e}");
        let e = error("t,q1\n0,0\n");
        assert!(e.contains("no column `q2`"), "{e}");
        assert!(error("t,q1,q2,tau1\n0,0,0,0\n").contains("no column `tau2`"));
        assert!(error("t,q1,q2,speed\n0,0,0,0\n").contains("unknown column `speed`"));
        assert!(error("q1,q2\n0,0\n").contains("no column `t`"));
        // A run that comes back.
        let e = error(&format!("run,t,q1,q2\n{}{}{}", samples("a", 0, 20), samples("b", 0, 20), samples("a", 40, 2)));
        assert!(e.contains("line 42: run") && e.contains("comes back"), "{e}");
        // Too short, and a missing field.
        assert!(error(&format!("run,t,q1,q2\n{}", samples("a", 0, 5))).contains("at least 16"));
        assert!(error("t,q1,q2\n0,1\n").contains("line 2: row"));
    }
}
