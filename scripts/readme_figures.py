#!/usr/bin/env python3
"""Regenerate every figure README.md and docs/*.md quote from springfit's own output files.

README.md and every page under docs/ mark each figure they quote:

    inline:  <!-- fig:NAME -->0.329°<!-- /fig -->
    block:   <!-- block:NAME -->            (a whole fenced block, e.g. what a command prints)
             ```text
             ...
             ```
             <!-- /block -->

This script builds target/release/springfit (unless --no-build), runs the commands behind the
figures (see JOBS below: every command writes into a folder under --out, default out/readme),
reads the JSON and CSV files those commands write and rewrites the text between the markers.
Only the quote of what `springfit fit` prints is taken from stdout, because that quote *is*
the printed text.

    python3 scripts/readme_figures.py                 # rewrite README.md and docs/*.md in place
    python3 scripts/readme_figures.py --check         # exit 1 and list the figures that differ, with their files
    python3 scripts/readme_figures.py --threads 2     # passed to springfit (results do not depend on it)
    python3 scripts/readme_figures.py --reuse         # reread the last run's files, run nothing
    python3 scripts/readme_figures.py --files README.md docs/guide.md   # only these files

Python 3.8+ standard library only. Every figure NAME marked in the files (README.md and
docs/*.md unless --files names others) must be known here, and every figure known here must be
marked in at least one of them, so that neither can drift silently: a figure moved from one page
to another keeps its marker and stays generated. A figure may be quoted in more than one file;
each quote is rewritten.
"""

import argparse
import csv
import json
import math
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# --------------------------------------------------------------------------------------------
# Commands behind the figures. Each job is `springfit <args…> --out <out>/<folder>`; `{design}`
# names a design file under designs/, `{probe:NAME}` a copy of designs/NAME.toml with a longer
# region-check probe (see LONG_PROBE_FACTOR).
# --------------------------------------------------------------------------------------------

LONG_PROBE_FACTOR = 5.0

JOBS = {
    "fit.dp": ["fit", "designs/double_pendulum.toml"],
    "fit.dense": ["fit", "designs/double_pendulum_dense.toml"],
    "fit.workshop": ["fit", "designs/double_pendulum_workshop.toml"],
    "fit.window": ["fit", "designs/double_pendulum_paper_window.toml"],
    "fit.triple": ["fit", "designs/triple_pendulum.toml"],
    "fit.dense_robust": ["fit", "designs/double_pendulum_dense_robust.toml"],
    "fit.window_cams": ["fit", "designs/double_pendulum_paper_window_cams.toml"],
    "fit.window_built": ["fit", "designs/double_pendulum_paper_window_built.toml"],
    "fit.cams4": ["fit", "designs/double_pendulum_cams4.toml"],
    "fit.cams": ["fit", "designs/double_pendulum_cams.toml"],
    "fit.dp_trim": ["fit", "designs/double_pendulum_trim.toml"],
    "fit.dp_trim_tol10": ["fit", "{tolerance:double_pendulum_trim:0.1}"],
    "fit.dp_nominal": ["fit", "{tolerance:double_pendulum:none}"],
    "fit.dp_nominal10": ["fit", "{tolerance:double_pendulum:none}", "--max-elements", "10"],
    "fit.dp_nominal8": ["fit", "{tolerance:double_pendulum:none}", "--max-elements", "8"],
    "sim.dp": ["simulate", "designs/double_pendulum.toml"],
    "sim.dp_exact": ["simulate", "designs/double_pendulum.toml", "--exact", "--scenario", "free"],
    "sim.dense": ["simulate", "designs/double_pendulum_dense.toml", "--scenario", "free"],
    "sweep.dp": ["sweep", "designs/double_pendulum.toml"],
    "pareto.dp": ["pareto", "designs/double_pendulum.toml", "--radii", "0.5,2,3.5"],
    "pareto.dp_mass": ["pareto", "designs/double_pendulum.toml", "--axis", "mass"],
    "geo.dp": ["geodesics", "designs/double_pendulum.toml"],
    "geo.triple": ["geodesics", "designs/triple_pendulum.toml"],
    "geo.dp_long": ["geodesics", "{probe:double_pendulum}"],
    "geo.straight_long": ["geodesics", "{probe:double_pendulum_straight}"],
    "geo.folded_long": ["geodesics", "{probe:double_pendulum_folded}"],
    "sweep.dense_robust": ["sweep", "designs/double_pendulum_dense_robust.toml"],
    # The paper's window: springs, cams, the exact potential, side by side.
    "compare.window": ["compare", "{dir:fit.window}", "{dir:fit.window_cams}", "{dir:fit.window_built}", "--exact"],
    # MuJoCo: export the fitted springs, simulate the same springs' free releases, compare.
    "export.dp": ["export", "--bom", "{bom:fit.dp}", "--mujoco"],
    "free.dp": ["simulate", "--bom", "{bom:fit.dp}", "--scenario", "free"],
    "export.dense": ["export", "designs/double_pendulum_dense.toml", "--bom", "{bom:fit.dense}", "--mujoco"],
    "free.dense": ["simulate", "designs/double_pendulum_dense.toml", "--bom", "{bom:fit.dense}", "--scenario", "free"],
    # The UR5 from its URDF.
    "check.ur5": ["check", "designs/ur5_lift_elbow.toml", "--json"],
    "fit.ur5": ["fit", "designs/ur5_lift_elbow.toml"],
    "sim.ur5": ["simulate", "designs/ur5_lift_elbow.toml", "--scenario", "free"],
    "sweep.ur5": ["sweep", "designs/ur5_lift_elbow.toml"],
    "check.ur5_3": ["check", "designs/ur5_pan_lift_elbow.toml", "--json"],
    "fit.ur5_3": ["fit", "designs/ur5_pan_lift_elbow.toml"],
    "fit.ur5_3_dense": ["fit", "designs/ur5_pan_lift_elbow.toml", "--max-elements", "0"],
    "sim.ur5_3_dense": ["simulate", "designs/ur5_pan_lift_elbow.toml", "--bom", "{bom:fit.ur5_3_dense}", "--scenario", "free"],
    "sweep.ur5_3": ["sweep", "designs/ur5_pan_lift_elbow.toml"],
    "export.ur5": ["export", "designs/ur5_lift_elbow.toml", "--bom", "{bom:fit.ur5}", "--mujoco"],
    "free.ur5": ["simulate", "designs/ur5_lift_elbow.toml", "--bom", "{bom:fit.ur5}", "--scenario", "free"],
    "export.ur5_3": ["export", "designs/ur5_pan_lift_elbow.toml", "--bom", "{bom:fit.ur5_3}", "--mujoco"],
    "free.ur5_3": ["simulate", "designs/ur5_pan_lift_elbow.toml", "--bom", "{bom:fit.ur5_3}", "--scenario", "free"],
}

