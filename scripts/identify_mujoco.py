#!/usr/bin/env python3
"""MuJoCo plays a built arm: identify its spring rates from its own swings, then tune it.

Usage:
    python3 scripts/identify_mujoco.py [DESIGN] [--out DIR] [--seconds 60] [--driven 15] [--seed 1] ...

The pipeline, every step through the springfit binary except the physics:

1. `springfit fit DESIGN` (or --bom), and a build of it: every spring and cam's rate off by a
   known delta drawn uniformly in +-tolerance (one delta per cam; the trims too, unless
   --exact-trims), written as a bill of materials;
2. the built arm as MuJoCo sees it, written by this script and not by springfit: an MJCF of the
   planar chain from the design's `[[robot.links]]` (masses, lengths, centres of mass, inertias,
   gravity; q1 from the x axis, each joint relative to the link before), and the built bill's
   springs applied by this script's own `mjcb_passive` from the element laws of docs/theory.md
   (torque -k u'(a.q - x0) a). With --exported (and for cams or URDF robots, which it needs),
   `springfit export --mujoco` of the build instead. MuJoCo gets joint damping and Coulomb
   friction (frictionloss, its constraint time constant at two steps so that it acts as Coulomb
   friction rather than lagging a reversal by MuJoCo's default 20 ms);
3. `springfit identify --plan` proposes releases; MuJoCo swings the arm from rest at them (as
   many as fit in --seconds minus --driven, each for the plan's log length) and drives it from
   q_eq with a multisine torque for --driven seconds, all at the plan's rate (1 kHz). The torque
   is held over each step at its mid-step value, so the logged torque at t is the one acting
   around t;
4. the angles are read through an encoder of --bits per turn with --noise counts rms of noise
   before quantisation, the torques with --torque-noise N*m rms, and written as logs;
5. `springfit identify` on the logs; the identified delta are compared with the true ones;
6. `springfit tune` from the identified rates and from the true rates; the arm as built, with the
   settings tuned from the identified rates, is judged by `springfit tune` reading the true rates
   (its "before" state: equilibrium shift and p99 residual).

Prints the comparison and writes DIR/summary.json with every figure. Exit codes: 0 done (and, with
--check, the acceptance figures met), 1 --check failed, 2 bad input or a failed command. Needs
`python3 -m pip install 'mujoco>=3.7' numpy`.
"""

import argparse
import csv
import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
try:
    import mujoco
    import numpy as np
    from verify_mujoco import Passive
except ImportError as e:  # pragma: no cover - reported, not tested
    print(f"identify_mujoco: {e}: install with `python3 -m pip install 'mujoco>=3.7' numpy`", file=sys.stderr)
    sys.exit(2)

ROOT = Path(__file__).resolve().parent.parent


class Failed(Exception):
    pass


def springfit(binary, threads, *args):
    """Runs springfit; returns its stdout, raises Failed with its stderr."""
    cmd = [str(binary), "--quiet"] + (["--threads", str(threads)] if threads else []) + [str(a) for a in args]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise Failed(f"{' '.join(cmd)}: exit {r.returncode}\n{r.stderr.strip()}")
    return r.stdout


