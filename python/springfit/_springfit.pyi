"""Type stubs of the extension module `springfit._springfit` (re-exported by `springfit`).

Arrays are float64 NumPy arrays. A function of points takes one point, shape (n,), or N points,
shape (N, n), and returns the matching shape: one result, or N results stacked on axis 0.
"""

from os import PathLike
from typing import Any, Callable, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

ArrayLike = npt.ArrayLike
Array = npt.NDArray[np.float64]
Progress = Optional[Callable[[str], Any]]
Springs = Union["Fit", "Potential", str, PathLike]

__version__: str

class Error(Exception):
    """Every error springfit raises. `str(e)` is the command line's message (after
    `springfit: error: `); `file` and `field` are what it names, or None."""

    file: Optional[str]
    field: Optional[str]
    line: Optional[int]
    column: Optional[int]

class BadInputError(Error):
    """The input is wrong: fix it and call again (the CLI's exit code 2)."""

class NotMetError(Error):
    """The input is well formed but the design cannot be met (exit code 1)."""

class FileError(BadInputError):
    """A file could not be read or written."""

class ParseError(BadInputError):
    """A TOML or CSV file does not parse, or has an unknown key or a value of the wrong type."""

class InvalidError(BadInputError):
    """A value in a file parsed but is not acceptable."""

class SettingError(BadInputError):
    """An argument is not acceptable: a wrong array shape, NaN, an unknown override key."""

class PlotError(BadInputError):
    """A plot could not be drawn or written."""

class InfeasibleError(NotMetError):
    """The fit's constraints cannot all be met."""

class NumericalError(NotMetError):
    """A numerical method failed (a log map that did not converge, a singular mass matrix)."""

class NoPartError(NotMetError):
    """An element of the fitted bill has no spring within the design's [parts] envelope."""

class Design:
    """A validated design: robot, equilibrium, region and every settings section."""

    @staticmethod
    def load(path: Union[str, PathLike], **overrides: Any) -> "Design":
        """Reads and validates a design file; keywords replace keys of `[fit]` or `[region]`
        (`max_elements=8`, `radius=1.5`; `kind=` replaces the whole region)."""
    @staticmethod
    def from_toml(text: str, path: Optional[Union[str, PathLike]] = None, **overrides: Any) -> "Design":
        """A design from the text of a design file; `path` names it in messages and anchors its
        relative paths (default `design.toml` in the working directory)."""
    @property
    def name(self) -> str: ...
    @property
    def path(self) -> str: ...
    @property
    def dof(self) -> int:
        """Number of joints n."""
    @property
    def joints(self) -> list[str]: ...
    @property
    def q_eq(self) -> Array:
        """The equilibrium, rad, shape (n,)."""
    @property
    def warnings(self) -> list[str]:
        """What the command line prints as `springfit: warning: …` for this design."""
    @property
    def scenarios(self) -> list[str]:
        """Names of the design's `[[scenario]]` tables."""
    @property
    def simulate_settings(self) -> dict[str, Any]:
        """The `[simulate]` settings (`rate`: the RK4 step rate, Hz)."""
    @property
    def controllers(self) -> dict[str, Any]:
        """The `[controllers]` settings."""
    def check(self, strict: bool = True) -> dict[str, Any]:
        """`springfit check --json`: dof, joints, q_eq, mass_matrix, gravity_torque (arrays) and
        region (dict). With `strict`, an invalid region raises the command's error."""
    def mass_matrix(self, q: ArrayLike) -> Array:
        """M(q): (n, n) or (N, n, n)."""
    def gravity_potential(self, q: ArrayLike) -> Array:
        """U_g(q), J: () or (N,)."""
    def gravity_gradient(self, q: ArrayLike) -> Array:
        """∂U_g/∂q, N·m: (n,) or (N, n)."""
    def acceleration(self, q: ArrayLike, qdot: ArrayLike, tau: ArrayLike) -> Array:
        """q̈ of M q̈ + C(q, q̇) q̇ = τ for the total joint torque τ: (n,) or (N, n)."""
    def exp(self, v: ArrayLike) -> Array:
        """exp(v), the geodesic from q_eq with initial velocity v at arc length |v|_M."""
    def log(self, q: ArrayLike) -> Array:
        """log(q): the v with exp(v) = q (Newton shooting, each point on its own)."""
    def distance(self, q: ArrayLike) -> Array:
        """r(q) = |log(q)|_M, the Riemannian distance from q_eq: () or (N,)."""
    def label(self, q: ArrayLike) -> Array:
        """The mode label θ(q) = 2·atan2(v₂, v₁), v = log(q) (two joints): () or (N,)."""
    def label_gradient(self, q: ArrayLike) -> Array:
        """∂θ/∂q (two joints): (2,) or (N, 2)."""
    def fit(
        self,
        exact: bool = False,
        solver: Optional[str] = None,
        max_elements: Optional[int] = None,
        progress: Progress = None,
    ) -> "Fit":
        """`springfit fit`: the springs from the catalogue (and the as-built builds), or the exact
        ½ω²r² with `exact`. Releases the GIL; `progress(stage)` at each stage."""
    def simulate(
        self,
        scenario: Optional[str] = None,
        springs: Optional[Springs] = None,
        exact: bool = False,
        exact_label: bool = False,
        progress: Progress = None,
    ) -> "Simulation":
        """`springfit simulate`: the scenarios (or the one named) in closed loop."""
    def sweep(
        self,
        builds: Optional[int] = None,
        seed: Optional[int] = None,
        progress: Progress = None,
    ) -> "Sweep":
        """`springfit sweep` in one process (no shards); `builds`, `seed` as the options."""
    def export_mujoco(
        self,
        folder: Union[str, PathLike],
        springs: Optional[Union["Fit", str, PathLike]] = None,
        overwrite_edits: bool = False,
        progress: Progress = None,
    ) -> str:
        """`springfit export --mujoco` into `folder`; returns the model file's path."""
    def tune(self, measured: Union[str, PathLike]) -> dict[str, Any]:
        """`springfit tune`: tune.json as a dict, with `bom_tuned_csv`."""