# Jobs that write no folder (`check` prints its report): run without --out, stdout kept.
NO_OUT = ("check",)


# --------------------------------------------------------------------------------------------
# Formatting: three significant figures unless a figure says otherwise; a real minus sign.
# --------------------------------------------------------------------------------------------


def sig(x, n=3):
    """x with n significant figures, in fixed notation."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    if x == 0:
        return "0"
    digits = max(n - 1 - math.floor(math.log10(abs(x))), 0)
    text = f"{round(x, digits):.{digits}f}"
    return text.replace("-", "−")


def deg(x, n=3):
    return sig(x, n) + "°"


def pct(fraction, n=3):
    return sig(100.0 * fraction, n) + " %"


def signed_pct(fraction, n=2):
    """A signed percentage with n significant figures: +0.03 %, −2.7 %."""
    x = 100.0 * fraction
    text = sig(abs(x), n)
    return ("+" if x >= 0 else "−") + text + " %"


def radius(x):
    return f"{x:.4g}"


# --------------------------------------------------------------------------------------------
# Running springfit.
# --------------------------------------------------------------------------------------------


class Runner:
    def __init__(self, binary, out, threads, verbose, reuse=False):
        self.binary = binary
        self.out = out
        self.threads = threads
        self.verbose = verbose
        self.reuse = reuse
        self.done = {}
        self.timings = {}

    def probe_copy(self, name):
        """designs/NAME.toml with `[geodesics] probe_factor = LONG_PROBE_FACTOR`, written under
        the scratch folder; a relative catalogue path is made absolute."""
        src = ROOT / "designs" / f"{name}.toml"
        text = src.read_text(encoding="utf-8")
        if re.search(r"^\s*\[geodesics\]", text, re.M):
            sys.exit(f"readme_figures: {src} already has [geodesics]; teach probe_copy to edit it")

        def absolute(m):
            path = (src.parent / m.group(2)).resolve()
            return f'{m.group(1)}"{path.as_posix()}"'

        text = re.sub(r'^(\s*catalog\s*=\s*)"([^"]*)"', absolute, text, flags=re.M)
        # A top-level table must come before the first [[scenario]]/[sweep] etc. only by TOML
        # rules for dotted keys; a new [geodesics] table may go anywhere, so append it.
        text += f"\n[geodesics]\nprobe_factor = {LONG_PROBE_FACTOR}\n"
        dst = self.out / "designs" / f"{name}_long_probe.toml"
        dst.parent.mkdir(parents=True, exist_ok=True)
        dst.write_text(text, encoding="utf-8")
        return str(dst)

    def tolerance_copy(self, name, value):
        """designs/NAME.toml with its `[fit] tolerance` line set to VALUE (`none` or a fraction),
        written under the scratch folder; a relative catalogue path is made absolute."""
        src = ROOT / "designs" / f"{name}.toml"
        text = src.read_text(encoding="utf-8")
        literal = '"none"' if value == "none" else value
        text, n = re.subn(r"^tolerance = [^\n]*$", f"tolerance = {literal}", text, count=1, flags=re.M)
        if n != 1:
            sys.exit(f"readme_figures: {src} has no `tolerance = …` line in [fit] to change")
        text = re.sub(
            r'^(\s*catalog\s*=\s*)"([^"]*)"',
            lambda m: f'{m.group(1)}"{(src.parent / m.group(2)).resolve().as_posix()}"',
            text,
            flags=re.M,
        )
        dst = self.out / "designs" / f"{name}_tolerance_{value}.toml"
        dst.parent.mkdir(parents=True, exist_ok=True)
        dst.write_text(text, encoding="utf-8")
        return str(dst)

    def run(self, job):
        """Runs a job once; returns (output folder, stdout)."""
        if job in self.done:
            return self.done[job]
        args = []
        for a in JOBS[job]:
            m = re.fullmatch(r"\{probe:(\w+)\}", a)
            t = re.fullmatch(r"\{tolerance:(\w+):([\w.]+)\}", a)
            b = re.fullmatch(r"\{bom:([\w.]+)\}", a)
            d = re.fullmatch(r"\{dir:([\w.]+)\}", a)
            if d:
                # The output folder of another job (that job runs first).
                args.append(str(self.folder(d.group(1))))
                continue
            if b:
                # The bill of materials another job wrote (that job runs first).
                args.append(str(self.folder(b.group(1)) / "bom.csv"))
                continue
            args.append(self.probe_copy(m.group(1)) if m else self.tolerance_copy(*t.groups()) if t else a)
        folder = self.out / job.replace(".", "_")
        saved = self.out / (job.replace(".", "_") + ".stdout")
        if self.reuse and (folder.is_dir() or JOBS[job][0] in NO_OUT) and saved.is_file():
            self.done[job] = (folder, saved.read_text(encoding="utf-8"))
            return self.done[job]
        cmd = [str(self.binary)]
        if self.threads:
            cmd += ["--threads", str(self.threads)]
        cmd += args if JOBS[job][0] in NO_OUT else args + ["--out", str(folder)]
        shown = " ".join(["springfit"] + cmd[1:])
        if self.verbose:
            print(f"$ {shown}", file=sys.stderr, flush=True)
        t0 = time.monotonic()
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
        self.timings[job] = time.monotonic() - t0
        if proc.returncode != 0:
            sys.stderr.write(proc.stdout + proc.stderr)
            sys.exit(f"readme_figures: `{shown}` failed with exit code {proc.returncode}")
        saved.write_text(proc.stdout, encoding="utf-8")
        self.done[job] = (folder, proc.stdout)
        return self.done[job]

    def folder(self, job):
        return self.run(job)[0]

    def verify_mujoco(self, key):
        """scripts/verify_mujoco.py on the model of job `export.KEY` and the free releases of job
        `free.KEY` (the same bill of materials); returns its stdout."""
        if ("verify", key) in self.done:
            return self.done[("verify", key)]
        export, free = self.folder(f"export.{key}"), self.folder(f"free.{key}")
        saved = self.out / f"verify_{key}.stdout"
        if not (self.reuse and saved.is_file()):
            model = next(export.glob("*.xml"))
            cmd = [sys.executable, str(ROOT / "scripts" / "verify_mujoco.py"), str(model), str(free / "sim_free.csv")]
            if self.verbose:
                print("$ python3 scripts/verify_mujoco.py " + " ".join(cmd[2:]), file=sys.stderr, flush=True)
            proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
            if proc.returncode != 0:
                sys.stderr.write(proc.stdout + proc.stderr)
                sys.exit(f"readme_figures: verify_mujoco.py on {model} failed with exit code {proc.returncode}")
            saved.write_text(proc.stdout, encoding="utf-8")
        self.done[("verify", key)] = saved.read_text(encoding="utf-8")
        return self.done[("verify", key)]

    def json(self, job, name):
        with open(self.folder(job) / name, encoding="utf-8") as f:
            return json.load(f)

    def csv(self, job, name):
        with open(self.folder(job) / name, encoding="utf-8", newline="") as f:
            return list(csv.DictReader(f))


# --------------------------------------------------------------------------------------------
# The figures. Each takes the runner and returns the text that goes between its markers.
# --------------------------------------------------------------------------------------------


def fit_stdout(r):
    """Every line `springfit fit` prints for the paper's design (progress goes to stderr)."""
    _, stdout = r.run("fit.dp")
    # Timings vary from run to run: shown as `; … s` (the README says what they are), so the
    # quote regenerates identically.
    lines = [re.sub(r"; [0-9.]+ s$", "; … s", l) for l in stdout.splitlines() if l.strip()]
    # The script writes into its own folder; the README's command writes the default one.
    lines = [re.sub(r"^wrote \S+", "wrote out/double_pendulum", l) for l in lines]
    return "```text\n" + "\n".join(lines) + "\n```"


