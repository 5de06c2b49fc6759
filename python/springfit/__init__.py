"""springfit from Python: spring layouts for robot arms whose strict normal modes fill a region.

The package is the springfit library (Rust) itself, built with maturin and PyO3: a design file
loaded here is validated as the command line validates it, a fit here is the command's fit
(`Fit.write(folder)` writes the same files), and `Controller.torque` is the code
`springfit simulate` calls at every stage of its integrator. Every error is a `springfit.Error`
whose message is the command line's.

    import springfit
    design = springfit.Design.load("designs/double_pendulum.toml")
    fit = design.fit()
    fit.write("out/double_pendulum")          # bom.csv, summary.json, plots, …
    controller = springfit.Controller(design, fit, scenario="switch")
    out = controller.torque(q, qdot, t)       # out.tau, out.label, out.energy

See docs/python.md in the repository for the whole API and the examples.
"""

from ._springfit import (
    BadInputError,
    Comparison,
    ControlOutput,
    Controller,
    Design,
    Error,
    FileError,
    Fit,
    InfeasibleError,
    InvalidError,
    NoPartError,
    NotMetError,
    NumericalError,
    ParseError,
    PlotError,
    Potential,
    SettingError,
    Simulation,
    Sweep,
    __version__,
    compare,
    settling_times,
)

__all__ = [
    "BadInputError",
    "Comparison",
    "ControlOutput",
    "Controller",
    "Design",
    "Error",
    "FileError",
    "Fit",
    "InfeasibleError",
    "InvalidError",
    "NotMetError",
    "NumericalError",
    "NoPartError",
    "ParseError",
    "PlotError",
    "Potential",
    "SettingError",
    "Simulation",
    "Sweep",
    "__version__",
    "compare",
    "settling_times",
]