class Fit:
    """A fit (or the exact reference) with its as-built figures."""

    @property
    def bom(self) -> list[dict[str, Any]]:
        """One dict per row of bom.csv, keyed by its columns (numbers float, blanks None)."""
    @property
    def bom_array(self) -> np.ndarray:
        """bom.csv as a structured array (float64 columns where every entry is a number)."""
    @property
    def bom_csv(self) -> str:
        """The text of bom.csv, byte for byte the command's."""
    @property
    def used(self) -> int:
        """Elements used (a cam counts as one)."""
    @property
    def residuals(self) -> Array:
        """Residual angles on the held-out geodesics, degrees, (N,)."""
    @property
    def residual_samples(self) -> dict[str, np.ndarray]:
        """The columns of residuals.csv: direction (N,), s (N,), q (N, n), angle_deg (N,)."""
    @property
    def summary(self) -> dict[str, Any]:
        """summary.json as a dict."""
    @property
    def as_built(self) -> Optional[dict[str, Any]]:
        """The Monte Carlo builds' figures, or None."""
    @property
    def potential(self) -> "Potential":
        """The fitted springs' potential U_e."""
    def write(self, folder: Union[str, PathLike], overwrite_edits: bool = False) -> str:
        """Writes every file `springfit fit` writes into `folder`, through its output folder."""

class Potential:
    """An elastic potential U_e: springs or the exact ½ω²r² − U_g."""

    @staticmethod
    def from_bom(design: Design, path: Union[str, PathLike]) -> "Potential":
        """The springs of a bom.csv."""
    @staticmethod
    def exact(design: Design, omega: Optional[float] = None) -> "Potential":
        """½ω²r² − U_g (ω from `[fit] frequency` unless given)."""
    def __len__(self) -> int: ...
    def value(self, q: ArrayLike) -> Array:
        """U_e(q), J: () or (N,)."""
    def gradient(self, q: ArrayLike) -> Array:
        """∂U_e/∂q, N·m: (n,) or (N, n)."""
    def hessian(self, q: ArrayLike) -> Array:
        """∇²U_e: (n, n) or (N, n, n)."""

class ControlOutput:
    """The controller's torques at one state and what it saw there."""

    @property
    def tau(self) -> Array:
        """τ_θ + τ_E + τ_comp, the motor torques, N·m, (n,)."""
    @property
    def mode(self) -> Array:
        """τ_θ (blend included)."""
    @property
    def energy_torque(self) -> Array:
        """τ_E or τ_nD."""
    @property
    def compensation(self) -> Array:
        """D q̇ fed forward."""
    label: float
    label_target: float
    in_ball: bool
    energy: float
    weight: float
    saturated: bool
    """Whether [controllers] max_torque scaled the torques down at this call."""
    saturation: tuple[float, float]
    """The factors applied on τ_θ and on τ_E + τ_comp (1, 1 when the torques fitted)."""
    demand: float
    """Largest |τ_c,i| over the joints as the laws asked, before saturation, N·m."""