def parts_count(job):
    """`N of M` elements with a part, from summary.json's `realised`."""

    def f(r):
        realised = r.json(job, "summary.json")["realised"]
        return f"{realised['parts']} of {realised['parts'] + len(realised['missing'])}"

    return f


def parts_missing(job):
    """The ids of the elements no spring meets, from summary.json's `realised`."""
    return lambda r: ", ".join(r.json(job, "summary.json")["realised"]["missing"]) or "none"


def fit_summary(job):
    return lambda r: r.json(job, "summary.json")


def fit_figures():
    figs = {}
    for key, job in [
        ("dp", "fit.dp"),
        ("dense", "fit.dense"),
        ("workshop", "fit.workshop"),
        ("window", "fit.window"),
        ("triple", "fit.triple"),
        ("dense_robust", "fit.dense_robust"),
        ("window_cams", "fit.window_cams"),
        ("window_built", "fit.window_built"),
        ("cams4", "fit.cams4"),
        ("cams", "fit.cams"),
        ("dp_nominal", "fit.dp_nominal"),
        ("dp_nominal10", "fit.dp_nominal10"),
        ("dp_nominal8", "fit.dp_nominal8"),
    ]:
        s = fit_summary(job)
        figs[f"fit.{key}.springs"] = lambda r, s=s: str(s(r)["used"])
        figs[f"fit.{key}.p99"] = lambda r, s=s: deg(s(r)["residual_deg"]["p99_abs"])
        figs[f"fit.{key}.max"] = lambda r, s=s: deg(s(r)["residual_deg"]["max_abs"])
    # Designs with cams count cams and springs together (`used`): the docs quote no count.
    for key in ("window_cams", "window_built", "cams4", "cams"):
        del figs[f"fit.{key}.springs"]
    return figs


def as_built(job, what):
    """p50 / p95 over builds of an as-built figure of a fit (`p99_deg`, `trimmed.p99_deg`, …)."""

    def f(r):
        ab = r.json(job, "summary.json")["as_built"]
        for key in what.split("."):
            ab = ab[key]
        unit = (lambda x: f"{x:.4f}") if what.startswith("shift") else deg
        return f"{unit(ab['p50'])} / {unit(ab['p95'])}"

    return f


def p95_interval(job, what):
    """The 95 % confidence interval of the p95 over builds of an as-built figure: `a–b°`."""

    def f(r):
        ab = r.json(job, "summary.json")["as_built"]
        for key in what.split("."):
            ab = ab[key]
        lo, hi = ab["p95_ci"]
        return f"{deg(lo)[:-1]}–{deg(hi)}"

    return f


def deviation(job, bound):
    """Largest geodesic deviation of the free runs, √(kg·m²)·rad: `≤ max`, or `min to max`."""

    def f(r):
        d = [m["geodesic_deviation"]["max"] for m in sim(r, job, "free")["runs"].values()]
        return f"≤ {max(d):.1e}" if bound else f"{min(d):.1e} to {max(d):.1e}"

    return f


def sim(r, job, scenario):
    return r.json(job, f"sim_{scenario}.json")


def drifts(r, job):
    return [m["mode_drift_deg"] for m in sim(r, job, "free")["runs"].values()]


def drift_range(r, job):
    d = drifts(r, job)
    return f"{sig(min(d), 2)}–{deg(max(d), 2)}"


def free_periods(r):
    """Small-oscillation periods in the free runs of the paper's design: duration · ω / 2π."""
    rows = r.csv("sim.dp", "sim_free.csv")
    t_end = max(float(row["t"]) for row in rows)
    omega = r.json("fit.dp", "summary.json")["frequency_rad_s"]
    return f"{t_end * omega / (2 * math.pi):.1f} periods ({t_end:g} s at ω = {omega:g} rad/s)"