def read_bom(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def write_csv(path, header, rows):
    with open(path, "w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows([header] + rows)


def draw_build(bom_path, out_dir, tolerance, rng, exact_trims):
    """The built bill: each line's rate times 1 + delta (a cam line scales its follower rate and
    its file's coefficients); trims stray too unless `exact_trims`. Returns {id: delta}."""
    header, rows = read_bom(bom_path)
    col = {n: i for i, n in enumerate(header)}
    deltas = {}
    built = []
    (out_dir / "cams").mkdir(parents=True, exist_ok=True)
    for r in rows:
        r = list(r)
        trim = r[col["trim_min"]] != ""
        d = float(rng.uniform(-tolerance, tolerance))
        if trim and exact_trims:
            d = 0.0
        deltas[r[col["id"]]] = d
        k = float(r[col["stiffness"]]) * (1.0 + d)
        r[col["stiffness"]] = repr(k)
        if r[col["profile"]] == "cam":
            src = bom_path.parent / r[col["file"]]
            text = src.read_text()
            text = re.sub(r"(?m)^follower_rate_n_per_mm = .*$", f"follower_rate_n_per_mm = {k!r}", text)
            coef = re.search(r"(?m)^coefficients_j = \[(.*)\]$", text)
            scaled = ", ".join(repr(float(c) * (1.0 + d)) for c in coef.group(1).split(","))
            text = text[:coef.start(1)] + scaled + text[coef.end(1):]
            (out_dir / r[col["file"]]).write_text(text)
        built.append(r)
    write_csv(out_dir / "built.csv", header, built)
    return deltas


def measured_bill(bom_path, out_path, rates):
    """bom_path with a measured_stiffness column: rates[id] where given, blank elsewhere; its
    cams' files copied beside it."""
    header, rows = read_bom(bom_path)
    col = {n: i for i, n in enumerate(header)}
    out_path.parent.mkdir(parents=True, exist_ok=True)
    out = []
    for r in rows:
        v = rates.get(r[col["id"]])
        out.append(list(r) + ["" if v is None else repr(v)])
        if r[col["profile"]] == "cam":
            dst = out_path.parent / r[col["file"]]
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(bom_path.parent / r[col["file"]], dst)
    write_csv(out_path, header + ["measured_stiffness"], out)


def independent_model(design_path, built_bom, timestep):
    """The built arm for MuJoCo without springfit's dynamics: (MjModel, passive callback). The
    planar chain from the design file's links, the springs from the built bill's lines."""
    import tomllib

    design = tomllib.loads(Path(design_path).read_text())
    robot = design.get("robot", {})
    links = robot.get("links")
    if not links or "urdf" in robot:
        raise Failed(f"{design_path}: the script builds planar [[robot.links]] arms only; use --exported")
    gravity = list(robot.get("gravity", [0.0, 0.0])) + [0.0]
    body, close = "", ""
    for i, link in enumerate(links):
        pos = 0.0 if i == 0 else float(links[i - 1]["length"])
        inertia = float(link["inertia"])
        body += (f'<body name="link{i + 1}" pos="{pos!r} 0 0"><joint name="q{i + 1}" type="hinge" axis="0 0 1"/>'
                 f'<inertial pos="{float(link["com"])!r} 0 0" mass="{float(link["mass"])!r}" '
                 f'diaginertia="{inertia!r} {inertia!r} {inertia!r}"/>'
                 f'<geom type="capsule" fromto="0 0 0 {float(link["length"])!r} 0 0" size="0.02" mass="0" '
                 f'contype="0" conaffinity="0"/>')
        close += "</body>"
    xml = (f'<mujoco model="{design.get("name", "arm")}"><compiler angle="radian" inertiafromgeom="false"/>'
           f'<option timestep="{timestep!r}" integrator="RK4" gravity="{gravity[0]!r} {gravity[1]!r} 0"/>'
           f"<worldbody>{body}{close}</worldbody></mujoco>")
    model = mujoco.MjModel.from_xml_string(xml)
    header, rows = read_bom(built_bom)
    col = {c: i for i, c in enumerate(header)}
    slopes = {
        ("linear", ""): lambda d: d,
        ("cubic", ""): lambda d: d ** 3,
        ("crank", ""): np.sin,
        ("compression", "+"): lambda d: np.maximum(d, 0.0),
        ("compression", "-"): lambda d: np.minimum(d, 0.0),
    }
    springs = []
    for r in rows:
        key = (r[col["profile"]], r[col["side"]])
        if key not in slopes:
            raise Failed(f"{built_bom}: {r[col['id']]}: a {key[0]} element; the script's own springs are linear, "
                         "cubic, crank and compression ones: use --exported")
        a = np.array([float(x) for x in r[col["coupling"]].split(";")])
        springs.append((slopes[key], a, float(r[col["offset_rad"]]), float(r[col["stiffness"]])))

    def passive(m, d):
        for slope, a, x0, k in springs:
            d.qfrc_passive[:] -= k * slope(float(a @ d.qpos) - x0) * a

    return model, passive


def simulate(model, q0, seconds, drive, rng, bits, noise, torque_noise):
    """One run from rest at q0: (t, encoder angles, logged torques or None)."""
    h = model.opt.timestep
    data = mujoco.MjData(model)
    data.qpos[:] = q0
    data.qvel[:] = 0.0
    steps = int(round(seconds / h))
    count = 2.0 * math.pi / 2 ** bits
    t = np.arange(steps + 1) * h
    q = np.empty((steps + 1, model.nq))
    tau = np.empty((steps + 1, model.nq)) if drive else None
    for k in range(steps + 1):
        q[k] = data.qpos
        if drive:
            tau[k] = drive(t[k])
            data.qfrc_applied[:] = drive(t[k] + 0.5 * h)
        mujoco.mj_step(model, data)
    q = np.round((q + noise * count * rng.standard_normal(q.shape)) / count) * count
    if tau is not None:
        tau = tau + torque_noise * rng.standard_normal(tau.shape)
    return t, q, tau


def write_log(path, runs, driven):
    n = runs[0][2].shape[1]
    cols = ["run", "t"] + [f"q{j + 1}" for j in range(n)] + ([f"tau{j + 1}" for j in range(n)] if driven else [])
    with open(path, "w") as f:
        f.write(",".join(cols) + "\n")
        for name, t, q, tau in runs:
            for k in range(len(t)):
                fields = [name, f"{t[k]:.6f}"] + [repr(float(x)) for x in q[k]]
                if driven:
                    fields += [repr(float(x)) for x in tau[k]]
                f.write(",".join(fields) + "\n")


def multisine(n, amplitude, rng, seconds):
    """A sum of 20 sines from 0.15 to 3 Hz per joint, random phases, rms `amplitude` N*m, faded in
    and out over 1 s."""
    freqs = np.linspace(0.15, 3.0, 20)
    phases = rng.uniform(0.0, 2.0 * math.pi, (n, len(freqs)))
    scale = amplitude * math.sqrt(2.0 / len(freqs))

    def torque(t):
        fade = min(1.0, t, max(0.0, seconds - t))
        return fade * scale * np.sin(2.0 * math.pi * freqs * t + phases).sum(axis=1)

    return torque


def tolerant_copy(design, folder):
    """The design written into `folder` with its relative paths made absolute and
    `[equilibrium] bill_tolerance = 10`: it accepts a built arm's bill, whose springs rest off q_eq."""
    path = Path(design).resolve()
    text = path.read_text().replace('"../', f'"{path.parent}/../')
    text = re.sub(r"^\[equilibrium\]\s*$", "[equilibrium]\nbill_tolerance = 10.0", text, count=1, flags=re.M)
    copy = Path(folder) / path.name
    copy.write_text(text)
    return copy


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("design", nargs="?", default="designs/double_pendulum.toml")
    ap.add_argument("--bom", help="the bill of materials as designed (default: fit the design)")
    ap.add_argument("--springfit", default=str(ROOT / "target/release/springfit"))
    ap.add_argument("--out", default="out/identify_mujoco")
    ap.add_argument("--threads", type=int)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--tolerance", type=float, default=0.05, help="rate errors uniform in +-this (default 0.05)")
    ap.add_argument("--damping", type=float, default=0.05, help="joint damping, N*m*s/rad (default 0.05)")
    ap.add_argument("--friction", type=float, default=0.02, help="Coulomb friction, N*m (default 0.02)")
    ap.add_argument("--seconds", type=float, default=60.0, help="total log length (default 60)")
    ap.add_argument("--driven", type=float, default=15.0, help="seconds of it driven from q_eq (default 15)")
    ap.add_argument("--drive", type=float, default=3.0, help="rms of the driving torque, N*m (default 3)")
    ap.add_argument("--bits", type=int, default=17, help="encoder bits per turn (default 17)")
    ap.add_argument("--noise", type=float, default=1.0, help="encoder noise before quantisation, counts rms")
    ap.add_argument("--torque-noise", type=float, default=0.01, help="noise of the logged torques, N*m rms")
    ap.add_argument("--exact-trims", action="store_true", help="the trims at the rates the bill gives")
    ap.add_argument("--exported", action="store_true",
                    help="MuJoCo's model from `springfit export --mujoco` instead of the script's own")
    ap.add_argument("--mujoco-friction", action="store_true",
                    help="keep MuJoCo's default friction time constant (0.02 s: the friction lags each reversal)")
    ap.add_argument("--no-tune", action="store_true", help="stop after the identification")
    ap.add_argument("--check", action="store_true",
                    help="exit 1 unless the identified delta are within 0.5 %% rms (--max-rms) and 3 sigma, the "
                         "damping within 10 %%, and tuning from them leaves the arm's equilibrium within 1e-3 rad and "
                         "its p99 within 10 %% of tuning from the true rates")
    ap.add_argument("--max-rms", type=float, default=0.005, help="the rms bound of --check (default 0.005)")
    ap.add_argument("--max-error", type=float, help="with --check, also a bound on every identified delta's error")
    ap.add_argument("--max-damping-error", type=float, default=0.1,
                    help="the bound of --check on the damping's error, a fraction (default 0.1)")
    args = ap.parse_args()
    out = Path(args.out)
    binary = Path(args.springfit)
    rng = np.random.default_rng(args.seed)
    sf = lambda *a: springfit(binary, args.threads, *a)
    design = args.design
    try:
        if out.exists():
            shutil.rmtree(out)
        out.mkdir(parents=True)
        if args.bom:
            bom = Path(args.bom)
        else:
            sf("fit", design, "--out", out / "fit")
            bom = out / "fit/bom.csv"
        truth = draw_build(bom, out / "build", args.tolerance, rng, args.exact_trims)
        sf("identify", design, "--bom", bom, "--plan", "--out", out / "plan")
        plan = json.loads((out / "plan/plan.json").read_text())
        if args.exported:
            # A build's rates hold its own equilibrium, not q_eq: a copy of the design lets its bill
            # through (`[equilibrium] bill_tolerance`) for the export.
            sf("export", tolerant_copy(design, out / "build"), "--bom", out / "build/built.csv", "--mujoco", "--out", out / "mj")
            model = mujoco.MjModel.from_xml_path(str(next((out / "mj").glob("*.xml"))))
            passive = Passive(model)
            callback = passive if len(passive) else None
        else:
            model, callback = independent_model(design, out / "build/built.csv", 1.0 / plan["rate_hz"])
    except Failed as e:
        print(f"identify_mujoco: {e}", file=sys.stderr)
        return 2

    model.opt.timestep = 1.0 / plan["rate_hz"]
    model.dof_damping[:] = args.damping
    model.dof_frictionloss[:] = args.friction
    if not args.mujoco_friction:
        model.dof_solref[:, 0] = 2.0 * model.opt.timestep
    mujoco.set_mjcb_passive(callback)
    n = model.nq
    free_seconds = max(0.0, args.seconds - args.driven)
    runs, used = [], 0.0
    for r in plan["releases"]:
        for _ in range(r["releases"]):
            length = min(r["seconds"], free_seconds - used)
            if length < 2.5:
                break
            t, q, _ = simulate(model, np.array(r["q0"]), length, None, rng, args.bits, args.noise, 0.0)
            runs.append((f"release{len(runs) + 1}", t, q, None))
            used += length
    logs = []
    if runs:
        write_log(out / "free.csv", runs, False)
        logs.append(out / "free.csv")
    q_eq = None
    if args.driven > 0:
        q_eq = np.array(json.loads(sf("check", design, "--json"))["q_eq"])
        drive = multisine(n, args.drive, rng, args.driven)
        t, q, tau = simulate(model, q_eq, args.driven, drive, rng, args.bits, args.noise, args.torque_noise)
        write_log(out / "driven.csv", [("driven", t, q, tau)], True)
        logs.append(out / "driven.csv")
    mujoco.set_mjcb_passive(None)

    try:
        sf("identify", design, "--bom", bom, "--log", *logs, "--out", out / "identify")
    except Failed as e:
        print(f"identify_mujoco: {e}", file=sys.stderr)
        return 2
    ident = json.loads((out / "identify/identify.json").read_text())
    rows = []
    for r in ident["rates"]:
        true = truth[r["id"]]
        se = r["standard_error"]
        ok = r["status"] == "identified"
        rows.append({"id": r["id"], "true": true, "delta": r["delta"] if ok else None, "se": se,
                     "z": (r["delta"] - true) / se if ok and se else None, "identified": ok,
                     "for_tuning": r["for_tuning"]})
    combos = []
    for g, group in enumerate(ident["groups"]):
        for c in group["identified"]:
            true = sum(w * truth[i] for i, w in c["weights"])
            combos.append({"group": g + 1, "weights": c["weights"], "value": c["value"], "se": c["standard_error"],
                           "true": true, "z": (c["value"] - true) / c["standard_error"]})
    unaccounted = [r["id"] for r in ident["rates"] if r["status"] != "identified"
                   and r["id"] not in ident["groups"][r["status"]["group"]]["members"]]
    good = [r for r in rows if r["identified"]]
    rms = math.sqrt(sum((r["delta"] - r["true"]) ** 2 for r in good) / len(good)) if good else float("nan")
    worst_z = max((abs(r["z"]) for r in good), default=float("nan"))
    worst_combo_z = max((abs(c["z"]) for c in combos), default=0.0)
    worst_error = max((abs(r["delta"] - r["true"]) for r in good), default=float("nan"))
    joints = []
    for j in ident["joints"]:
        d = j["damping"]["value"] if j.get("damping") else None
        f = j["friction"]["value"] if j.get("friction") else None
        joints.append({"joint": j["joint"], "damping": d, "friction": f,
                       "damping_error": None if d is None else d / args.damping - 1.0})
    summary = {
        "design": design, "seed": args.seed, "tolerance": args.tolerance, "damping": args.damping,
        "friction": args.friction, "encoder_bits": args.bits, "encoder_noise_counts": args.noise,
        "log_seconds": used + (args.driven if args.driven > 0 else 0.0), "releases": len(runs),
        "driven_seconds": args.driven, "rates": rows, "identified": len(good), "parts": len(rows),
        "rms_delta_error": rms, "largest_delta_error": worst_error, "largest_z": worst_z, "joints": joints,
        "groups": ident["groups"], "combinations": combos, "largest_combination_z": worst_combo_z,
        "unaccounted": unaccounted, "condition": ident["condition"], "independent_model": not args.exported,
    }
    print(f"{design}: {len(runs)} releases + {args.driven:g} s driven = {summary['log_seconds']:.1f} s at "
          f"{plan['rate_hz']:g} Hz, {args.bits}-bit encoder; damping {args.damping}, friction {args.friction}")
    print("part   true δ      identified δ ± se        z")
    for r in rows:
        if r["identified"]:
            print(f"{r['id']:6s} {100 * r['true']:+7.3f} %  {100 * r['delta']:+7.3f} % ± {100 * r['se']:.3f} %  {r['z']:+5.2f}")
        else:
            print(f"{r['id']:6s} {100 * r['true']:+7.3f} %  not identified (for tune {100 * r['for_tuning']:+.3f} %)")
    print(f"identified {len(good)} of {len(rows)} parts: rms error {100 * rms:.3f} % of the rate, largest "
          f"{100 * worst_error:.3f} %, largest |z| {worst_z:.2f}")
    for c in combos:
        text = " ".join(f"{w:+.4f} {i}" for i, w in c["weights"])
        print(f"group {c['group']}: {text} = {100 * c['value']:+.3f} % ± {100 * c['se']:.3f} % (true "
              f"{100 * c['true']:+.3f} %, z {c['z']:+.2f})")
    for j in joints:
        if j["damping"] is not None:
            print(f"{j['joint']}: damping {j['damping']:.5f} ({100 * j['damping_error']:+.2f} %), friction "
                  f"{j['friction'] if j['friction'] is not None else float('nan'):.5f} N*m")

    if not args.no_tune:
        try:
            true_rates = {}
            header, bom_rows = read_bom(bom)
            col = {c: i for i, c in enumerate(header)}
            for r in bom_rows:
                true_rates[r[col["id"]]] = float(r[col["stiffness"]]) * (1.0 + truth[r[col["id"]]])
            measured_bill(bom, out / "tune_true_input/measured.csv", true_rates)
            sf("tune", design, "--measured", out / "tune_true_input/measured.csv", "--out", out / "tune_true")
            sf("tune", design, "--measured", out / "identify/identified.csv", "--out", out / "tune_identified")
            # The arm as built with the settings tuned from the identified rates: its true rates
            # read into the tuned bill (trims as tune set them), judged by tune's "before".
            tuned_rates = {}
            header, tuned_rows = read_bom(out / "tune_identified/bom_tuned.csv")
            col = {c: i for i, c in enumerate(header)}
            for r in tuned_rows:
                if r[col["trim_min"]] == "" and r[col["id"]] in true_rates:
                    tuned_rates[r[col["id"]]] = true_rates[r[col["id"]]]
            measured_bill(out / "tune_identified/bom_tuned.csv", out / "tune_check_input/measured.csv", tuned_rates)
            sf("tune", design, "--measured", out / "tune_check_input/measured.csv", "--out", out / "tune_check")
        except Failed as e:
            print(f"identify_mujoco: {e}", file=sys.stderr)
            return 2
        true_tune = json.loads((out / "tune_true/tune.json").read_text())
        check = json.loads((out / "tune_check/tune.json").read_text())
        summary["tune"] = {
            "true_rates": true_tune["after"],
            "identified_rates_on_the_true_arm": check["before"],
            "p99_ratio": check["before"]["p99_deg"] / true_tune["after"]["p99_deg"],
        }
        print(f"tune from the true rates: p99 {true_tune['after']['p99_deg']:.4f}°, shift {true_tune['after']['shift_rad']:.2e} rad")
        print(f"tune from the identified rates, on the true arm: p99 {check['before']['p99_deg']:.4f}° "
              f"({100 * (summary['tune']['p99_ratio'] - 1):+.2f} %), shift {check['before']['shift_rad']:.2e} rad")

    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    if args.check:
        failures = []
        if not (rms <= args.max_rms):
            failures.append(f"rms delta error {rms:.4f} > {args.max_rms}")
        if args.max_error is not None and not (worst_error <= args.max_error):
            failures.append(f"largest delta error {worst_error:.4f} > {args.max_error}")
        if not (worst_z <= 3.0):
            failures.append(f"largest |z| {worst_z:.2f} > 3")
        if not (worst_combo_z <= 3.0):
            failures.append(f"largest |z| of a group combination {worst_combo_z:.2f} > 3")
        if unaccounted:
            failures.append(f"parts neither identified nor in a group: {unaccounted}")
        for j in joints:
            if j["damping_error"] is not None and abs(j["damping_error"]) > args.max_damping_error:
                failures.append(f"{j['joint']} damping off by {100 * j['damping_error']:+.1f} %")
        if "tune" in summary:
            t = summary["tune"]
            shift = t["identified_rates_on_the_true_arm"]["shift_rad"] - t["true_rates"]["shift_rad"]
            if abs(shift) > 1e-3:
                failures.append(f"equilibrium shift {shift:+.2e} rad from tuning with the true rates")
            if abs(t["p99_ratio"] - 1.0) > 0.1:
                failures.append(f"p99 {100 * (t['p99_ratio'] - 1):+.1f} % from tuning with the true rates")
        print("PASS" if not failures else "FAIL: " + "; ".join(failures))
        return 0 if not failures else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
