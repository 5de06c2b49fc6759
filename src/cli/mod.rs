//! Argument parsing and command dispatch. Arguments are parsed and validated here, then each
//! command resolves them into a run of library calls; printing and progress bars live here only.

mod check;
mod compare;
mod export;
mod fit;
mod geodesics;
mod identify;
mod init;
mod parts;
mod progress;
mod simulate;
mod sweep;
mod tune;

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::{Parser, Subcommand};
use springfit::design::Design;
use springfit::design::fit::SolverKind;
use springfit::design::validate::Validated;
use springfit::report::output::{Edits, Plan};
use springfit::{Error, ErrorKind};

/// The design used when none is given: the paper's double pendulum.
pub const DEFAULT_DESIGN: &str = "designs/double_pendulum.toml";

#[derive(Debug, Parser)]
#[command(
    name = "springfit",
    version,
    about = "Designs spring layouts for robot arms so that strict normal modes fill a region",
    long_about = "springfit designs spring layouts for robot arms (planar chains typed into the design file, or \
serial arms from a URDF): released from rest anywhere in a \
region, the arm swings back and forth through its equilibrium on a fixed geodesic of its inertia \
metric (a strict normal mode). It fits non-negative stiffnesses of real elastic elements from a \
spring catalogue and checks the design before it is built.",
    after_help = "Examples:\n  springfit fit                      # the paper's design, outputs in out/double_pendulum\n  springfit check designs/double_pendulum.toml\n  springfit geodesics designs/double_pendulum.toml --out out/geodesics\n\nExit codes: 0 ok, 1 the design could not be met, 2 bad input or usage."
)]
pub struct Cli {
    /// Print nothing but errors and warnings (no progress bars, no summaries).
    #[arg(long, short, global = true)]
    pub quiet: bool,
    /// How progress is shown on stderr: `auto` (bars on a terminal, lines otherwise), `bars`,
    /// `lines` (one plain line per step; counted steps add a line every 10 s with the count
    /// and an estimate of the time left: for batch schedulers and logs) or `none`.
    #[arg(long, global = true, value_enum, default_value = "auto", value_name = "MODE")]
    pub progress: progress::Mode,
    /// Worker threads for parallel steps (default: all cores). Results do not depend on it.
    #[arg(long, global = true, value_name = "N", allow_negative_numbers = true)]
    pub threads: Option<usize>,
    /// Let a run replace files of its earlier output that you edited since (a bom.csv with
    /// measured rates filled in); without it such a run is refused before any work.
    #[arg(long, global = true)]
    pub overwrite_edits: bool,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Fit spring stiffnesses from the design's catalogue and write the bill of materials.
    #[command(
        after_help = "Examples:\n  springfit fit\n  springfit fit designs/double_pendulum_dense.toml --out out/dense\n  springfit fit --exact\n\n\
Writes bom.csv, bom.md, summary.json, residuals.csv, histogram.svg/.png, potential.svg/.png and\n\
report.md into the output folder, all at once (nothing is left half-written on an error)."
    )]
    Fit {
        /// Design file (TOML).
        #[arg(default_value = DEFAULT_DESIGN)]
        design: PathBuf,
        /// Output folder (default: out/<design name>, out/<design name>_exact with --exact).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Evaluate the exact potential ½ω²r² (the physical limit, ~0°) instead of fitting springs.
        #[arg(long)]
        exact: bool,
        /// Override the design's solver.
        #[arg(long, value_enum)]
        solver: Option<SolverArg>,
        /// Override the design's element budget (0: no limit).
        #[arg(long, value_name = "K", allow_negative_numbers = true)]
        max_elements: Option<usize>,
    },
    /// Simulate the design's scenarios in closed loop: free releases, mode switching, swing-up.
    #[command(
        after_help = "Examples:\n  springfit simulate\n  springfit simulate --scenario swingup\n  springfit simulate --bom out/double_pendulum/bom.csv\n  springfit simulate --exact\n\n\
Writes, per scenario, sim_<name>.csv (t, q, q̇, torque per source, E, label, geodesic deviation),\n\
sim_<name>.json (geodesic deviation, label drift, settling times, energy error, fluxes, actuator\n\
share, peak torques) and plots (configuration space, q(t), torques, label, power, E(t), deviation)\n\
as SVG and PNG."
    )]
    Simulate {
        /// Design file (TOML).
        #[arg(default_value = DEFAULT_DESIGN)]
        design: PathBuf,
        /// Run only this scenario.
        #[arg(long, value_name = "NAME")]
        scenario: Option<String>,
        /// Output folder (default: out/<design name>_simulate). Replaced atomically.
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Use the exact potential ½ω²r² instead of springs.
        #[arg(long, conflicts_with = "bom")]
        exact: bool,
        /// Use the springs of this bill of materials instead of fitting.
        #[arg(long, value_name = "FILE")]
        bom: Option<PathBuf>,
        /// Use the exact (log-map) label instead of the table (slow).
        #[arg(long)]
        exact_label: bool,
    },
    /// Sensitivity of a fitted design: parasitic springs, manufacturing tolerance, stock rates.
    #[command(
        after_help = "Examples:\n  springfit sweep\n  springfit sweep --shard 1/4 --out shards/1   # on a batch scheduler, one per task\n  springfit sweep --merge shards/1 shards/2 shards/3 shards/4\n\n\
Writes sweep.csv (one row per run), sweep.json (the tables), tolerance.md, plots and, when the\n\
catalogue lists stock rates, bom_stock.csv. A shard writes sweep_shard.json; merging the shards gives the same tables as one run."
    )]
    Sweep {
        /// Design file (TOML).
        #[arg(default_value = DEFAULT_DESIGN)]
        design: PathBuf,
        /// Output folder (default: out/<design name>_sweep, or …_sweep_shard_<i>_of_<N>).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Compute only shard i of N of the runs (1-based), e.g. 3/8.
        #[arg(long, value_name = "i/N", conflicts_with = "merge")]
        shard: Option<String>,
        /// Join the shards in these folders into the tables.
        #[arg(long, value_name = "DIR", num_args = 1..)]
        merge: Vec<PathBuf>,
        /// Override the number of Monte Carlo builds per tolerance level.
        #[arg(long, value_name = "N", allow_negative_numbers = true)]
        builds: Option<usize>,
        /// Override the seed of the builds.
        #[arg(long, value_name = "S", allow_negative_numbers = true)]
        seed: Option<u64>,
    },
    /// Compare fits side by side: histograms on shared bins, box plots and a table.
    #[command(
        after_help = "Examples:\n  springfit compare out/double_pendulum out/double_pendulum_dense out/double_pendulum_workshop --exact\n  springfit compare designs/double_pendulum.toml designs/double_pendulum_workshop.toml\n\n\
Inputs are output folders of `springfit fit` or design files (fitted on the fly). Writes\n\
compare.csv, compare.md and compare.svg/.png (default folder out/compare)."
    )]
    Compare {
        /// Fit output folders or design files.
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        /// Output folder (default: out/compare).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Add the exact potential ½ω²r² of the first input's design as a reference.
        #[arg(long)]
        exact: bool,
    },
    /// The best residual per spring budget, per region size and per spring mass.
    #[command(
        after_help = "Examples:\n  springfit pareto designs/double_pendulum.toml\n  springfit pareto designs/double_pendulum.toml --axis mass\n\n\
Fits the design's catalogue with K = 2 … K_max springs, and with its budget on geodesic balls\n\
from radius 0.5 to the largest valid one. Writes pareto.csv, pareto.md, pareto.svg/.png.\n\
With --axis mass: with its budget and max_spring_mass from the floor to the mass of the fit\n\
without one, each point's parts chosen; writes pareto_mass.csv, .json, .svg/.png."
    )]
    Pareto {
        /// Design file (TOML).
        #[arg(default_value = DEFAULT_DESIGN)]
        design: PathBuf,
        /// Output folder (default: out/<design name>_pareto).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// Largest budget (default: the design's max_elements, at least 16).
        #[arg(long, value_name = "N", allow_negative_numbers = true)]
        k_max: Option<usize>,
        /// Radii of the region-size curve (default: 8 from 0.5, less for small regions, up to the
        /// largest valid radius).
        #[arg(long, value_name = "R,R,…", value_delimiter = ',')]
        radii: Option<Vec<f64>>,
        /// The curves to draw: budget, radius, mass (default: budget,radius).
        #[arg(long, value_name = "AXIS,…", value_delimiter = ',')]
        axis: Option<Vec<AxisArg>>,
        /// Spring-mass budgets of the mass curve in kg, none below the floor (default: 8 evenly in
        /// log from the floor to the mass of the fit without a budget).
        #[arg(long, value_name = "KG,KG,…", value_delimiter = ',')]
        masses: Option<Vec<f64>>,
    },
    /// Export the arm and its springs to MuJoCo (MJCF) to check the design there.
    #[command(
        after_help = "Examples:\n  springfit export --mujoco\n  springfit export designs/double_pendulum.toml --bom out/double_pendulum/bom.csv --mujoco --out out/mj\n\n\
Writes <design name>.xml (bodies, hinge joints, springs as joint stiffness, fixed and spatial\n\
tendons, RK4 at springfit's step), elements.md (exact or callback, per element) and bom.csv (the\n\
springs exported). scripts/verify_mujoco.py runs it in MuJoCo against `springfit simulate`."
    )]
    Export {
        /// Design file (TOML).
        #[arg(default_value = DEFAULT_DESIGN)]
        design: PathBuf,
        /// Use the springs of this bill of materials instead of fitting.
        #[arg(long, value_name = "FILE")]
        bom: Option<PathBuf>,
        /// Write a MuJoCo model (MJCF); the only format so far, so required.
        #[arg(long, required = true)]
        mujoco: bool,
        /// Output folder (default: out/<design name>_mujoco).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
    /// Offsets and trim rates to set on a built arm, from its measured spring rates.
    #[command(after_help = "Example:\n  springfit tune designs/double_pendulum.toml --measured built.csv\n\n\
MEASURED is the fit's bom.csv with a measured_stiffness column added (blank = as designed).\n\
Adjustable offsets put the equilibrium back at q_eq, trim rates restore the Hessian match, then\n\
the residual is made as small as the freedom left allows. Writes bom_tuned.csv, tune.json, tune.md.")]
    Tune {
        /// Design file (TOML).
        design: PathBuf,
        /// The bill of materials with a measured_stiffness column.
        #[arg(long, value_name = "FILE")]
        measured: PathBuf,
        /// Output folder (default: out/<design name>_tune).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
    /// A built arm's spring rates, damping and friction from logged swings (or, with --plan, the
    /// releases to log).
    #[command(
        after_help = "Examples:\n  springfit identify designs/double_pendulum.toml --bom out/double_pendulum/bom.csv --plan\n  springfit identify designs/double_pendulum.toml --bom out/double_pendulum/bom.csv --log swings.csv driven.csv\n\n\
A log is CSV with t, q1…qn (rad, the design's joint order), optionally tau1…taun (N·m) and run.\n\
Writes identify.md, identify.json, identified.csv (the bill with measured_stiffness filled in, for\n\
springfit tune --measured), identify_torque and identify_rates (SVG, PNG) and report.html; with\n\
--plan, plan.md, plan.json, plan_rates and report.html."
    )]
    Identify {
        /// Design file (TOML).
        design: PathBuf,
        /// The bill of materials of the built arm (the fit's bom.csv).
        #[arg(long, value_name = "FILE")]
        bom: PathBuf,
        /// Logs of its motion (CSV), one or more.
        #[arg(long = "log", value_name = "FILE", num_args = 1.., required_unless_present = "plan")]
        logs: Vec<PathBuf>,
        /// Propose releases to log instead (D-optimal), with the standard errors they would give.
        #[arg(long, conflicts_with = "logs")]
        plan: bool,
        /// Output folder (default: out/<design name>_identify, or …_identify_plan).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
    /// A spring for every element of a fitted bill: mechanism, wire, coils, checks, stock parts.
    #[command(
        after_help = "Examples:\n  springfit parts\n  springfit parts designs/double_pendulum.toml --bom out/double_pendulum/bom.csv\n\n\
Fits the design (or reads BOM) and realises every element by EN 13906 within the design's [parts]\n\
envelope: writes parts.csv, parts.md (a request for quotation) and sketch_<id>.svg, and prints the\n\
realised design's residual angles beside the ideal ones. Exit code 1 names the limit no spring meets."
    )]
    Parts {
        /// Design file (TOML).
        #[arg(default_value = DEFAULT_DESIGN)]
        design: PathBuf,
        /// Realise the springs of this bill of materials instead of fitting.
        #[arg(long, value_name = "FILE")]
        bom: Option<PathBuf>,
        /// Output folder (default: out/<design name>_parts).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
    /// Validate a design and report its robot, equilibrium and region.
    #[command(
        after_help = "Examples:\n  springfit check designs/double_pendulum.toml\n  springfit check designs/ur5_lift_elbow.toml --json\n\n\
With --json, prints one JSON object on stdout: dof, joints, q_eq, mass_matrix (rows, at q_eq),\n\
gravity_torque (∂U_g/∂q at q_eq, N·m) and region (the region check), for comparing models."
    )]
    Check {
        /// Design file (TOML).
        design: PathBuf,
        /// Print one JSON object (robot, equilibrium, mass matrix, gravity torque, region check).
        #[arg(long)]
        json: bool,
    },
    /// Write a design to start from: an arm (a URDF and its moving joints, or planar links), an
    /// equilibrium within its limits, a region inside what limits it, ω from gravity, a catalogue.
    #[command(
        after_help = "Examples:\n  springfit init my_arm.toml --urdf robots/panda/panda.urdf --joints panda_joint2,panda_joint4,panda_joint6\n  springfit init three.toml --links \"1.5,1,0.5,0.125;1,0.8,0.4,0.0533;0.5,0.6,0.3,0.015\"\n\n\
Writes the design and <stem>_catalog.toml beside it (never replacing a file) and prints why each\n\
value was chosen; then run `springfit check` and `springfit fit` on it."
    )]
    Init {
        /// The design file to write.
        out: PathBuf,
        /// The robot's URDF file.
        #[arg(long, value_name = "FILE")]
        urdf: Option<PathBuf>,
        /// The URDF joints that move, from the base outwards (comma-separated).
        #[arg(long, value_delimiter = ',', value_name = "NAMES")]
        joints: Vec<String>,
        /// A joint held still at a value: name=rad (repeat for more).
        #[arg(long, value_name = "NAME=RAD")]
        lock: Vec<String>,
        /// A planar arm's links, `mass,length,com,inertia;…` (kg, m, m, kg·m²), or a file of one
        /// link a line.
        #[arg(long, value_name = "LINKS")]
        links: Option<String>,
        /// Gravity (m/s²): 3 numbers in the URDF's base frame (default 0,0,-9.81) or 2 in a
        /// planar arm's plane (default 0,-9.81).
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true, value_name = "X,Y[,Z]")]
        gravity: Option<Vec<f64>>,
        /// The equilibrium (rad, comma-separated); default: the URDF's zero inside the limits,
        /// else their middle (0 for planar links).
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true, value_name = "Q1,Q2,…")]
        q: Option<Vec<f64>>,
    },
    /// Trace the fan of geodesics from the equilibrium, check the region and plot them.
    #[command(after_help = "Example:\n  springfit geodesics designs/double_pendulum.toml --out out/geodesics\n\n\