def settling(r):
    runs = sim(r, "sim.dp", "switch")["runs"]
    steps = [s for m in runs.values() for s in m["settling_s"]]
    never = sum(1 for s in steps if s is None)
    if never:
        return f"{never} of {len(steps)} steps never settle"
    return f"every step settles within {sig(max(steps), 2)} s"


def swingup(variant, key, fmt):
    return lambda r: fmt(sim(r, "sim.dp", "swingup")["runs"][variant][key])


def label_error(r):
    e = sim(r, "sim.dp", "free")["label_error_deg"]
    mantissa, exponent = f"{e:.1e}".split("e")
    sup = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")
    return f"{mantissa}·10{str(int(exponent)).translate(sup)}°"


def sweep_tables(r):
    return r.json("sweep.dp", "sweep.json")


def parasitic_share(eps):
    def f(r):
        rows = [p for p in sweep_tables(r)["parasitic"] if p["eps"] == eps]
        return pct(rows[0]["actuator_share"])

    return f


def tolerance_cell(level):
    def f(r):
        rows = [t for t in sweep_tables(r)["tolerance_levels"] if t["tolerance"] == level]
        t = rows[0]
        return (
            f"{pct(t['actuator_share_p50'])} / {pct(t['actuator_share_p95'])}, "
            f"{deg(t['residual_p99_deg_p50'])} / {deg(t['residual_p99_deg_p95'])}"
        )

    return f


def tuned_cell(level):
    """The sweep's builds tuned after assembly: share p50 / p95, residual p99 p50 / p95."""

    def f(r):
        t = [t for t in sweep_tables(r)["tolerance_levels"] if t["tolerance"] == level][0]["tuned"]
        return (
            f"{pct(t['actuator_share']['p50'])} / {pct(t['actuator_share']['p95'])}, "
            f"{deg(t['residual_p99_deg']['p50'])} / {deg(t['residual_p99_deg']['p95'])}"
        )

    return f


def trimmed_cell(level):
    """The sweep's trimmed builds: residual p99 p50 / p95."""

    def f(r):
        t = [t for t in sweep_tables(r)["tolerance_levels"] if t["tolerance"] == level][0]
        return f"{deg(t['trimmed_residual_p99_deg_p50'])} / {deg(t['trimmed_residual_p99_deg_p95'])}"

    return f


def pareto_rows(r):
    return r.csv("pareto.dp", "pareto.csv")


def pareto_budget(k):
    def f(r):
        row = [x for x in pareto_rows(r) if x["curve"] == "budget" and int(x["budget"]) == k][0]
        return f"{deg(float(row['p99_abs_deg']))} / {deg(float(row['max_abs_deg']))}"

    return f


def pareto_radius(rad):
    def f(r):
        row = [x for x in pareto_rows(r) if x["curve"] == "radius" and abs(float(x["radius"]) - rad) < 1e-9][0]
        return deg(float(row["p99_abs_deg"]))

    return f