class Controller:
    """Mode selection and energy regulation exactly as `springfit simulate` runs them."""

    def __init__(
        self,
        design: Design,
        springs: Springs,
        scenario: Optional[str] = None,
        run: int = 0,
        label: Optional[str] = None,
        damping: Optional[ArrayLike] = None,
    ) -> None:
        """With `scenario`, its run `run`'s θ_d / E_d schedules and damping; `label` "auto", "table" or
        "exact" (default: the design's); `damping` (n,) the D the compensation feeds forward."""
    def torque(self, q: ArrayLike, qdot: ArrayLike, t: float) -> ControlOutput:
        """The motor torques at (q, q̇, t)."""
    def label(self, q: ArrayLike) -> float:
        """The label at q (NaN inside the ε-ball)."""
    theta_d: Optional[float]
    """θ_d in force at the last call's time; set a number to hold that mode, None for off."""
    energy_target: Optional[float]
    """E_d in force, J; set a number to hold it, None for off."""
    energy_law: Optional[str]
    """"energy" (τ_E) or "negative_damping" (τ_nD)."""
    compensate_damping: bool
    def set_mode_direction(self, direction: ArrayLike) -> None:
        """Holds the mode of the joint velocity `direction` (any number of joints)."""
    @property
    def damping(self) -> Array: ...
    @property
    def start(self) -> Optional[tuple[Array, Array]]:
        """The scenario run's start (q0, qdot0)."""
    @property
    def duration(self) -> Optional[float]: ...
    @property
    def mode_steps(self) -> list[float]:
        """Start times of the θ_d schedule, s."""
    @property
    def label_error_deg(self) -> Optional[float]:
        """The table's largest error against the exact label, degrees (None: exact label)."""
    @property
    def label_rejected_error_deg(self) -> Optional[float]:
        """The error of the fitted log map `auto` rejected for the exact one, degrees (None: none rejected)."""
    @property
    def label_note(self) -> Optional[str]:
        """Why the label is exact when `auto` rejected a fit, e.g. "fitted log map error 6.61° > 0.1°: exact log map used"."""
    @property
    def settings(self) -> dict[str, Any]:
        """The `[controllers]` gains in use."""

class Simulation:
    """The outcome of `Design.simulate()`."""

    @property
    def scenarios(self) -> list[str]: ...
    def summary(self, name: str) -> dict[str, Any]:
        """sim_<name>.json as a dict."""
    def runs(self, name: str) -> list[dict[str, Any]]:
        """Each run: name, t, q, qdot, tau (per source), energy, label, label_target,
        geodesic_deviation, in_ball, metrics."""
    def write(self, folder: Union[str, PathLike], overwrite_edits: bool = False) -> str:
        """Writes what `springfit simulate` writes into `folder`."""

class Sweep:
    """The outcome of `Design.sweep()`."""

    @property
    def tables(self) -> dict[str, Any]:
        """sweep.json as a dict."""
    @property
    def items(self) -> list[dict[str, Any]]:
        """Every item's result (the rows of sweep.csv)."""
    def write(self, folder: Union[str, PathLike], overwrite_edits: bool = False) -> str:
        """Writes what `springfit sweep` writes into `folder`."""

class Comparison:
    """Fits side by side, as `springfit compare` sets them."""

    @property
    def table(self) -> list[dict[str, Any]]:
        """compare.csv as records, one per fit."""
    @property
    def csv(self) -> str:
        """The text of compare.csv."""
    def write(self, folder: Union[str, PathLike], overwrite_edits: bool = False) -> str:
        """Writes what `springfit compare` writes into `folder`."""

def compare(inputs: Sequence[Union[Fit, str, PathLike]], exact: Optional[Design] = None) -> Comparison:
    """`springfit compare`: each input a Fit or a fit output folder; `exact` adds the exact
    potential of that design as a reference."""

def settling_times(
    t: Sequence[float],
    label: Sequence[float],
    label_target: Sequence[float],
    in_ball: Sequence[bool],
    starts: Sequence[float],
    duration: float,
    two_joints: bool = True,
) -> list[Optional[float]]:
    """Seconds from each mode step until the label stays within 3° of its target (None: never),
    the rule of sim_<name>.json's settling_s."""