Writes geodesics.csv (direction, s, q…, q̇…), region.json (valid, largest_radius, reason) and\n\
geodesics.svg/.png (the fan in joint space and the same motions in Cartesian space).")]
    Geodesics {
        /// Design file (TOML).
        #[arg(default_value = DEFAULT_DESIGN)]
        design: PathBuf,
        /// Output folder (default: out/<design name>_geodesics). Replaced atomically.
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
}

/// `pareto --axis` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum AxisArg {
    /// The element budget K = 2 … K_max.
    Budget,
    /// The geodesic-ball radius.
    Radius,
    /// The spring mass (max_spring_mass), each point's parts chosen.
    Mass,
}

/// `--solver` values.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum SolverArg {
    /// Lawson–Hanson non-negative least squares (equalities by weighting).
    Nnls,
    /// Clarabel quadratic program (constraints exact).
    Qp,
}

/// Parses the command line and runs the command.
pub fn run() -> Result<()> {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return Err(usage_error(e)),
    };
    if let Some(t) = cli.threads {
        if t == 0 {
            return Err(Error::Setting { field: "--threads".into(), reason: "must be at least 1".into() }.into());
        }
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let most = springfit::MAX_THREADS_PER_CORE * cores;
        if t > most {
            return Err(Error::Setting {
                field: "--threads".into(),
                reason: format!(
                    "{t} threads on a machine with {cores} cores: at most {most} ({} per core; more only slow the work down)",
                    springfit::MAX_THREADS_PER_CORE
                ),
            }
            .into());
        }
        rayon::ThreadPoolBuilder::new().num_threads(t).build_global()?;
    }
    let edits = if cli.overwrite_edits { Edits::Overwrite } else { Edits::Refuse };
    let session = Session { progress: progress::Progress::new(cli.quiet, cli.progress), edits };
    match cli.command {
        Command::Check { design, json } => check::run(&design, json, &session.progress),
        Command::Init { out, urdf, joints, lock, links, gravity, q } => {
            init::run(init::InitArgs { out, urdf, joints, lock, links, gravity, q }, &session.progress)
        }
        Command::Compare { inputs, out, exact } => compare::compare(&inputs, out, exact, &session),
        Command::Pareto { design, out, k_max, radii, axis, masses } => {
            compare::pareto(compare::ParetoArgs { path: design, out, k_max, radii, axis, masses }, &session)
        }
        Command::Sweep { design, out, shard, merge, builds, seed } => {
            sweep::run(sweep::SweepArgs { design, out, shard, merge, builds, seed }, &session)
        }
        Command::Simulate { design, scenario, out, exact, bom, exact_label } => {
            simulate::run(simulate::SimArgs { design, scenario, out, exact, bom, exact_label }, &session)
        }
        Command::Export { design, bom, mujoco: _, out } => {
            export::run(export::ExportArgs { design, bom, out }, &session)
        }
        Command::Geodesics { design, out } => geodesics::run(&design, out, &session),
        Command::Tune { design, measured, out } => tune::run(&design, &measured, out, &session),
        Command::Identify { design, bom, logs, plan, out } => {
            identify::run(identify::IdentifyArgs { design, bom, logs, plan, out }, &session)
        }
        Command::Parts { design, bom, out } => parts::run(&design, bom, out, &session),
        Command::Fit { design, out, exact, solver, max_elements } => {
            let solver = solver.map(|s| match s {
                SolverArg::Nnls => SolverKind::Nnls,
                SolverArg::Qp => SolverKind::Qp,
            });
            fit::run(fit::FitArgs { design, out, exact, solver, max_elements }, &session)
        }
    }
}