def pareto_mass_table(r):
    """The default design's mass curve (pareto_mass.csv) as a Markdown table: per mass budget, the
    residual and the masses by the fit's model and by the parts chosen, against the floor."""
    rows = r.csv("pareto.dp_mass", "pareto_mass.csv")
    lines = [
        "| max_spring_mass | p99 / max | model mass | parts' mass | × floor | stored energy / U* | total \\|preload\\| |",
        "| ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for x in rows:
        budget = f"{sig(float(x['max_spring_mass_kg']))} kg" if x["max_spring_mass_kg"] else "none"
        if x["infeasible"]:
            lines.append(f"| {budget} | infeasible | | | | | |")
            continue
        parts = float(x["spring_mass_kg"]) if x["spring_mass_kg"] else None
        lines.append(
            f"| {budget} | {deg(float(x['p99_abs_deg']))} / {deg(float(x['max_abs_deg']))} "
            f"| {sig(float(x['model_mass_kg']))} kg | {sig(parts) + ' kg' if parts else '–'} "
            f"| {sig(parts / float(x['floor_kg']), 2) + '×' if parts else '–'} "
            f"| {sig(float(x['stored_energy_over_potential']), 2)}× | {sig(float(x['preload_total_nm']))} N·m |"
        )
    return "\n".join(lines)


def region_cell(job, probe_word):
    def f(r):
        rep = r.json(job, "region.json")
        if rep["largest_radius_is_lower_bound"]:
            return f"≥ {radius(rep['largest_radius'])} ({probe_word})"
        kind = {"conjugate": "conjugate point", "crossing": "crossing geodesics"}[rep["limit"]["kind"]]
        return f"{radius(rep['largest_radius'])} ({kind})"

    return f


# --------------------------------------------------------------------------------------------
# Error messages: small bad inputs written under <out>/errors/<case>/, each run from its own
# folder so the messages name `design.toml` and `catalog.toml` as a user would see them.
# --------------------------------------------------------------------------------------------

ERROR_DESIGN = """name = "demo"
catalog = "catalog.toml"

[robot]
gravity = [0.0, 0.0]

[[robot.links]]
mass = 1.0
length = 2.0
com = 1.0
inertia = 1.0

[[robot.links]]
mass = 1.0
length = 2.0
com = 1.0
inertia = 1.0

[equilibrium]
q = [0.0, "pi/2"]

[region]
kind = "ball"
radius = 2.0

[fit]
frequency = 4.0

[[scenario]]
name = "free"
kind = "free"
duration = 5.0
releases = [{ mode = 0.0, energy = 5.0 }]

[sweep]
scenario = "free"
"""

ERROR_CATALOG = """name = "demo"

[[family]]
name = "torsion spring"
profile = "linear"
couplings = [[1, 0], [0, 1], [1, 1]]
offsets = "equilibrium"
"""

# (what is wrong, edits of the design [(old, new)], edits of the catalogue, command, exit code)
# The end of ERROR_DESIGN, where the cases of `[parts]` add their section.
SWEEP_END = '[sweep]\nscenario = "free"\n'

ERROR_CASES = [
    ("malformed TOML", [("[region]", "[region")], [], "check", 2),
    ("unknown field", [('kind = "ball"', 'kind = "ball"\nspeed = 1.0')], [], "check", 2),
    ("wrong type", [("length = 2.0", 'length = "long"')], [], "check", 2),
    ("NaN or infinite numbers", [("inertia = 1.0", "inertia = nan")], [], "check", 2),
    ("zero or negative mass, length", [("mass = 1.0", "mass = -1.0")], [], "check", 2),
    ("equilibrium outside the region",
     [('kind = "ball"\nradius = 2.0', 'kind = "box"\nlower = [-1.0, 2.0]\nupper = [1.0, 3.0]')], [], "check", 2),
    ("region past the largest valid radius", [("radius = 2.0", "radius = 10.0")], [], "check", 2),
    ("a catalogue file that does not exist", [('catalog = "catalog.toml"', 'catalog = "../catalogs/x.toml"')], [],
     "check", 2),
    ("a scenario that cannot run",
     [('releases = [{ mode = 0.0, energy = 5.0 }]\n',
       'releases = [{ mode = 0.0, energy = 5.0 }]\n\n[[scenario]]\nname = "switch"\nkind = "switch"\n'
       'duration = 10.0\nmode = 0.0\nenergy = 5.0\nstep = "pi/6"\nevery = 0.0\n')], [], "check", 2),
    ("a gravity vector with three components", [("gravity = [0.0, 0.0]", "gravity = [0.0, 0.0, -9.81]")], [],
     "check", 2),
    ("a sweep scenario the design lacks", [('scenario = "free"', 'scenario = "sensitivity"')], [], "check", 2),
    ("a catalogue that yields no candidate", [], [(ERROR_CATALOG[ERROR_CATALOG.index("[[family]]"):], "")], "check", 2),
    ("an infeasible fit (exit 1)", [], [("[[1, 0], [0, 1], [1, 1]]", "[[1, 0]]")], "fit", 1),
    ("an unwritable output folder", [], [], "fit --out plainfile/out", 2),
    ("an unknown spring material", [(SWEEP_END, SWEEP_END + '\n[parts]\nmaterial = "unobtainium"\n')], [], "check", 2),
    ("an EN 15800 grade outside 1–3", [(SWEEP_END, SWEEP_END + "\n[parts]\ngrade = 4\n")], [], "check", 2),
    ("a stock list without its columns", [(SWEEP_END, SWEEP_END + '\n[parts]\nstock = "catalog.toml"\n')], [],
     "parts --out out", 2),
]

# Longer messages are cut here in the table (the full text is in the case's stderr file).
ERROR_WIDTH = 200


def error_table(r):
    """The table of example error messages (docs/guide.md), from running each bad input."""
    rows = ["| input | message |", "| --- | --- |"]
    for label, design_edits, catalog_edits, command, code in ERROR_CASES:
        case = r.out / "errors" / re.sub(r"\W+", "_", label).strip("_")
        if not (r.reuse and (case / "stderr").is_file()):
            case.mkdir(parents=True, exist_ok=True)
            design, catalog = ERROR_DESIGN, ERROR_CATALOG
            for old, new in design_edits:
                if old not in design:
                    sys.exit(f"readme_figures: error case {label!r}: {old!r} not in the design")
                design = design.replace(old, new, 1)
            for old, new in catalog_edits:
                catalog = catalog.replace(old, new, 1)
            (case / "design.toml").write_text(design, encoding="utf-8")
            (case / "catalog.toml").write_text(catalog, encoding="utf-8")
            (case / "plainfile").write_text("a file, not a folder\n", encoding="utf-8")
            args = command.split()
            cmd = [str(r.binary)] + (["--threads", str(r.threads)] if r.threads else []) + args[:1] + ["design.toml"]
            cmd += args[1:] if len(args) > 1 else (["--out", "out"] if args[0] == "fit" else [])
            proc = subprocess.run(cmd, cwd=case, capture_output=True, text=True)
            if proc.returncode != code:
                sys.stderr.write(proc.stdout + proc.stderr)
                sys.exit(f"readme_figures: error case {label!r} exited {proc.returncode}, expected {code}")
            (case / "stderr").write_text(proc.stderr, encoding="utf-8")
        lines = [l for l in (case / "stderr").read_text(encoding="utf-8").splitlines() if "error:" in l]
        if len(lines) != 1:
            sys.exit(f"readme_figures: error case {label!r} printed {len(lines)} error lines, expected one")
        message = lines[0].split("error: ", 1)[1].replace(str(case.resolve()), "…").replace(str(case), "…")
        if len(message) > ERROR_WIDTH:
            message = message[: message.rfind(" ", 0, ERROR_WIDTH)].rstrip(" ,;:(") + " …"
        # Messages quote fields in backticks: a double-backtick code span holds them.
        rows.append(f"| {label} | `` {message.replace('|', '/')} `` |")
    return "\n".join(rows)


def compare_table(job):
    """Columns of the table in a `compare` run's compare.md, cell for cell as the command wrote
    them: input, springs, p99 and max |angle| as drawn, and the p99 as built at the design's
    tolerance (p50 / p95 over builds) where the fit drew builds."""

    def f(r):
        text = (r.folder(job) / "compare.md").read_text(encoding="utf-8")
        table = [l for l in text.splitlines() if l.startswith("|")]
        head = [c.strip() for c in table[0].strip("|").split("|")]
        pick = [head.index(c) for c in ("design", "springs", "p99", "max", "as built p99 (p50 / p95 over builds)")]
        rows = ["| input | springs | p99 | max | as built: p99, p50 / p95 over builds |", "| --- | ---: | ---: | ---: | --- |"]
        for line in table[2:]:
            cells = [c.strip() for c in line.strip("|").split("|")]
            rows.append("| " + " | ".join(cells[i] for i in pick) + " |")
        return "\n".join(rows)

    return f


def mujoco_row(key):
    """A row of the MuJoCo table: springs exact / by callback (from `export`'s stdout), the
    largest joint-angle difference and MuJoCo's largest energy drift (from verify_mujoco.py)."""

    def f(r):
        exported = r.run(f"export.{key}")[1]
        m = re.search(r"(\d+) springs for MuJoCo, (\d+) exact, (\d+) by passive-force callback", exported)
        if not m:
            sys.exit(f"readme_figures: export.{key}: unexpected stdout {exported!r}")
        out = r.verify_mujoco(key)
        v = re.search(r"largest difference ([0-9.e+-]+) rad .*largest MuJoCo energy drift ([0-9.e+-]+) J", out)
        if not v:
            sys.exit(f"readme_figures: verify_mujoco.py ({key}): unexpected output {out!r}")
        diff, drift = float(v.group(1)), float(v.group(2))
        return f"{m.group(1)}: {m.group(2)} / {m.group(3)} | {diff:.1e} rad | {drift:.1e} J"

    return f


def stdout_lines(job, starts):
    """The lines of a job's stdout that start with `starts`, timings dropped, as a text block."""

    def f(r):
        _, stdout = r.run(job)
        lines = [re.sub(r"; [0-9.]+ s$", "", l) for l in stdout.splitlines() if l.startswith(starts)]
        return "```text\n" + "\n".join(lines) + "\n```"

    return f


def check_json(job):
    return lambda r: json.loads(r.run(job)[1])


def matrix2(m):
    return " ".join("(" + ", ".join(f"{x:.4f}" for x in row) + ")" for row in m)


def sweep_row(job, level):
    """share p50 / p95 and residual p99 p50 / p95 over builds at one tolerance level."""

    def f(r):
        t = [t for t in r.json(job, "sweep.json")["tolerance_levels"] if t["tolerance"] == level][0]
        return (
            f"{pct(t['actuator_share_p50'], 2)} / {pct(t['actuator_share_p95'], 2)}, "
            f"{deg(t['residual_p99_deg_p50'], 2)} / {deg(t['residual_p99_deg_p95'], 2)}"
        )

    return f


def parasitic(job, eps_list):
    def f(r):
        rows = r.json(job, "sweep.json")["parasitic"]
        return " / ".join(pct([p for p in rows if p["eps"] == e][0]["actuator_share"]) for e in eps_list)

    return f


def ur5_tolerance(job):
    def f(r):
        t = [t for t in r.json(job, "sweep.json")["tolerance_levels"] if t["tolerance"] == 0.05][0]
        return f"{deg(t['residual_p99_deg_p50'], 4)} / {deg(t['residual_p99_deg_p95'], 4)}"

    return f


def ur5_shift(job):
    def f(r):
        t = [t for t in r.json(job, "sweep.json")["tolerance_levels"] if t["tolerance"] == 0.05][0]
        return f"{t['equilibrium_shift_rad_p50']:.3g} rad"

    return f


def drift_list(job):
    def f(r):
        d = drifts(r, job)
        return ", ".join(deg(x, 2) for x in d[:-1]) + " and " + deg(d[-1], 2)

    return f


FIGURES = {
    "fit.stdout": fit_stdout,
    **fit_figures(),
    "sim.dense.free.drift": lambda r: "≤ " + deg(max(drifts(r, "sim.dense")), 2),
    "sim.dp.free.drift": lambda r: drift_range(r, "sim.dp"),
    "sim.dp.free.periods": free_periods,
    "sim.exact.free.drift": lambda r: "≤ " + deg(max(drifts(r, "sim.dp_exact")), 1),
    "sim.dp.switch.settling": settling,
    "sim.dp.switch.share": lambda r: pct(sim(r, "sim.dp", "switch")["runs"]["switch"]["actuator_share"], 2),
    "sim.dp.swingup.energy": swingup("energy", "energy_signed_error_last5s", signed_pct),
    "sim.dp.swingup.negative_damping": swingup("negative_damping", "energy_signed_error_last5s", signed_pct),
    "sim.dp.swingup.compensated": swingup("energy_compensated", "energy_signed_error_last5s", signed_pct),
    "sim.dp.swingup.compensated.share5": swingup(
        "energy_compensated", "actuator_share_last5s", lambda x: pct(x, 2)
    ),
    "sim.dp.label_error": label_error,
    "sim.dense.free.dev": deviation("sim.dense", True),
    "sim.dp.free.dev": deviation("sim.dp", False),
    "sim.exact.free.dev": deviation("sim.dp_exact", True),
    "sim.dp.switch.energy": lambda r: signed_pct(
        sim(r, "sim.dp", "switch")["runs"]["switch"]["energy_signed_error_last5s"]
    ),
    "sim.dp.switch.peak": lambda r: f"{sim(r, 'sim.dp', 'switch')['runs']['switch']['peak_actuator_torque_nm']:.2f} N·m",
    "sim.dp.isochrony": lambda r: f"{r.json('sim.dp', 'summary.json')['isochrony_error']:.1e}",
    "sim.exact.isochrony": lambda r: f"{r.json('sim.dp_exact', 'summary.json')['isochrony_error']:.1e}",
    "sim.dp.switch.demand": lambda r: f"{sim(r, 'sim.dp', 'switch')['runs']['switch']['peak_demanded_torque_nm']:.1f} N·m",
    "sim.dp.switch.saturated": lambda r: f"{sim(r, 'sim.dp', 'switch')['runs']['switch']['saturated_s']:.2f} s",
    "asbuilt.dp5.p99": as_built("fit.dp", "p99_deg"),
    "asbuilt.dp5.shift": as_built("fit.dp", "shift_rad"),
    "asbuilt.dp5.trimmed": as_built("fit.dp", "trimmed.p99_deg"),
    "asbuilt.trim5.p99": as_built("fit.dp_trim", "p99_deg"),
    "asbuilt.trim5.trimmed": as_built("fit.dp_trim", "trimmed.p99_deg"),
    "asbuilt.trim5.shift": as_built("fit.dp_trim", "shift_rad"),
    "asbuilt.trim10.p99": as_built("fit.dp_trim_tol10", "p99_deg"),
    "asbuilt.trim10.trimmed": as_built("fit.dp_trim_tol10", "trimmed.p99_deg"),
    "asbuilt.trim10.shift": as_built("fit.dp_trim_tol10", "shift_rad"),
    "asbuilt.cams4.p99": as_built("fit.cams4", "p99_deg"),
    "asbuilt.cams.p99": as_built("fit.cams", "p99_deg"),
    "asbuilt.cams.trimmed": as_built("fit.cams", "trimmed.p99_deg"),
    "asbuilt.window_cams.p99": as_built("fit.window_cams", "p99_deg"),
    "asbuilt.window_cams.preload": as_built("fit.window_cams", "preload_trimmed.p99_deg"),
    "asbuilt.window_built.p99": as_built("fit.window_built", "p99_deg"),
    "asbuilt.window_built.p95": lambda r: deg(r.json("fit.window_built", "summary.json")["as_built"]["p99_deg"]["p95"]),
    "asbuilt.window_built.p95_ci": p95_interval("fit.window_built", "p99_deg"),
    "asbuilt.window_built.preload": as_built("fit.window_built", "preload_trimmed.p99_deg"),
    "asbuilt.window_built.preload_ci": p95_interval("fit.window_built", "preload_trimmed.p99_deg"),
    "sweep.dp.eps0.share": parasitic_share(0.0),
    "sweep.dp.eps1.share": parasitic_share(1.0),
    "sweep.dp.tol5": tolerance_cell(0.05),
    "sweep.dp.tol10": tolerance_cell(0.1),
    "sweep.dp.tol5.tuned": tuned_cell(0.05),
    "sweep.dp.tol10.tuned": tuned_cell(0.1),
    "sweep.dp.tol10.trimmed": trimmed_cell(0.1),
    **{f"pareto.dp.k{k}": pareto_budget(k) for k in (4, 6, 8, 10, 12, 16)},
    "pareto.dp.r0.5": pareto_radius(0.5),
    "pareto.dp.r2": pareto_radius(2.0),
    "pareto.dp.r3.5": pareto_radius(3.5),
    "pareto.dp.mass": pareto_mass_table,
    "region.dp": region_cell("geo.dp", "probe"),
    "region.dp.long": region_cell("geo.dp_long", "no failure found"),
    "region.straight.long": region_cell("geo.straight_long", "no failure found"),
    "region.folded.long": region_cell("geo.folded_long", "no failure found"),
    "region.triple": region_cell("geo.triple", "no failure found"),
    "sweep.dense_robust.eps0.share": lambda r: pct(
        [p for p in r.json("sweep.dense_robust", "sweep.json")["parasitic"] if p["eps"] == 0.0][0]["actuator_share"], 2
    ),
    "sweep.dense_robust.eps1.share": lambda r: pct(
        [p for p in r.json("sweep.dense_robust", "sweep.json")["parasitic"] if p["eps"] == 1.0][0]["actuator_share"]
    ),
    "sweep.dense_robust.tol5": sweep_row("sweep.dense_robust", 0.05),
    "sweep.dense_robust.tol10": sweep_row("sweep.dense_robust", 0.1),
    "mujoco.dp": mujoco_row("dp"),
    "mujoco.dense": mujoco_row("dense"),
    "mujoco.ur5": mujoco_row("ur5"),
    "mujoco.ur5_3": mujoco_row("ur5_3"),
    "ur5.mass": lambda r: matrix2(check_json("check.ur5")(r)["mass_matrix"]),
    "ur5.radius": lambda r: radius(check_json("check.ur5")(r)["region"]["largest_radius"]),
    "ur5.gravity": lambda r: "(" + ", ".join(sig(x, 4) for x in check_json("check.ur5")(r)["gravity_torque"]) + ")",
    "ur5.fit.stdout": stdout_lines("fit.ur5", ("ur5_lift_elbow:", "residual angle")),
    "ur5.free.drift": drift_list("sim.ur5"),
    "ur5_3.radius": lambda r: radius(check_json("check.ur5_3")(r)["region"]["largest_radius"]),
    "ur5_3.springs": lambda r: str(r.json("fit.ur5_3", "summary.json")["used"]),
    "ur5_3.p99": lambda r: deg(r.json("fit.ur5_3", "summary.json")["residual_deg"]["p99_abs"]),
    "ur5_3.max": lambda r: deg(r.json("fit.ur5_3", "summary.json")["residual_deg"]["max_abs"]),
    "ur5_3.dense.springs": lambda r: str(r.json("fit.ur5_3_dense", "summary.json")["used"]),
    "ur5_3.dense.p99": lambda r: deg(r.json("fit.ur5_3_dense", "summary.json")["residual_deg"]["p99_abs"]),
    "ur5_3.dense.max": lambda r: deg(r.json("fit.ur5_3_dense", "summary.json")["residual_deg"]["max_abs"]),
    "ur5_3.dense.drift": drift_list("sim.ur5_3_dense"),
    "ur5.sweep.parasitic": parasitic("sweep.ur5", [0.0, 0.1, 1.0]),
    "ur5.sweep.tol5": ur5_tolerance("sweep.ur5"),
    "ur5.sweep.shift": ur5_shift("sweep.ur5"),
    "ur5_3.sweep.parasitic": parasitic("sweep.ur5_3", [0.0, 0.1, 1.0]),
    "ur5_3.sweep.tol5": ur5_tolerance("sweep.ur5_3"),
    "ur5_3.sweep.shift": ur5_shift("sweep.ur5_3"),
    "errors.table": error_table,
    "parts.dp.realised.p99": lambda r: deg(r.json("fit.dp", "summary.json")["realised"]["residual_deg"]["p99_abs"], 4),
    "parts.dp.ideal.p99": lambda r: deg(r.json("fit.dp", "summary.json")["residual_deg"]["p99_abs"], 4),
    "parts.dp.change.p99": lambda r: deg(r.json("fit.dp", "summary.json")["realised"]["p99_change_deg"], 2),
    "parts.dp.mass": lambda r: sig(r.json("fit.dp", "summary.json")["realised"]["spring_mass_kg"]) + " kg",
    "mass.dp.spring": lambda r: sig(r.json("fit.dp", "summary.json")["mass"]["spring_mass_kg"]) + " kg",
    "mass.dp.over_arm": lambda r: f'{r.json("fit.dp", "summary.json")["mass"]["mass_over_arm"]:.2f}×',
    "mass.dp.over_floor": lambda r: f'{r.json("fit.dp", "summary.json")["mass"]["mass_over_floor"]:.1f}×',
    "mass.dp.stored": lambda r: f'{r.json("fit.dp", "summary.json")["mass"]["stored_energy_over_potential"]:.1f}×',
    "mass.dp.preload": lambda r: sig(r.json("fit.dp", "summary.json")["mass"]["preload_total_nm"]) + " N·m",
    "parts.cams.count": parts_count("fit.cams"),
    "parts.cams.missing": parts_missing("fit.cams"),
    "compare.window": compare_table("compare.window"),
    "ur5.fit.p99": lambda r: deg(r.json("fit.ur5", "summary.json")["residual_deg"]["p99_abs"], 4),
    "ur5.sweep.p99_p50": lambda r: deg(
        [t for t in r.json("sweep.ur5", "sweep.json")["tolerance_levels"] if t["tolerance"] == 0.05][0][
            "residual_p99_deg_p50"
        ],
        4,
    ),
}

# --------------------------------------------------------------------------------------------
# Rewriting README.md and docs/*.md.
# --------------------------------------------------------------------------------------------

INLINE = re.compile(r"<!-- fig:(?P<name>[\w.\-]+) -->(?P<body>.*?)<!-- /fig -->")
BLOCK = re.compile(r"<!-- block:(?P<name>[\w.\-]+) -->\n(?P<body>.*?)\n<!-- /block -->", re.S)


def markers(text):
    return [(m.group("name"), m) for m in INLINE.finditer(text)] + [
        (m.group("name"), m) for m in BLOCK.finditer(text)
    ]


def default_files():
    """README.md and every docs/*.md, in a stable order."""
    return [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))


