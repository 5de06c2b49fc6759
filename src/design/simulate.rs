//! `[simulate]`: how a closed-loop run is integrated and which mode label it uses.

use serde::{Deserialize, Serialize};

use crate::numerics::ode::OdeSettings;

/// Time integration scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Integrator {
    /// Classical Runge–Kutta with a fixed step 1/rate.
    #[default]
    Rk4,
    /// Dormand–Prince 5(4) with error control on (q, q̇).
    Adaptive,
}

/// Which label the mode controller uses.
///
/// The default, `auto`, is the table wherever it is measured to be good: for two joints the
/// grid table (as `table`), for three or more the fitted log map when its largest error against
/// the exact label on held-out geodesics is at most [`auto_label_bound`] ([`AUTO_LABEL_MAX_ERROR_DEG`]
/// up to five joints, [`AUTO_LOOP_LABEL_MAX_ERROR_DEG`] from six, with cells), and the exact
/// log map otherwise (the outputs' `label` then says `exact`). Why a bound: the fitted label
/// costs microseconds instead of the exact one's ~160 µs per call, but a region close to its
/// conjugate locus bends the log map more than a polynomial of the affordable degree follows,
/// and a label off by a sizeable fraction of the settling band (3°) would move what the mode
/// controller settles on. `table` takes the table whatever its error (reported), `exact` never.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum LabelKind {
    /// `table` where its measured error is within [`auto_label_bound`], else `exact`.
    #[default]
    Auto,
    /// The log map tabulated on a grid (two joints) or fitted by a polynomial (three or more);
    /// its error is measured and reported.
    Table,
    /// Newton shooting at every evaluation (slow; any number of joints).
    Exact,
}

/// The largest label error, degrees, at which `label = "auto"` takes the fitted label of three
/// to five joints: a thirtieth of the 3° band a mode step settles within.
pub const AUTO_LABEL_MAX_ERROR_DEG: f64 = 0.1;

/// From this many joints `label = "auto"` also builds the log map fitted by cells where the one
/// polynomial misses, and takes the fit within [`AUTO_LOOP_LABEL_MAX_ERROR_DEG`].
pub const AUTO_CELLS_FROM_JOINTS: usize = 6;

/// The largest label error, degrees, at which `label = "auto"` takes the fitted label from
/// [`AUTO_CELLS_FROM_JOINTS`] joints: half the 3° settling band. Why: the mode error the run
/// judges is the controller's error in its own label, and the true one differs from it by at
/// most the label's error, so with half the band each a step that settles by the fitted label
/// settles by the exact one. Measured in the loop (`docs/simulation.md`): on `ur5_six` a switch
/// through five modes with the cells (1.00° on the check fan) settled every step by the exact
/// label, the label along the run within 0.67° of the exact one. Fewer joints keep the 0.1° rule
/// (their loop was not checked this way; `planar_three`'s polynomial, 0.84°, would move), and
/// from six joints the exact label costs about 3 ms per call, 150× the 20 µs target.
pub const AUTO_LOOP_LABEL_MAX_ERROR_DEG: f64 = 1.5;

/// The bound `label = "auto"` holds a fitted label of an `n`-joint arm to, degrees.
pub fn auto_label_bound(n: usize) -> f64 {
    if n >= AUTO_CELLS_FROM_JOINTS { AUTO_LOOP_LABEL_MAX_ERROR_DEG } else { AUTO_LABEL_MAX_ERROR_DEG }
}

/// `[simulate]`: integration settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimSettings {
    /// Steps per second of RK4 (and outputs are never denser than this).
    pub rate: f64,
    /// `rk4` or `adaptive`.
    pub integrator: Integrator,
    /// Tolerances of the adaptive integrator.
    pub ode: OdeSettings,
    /// `auto` (default), `table` or `exact`.
    pub label: LabelKind,
    /// Nodes per axis of the label table.
    pub table_nodes: usize,
    /// Time between output samples, s.
    pub output_interval: f64,
}

impl Default for SimSettings {
    fn default() -> Self {
        SimSettings {
            rate: 1000.0,
            integrator: Integrator::Rk4,
            ode: OdeSettings { rtol: 1e-8, atol: 1e-10, ..OdeSettings::default() },
            label: LabelKind::Auto,
            table_nodes: 121,
            output_interval: 0.01,
        }
    }
}

impl SimSettings {
    /// Checks the settings, naming the bad field.
    pub fn validate(&self) -> Result<(), (String, String)> {
        if !(self.rate.is_finite() && self.rate >= 10.0 && self.rate <= 1e6) {
            return Err(("simulate.rate".into(), format!("must be 10 to 1e6 Hz, got {}", self.rate)));
        }
        if !(self.output_interval.is_finite() && self.output_interval > 0.0) {
            return Err(("simulate.output_interval".into(), "must be positive".into()));
        }
        if self.table_nodes < 8 || self.table_nodes > 2000 {
            return Err(("simulate.table_nodes".into(), "must be 8 to 2000".into()));
        }
        self.ode.validate("simulate.ode")
    }
}