/// What every command gets: where to report progress, and what the user allows it to replace.
pub struct Session {
    pub progress: progress::Progress,
    /// What to do with output files the user edited since springfit wrote them (`--overwrite-edits`).
    pub edits: Edits,
}

impl Session {
    /// The plan of `command` writing files named like `patterns`, under the user's edits policy.
    pub fn plan<S: Into<String>>(&self, command: &str, patterns: impl IntoIterator<Item = S>) -> Plan {
        Plan::new(command, patterns).with_edits(self.edits)
    }

    /// The plan of `command` on `design` (see [`Plan::for_design`]): another design's results
    /// are never replaced.
    pub fn plan_for<S: Into<String>>(
        &self,
        design: &Design,
        command: &str,
        patterns: impl IntoIterator<Item = S>,
    ) -> Plan {
        self.plan(command, patterns).for_design(design)
    }
}

/// Loads a design and validates everything the commands read from it (the catalogue, the
/// scenarios, the sweep settings) before any work; prints the warnings on stderr.
pub fn load_design(path: &Path, progress: &progress::Progress) -> springfit::Result<(Design, Validated)> {
    let design = Design::load(path)?;
    let validated = springfit::design::validate::validate(&design)?;
    for w in &validated.warnings {
        progress.warn(w);
    }
    Ok((design, validated))
}