def shown(path):
    """A file's path relative to the repository, for messages."""
    try:
        return path.resolve().relative_to(ROOT).as_posix()
    except ValueError:
        return str(path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="do not write; exit 1 if a figure differs")
    ap.add_argument("--threads", type=int, default=None, help="springfit --threads (default: all cores)")
    ap.add_argument("--out", default="out/readme", help="scratch folder for the commands' outputs")
    ap.add_argument("--files", nargs="+", default=None, metavar="FILE",
                    help="the files to rewrite or check, together (default: README.md and docs/*.md)")
    ap.add_argument("--bin", default=None, help="springfit binary (default: build target/release/springfit)")
    ap.add_argument("--no-build", action="store_true", help="use the existing target/release/springfit")
    ap.add_argument("--quiet", action="store_true", help="print only differences and errors")
    ap.add_argument("--reuse", action="store_true",
                    help="read the outputs of an earlier run under --out instead of running the commands again "
                         "(for editing the docs; the figures are only as fresh as that run)")
    args = ap.parse_args()

    files = default_files() if args.files is None else [
        (ROOT / f) if not Path(f).is_absolute() else Path(f) for f in args.files
    ]
    texts = {}
    for path in files:
        if not path.is_file():
            sys.exit(f"readme_figures: {shown(path)}: no such file")
        texts[path] = path.read_text(encoding="utf-8")
    where = {}  # figure name -> the files that mark it
    for path, text in texts.items():
        for name, _ in markers(text):
            where.setdefault(name, [])
            if path not in where[name]:
                where[name].append(path)
    names = set(where)
    unknown = sorted(names - set(FIGURES))
    unused = sorted(set(FIGURES) - names)
    if unknown:
        sys.exit("readme_figures: figures marked but unknown to this script: "
                 + ", ".join(f"{n} ({', '.join(shown(p) for p in where[n])})" for n in unknown))
    if unused:
        sys.exit(f"readme_figures: figures marked in none of {', '.join(shown(p) for p in files)} "
                 f"(remove them here or mark them there): {', '.join(unused)}")

    t0 = time.monotonic()
    if args.bin:
        binary = Path(args.bin).resolve()
    else:
        binary = ROOT / "target" / "release" / "springfit"
        if not (args.no_build or args.reuse):
            if not args.quiet:
                print("$ cargo build --release", file=sys.stderr, flush=True)
            subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    out = (ROOT / args.out) if not Path(args.out).is_absolute() else Path(args.out)
    runner = Runner(binary, out, args.threads, verbose=not args.quiet, reuse=args.reuse)

    values = {name: FIGURES[name](runner) for name in sorted(names)}

    differ = []  # (file, name, old, new)
    new_texts = {}
    for path, text in texts.items():

        def replace_inline(m, path=path):
            new = values[m.group("name")]
            if m.group("body") != new:
                differ.append((path, m.group("name"), m.group("body"), new))
            return f"<!-- fig:{m.group('name')} -->{new}<!-- /fig -->"

        def replace_block(m, path=path):
            new = values[m.group("name")]
            if m.group("body") != new:
                differ.append((path, m.group("name"), m.group("body"), new))
            return f"<!-- block:{m.group('name')} -->\n{new}\n<!-- /block -->"

        new_texts[path] = BLOCK.sub(replace_block, INLINE.sub(replace_inline, text))
    elapsed = time.monotonic() - t0
    if not args.quiet:
        for job, secs in runner.timings.items():
            print(f"  {job}: {secs:.1f} s", file=sys.stderr)
        print(f"{len(values)} figures in {len(files)} files from {len(runner.done)} commands in {elapsed:.0f} s",
              file=sys.stderr)
    for path, name, old, new in differ:
        print(f"{shown(path)}: {name}: {old!r} -> {new!r}")
    if args.check:
        if differ:
            changed = sorted({shown(p) for p, *_ in differ})
            print(f"readme_figures: {len(differ)} figure(s) in {', '.join(changed)} differ from what springfit "
                  f"prints now; run `python3 scripts/readme_figures.py` to update them", file=sys.stderr)
            return 1
        return 0
    for path, text in texts.items():
        if new_texts[path] != text:
            path.write_text(new_texts[path], encoding="utf-8")
            if not args.quiet:
                n = sum(1 for p, *_ in differ if p == path)
                print(f"rewrote {n} figure(s) in {shown(path)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