/// An error of a job on `design`: errors that carry no file of their own (infeasible,
/// numerical) are prefixed with the design's path.
pub fn in_design(design: &Design, e: Error) -> anyhow::Error {
    match e {
        Error::Infeasible { .. } | Error::Numerical { .. } => {
            anyhow::Error::new(e).context(design.path.display().to_string())
        }
        other => other.into(),
    }
}

/// A job's error about its argument `name` (as the library and the Python package name it:
/// `scenario`, `radii[2]`) named as the command line's option `flag` (`--scenario`, `--radii[2]`).
pub fn flag(e: Error, name: &str, flag: &str) -> Error {
    match e {
        Error::Setting { field, reason } if field == name || field.starts_with(&format!("{name}[")) => {
            Error::Setting { field: field.replacen(name, flag, 1), reason }
        }
        other => other,
    }
}

/// A command-line error as one line, like every other error (help and version are printed as
/// clap renders them and exit as clap decides).
fn usage_error(e: clap::Error) -> anyhow::Error {
    use clap::error::ErrorKind as K;
    if matches!(e.kind(), K::DisplayHelp | K::DisplayVersion | K::DisplayHelpOnMissingArgumentOrSubcommand) {
        e.exit();
    }
    let text = e.render().to_string();
    let lines: Vec<&str> = text.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
    let mut first =
        lines.first().copied().unwrap_or("invalid command line").trim_start_matches("error:").trim().to_string();
    // "the following required arguments were not provided:" lists them on the next lines.
    if first.ends_with(':') {
        let listed: Vec<&str> =
            lines[1..].iter().copied().take_while(|l| l.starts_with('-') || l.starts_with('<')).collect();
        first = format!("{} {}", first, listed.join(", "));
    }
    let tip = lines.iter().find(|l| l.starts_with("tip:")).map(|t| format!("; {t}")).unwrap_or_default();
    let first = first
        .replace("invalid digit found in string", "expected a whole number")
        .replace("invalid float literal", "expected a number");
    anyhow::anyhow!("{first}{tip} (`springfit --help` lists the commands and options)")
}

/// The error as one line: the library's message with its causes.
pub fn describe(e: &anyhow::Error) -> String {
    format!("{e:#}")
}

/// Exit code: 2 for bad input or usage, 1 when the design cannot be met.
pub fn exit_code(e: &anyhow::Error) -> u8 {
    match e.downcast_ref::<Error>().map(Error::kind) {
        Some(ErrorKind::NotMet) => 1,
        _ => 2,
    }
}
