#!/usr/bin/env python3
"""Replays springfit's free releases in MuJoCo and compares the joint angles.

Usage:
    python3 scripts/verify_mujoco.py MODEL.xml SIM_FREE.csv [--duration 5] [--tolerance TOL]

MODEL.xml is the output of `springfit export DESIGN --bom BOM --mujoco`; SIM_FREE.csv the output
of `springfit simulate DESIGN --scenario free --bom BOM` with the same bill of materials. Each run
of the CSV (column `run`) starts from rest at its first sample; MuJoCo integrates it with the
model's own RK4 step, and q(t) is compared with springfit's at every sample up to --duration
seconds. Elements MuJoCo cannot represent exactly are listed in the model as
`<numeric name="springfit_callback_...">` entries [code, k, x0, a1..an] and applied through
`mjcb_passive`, which MuJoCo calls at every RK4 stage, so the scheme stays the same as
springfit's.

Prints, per run, the largest |q_mujoco - q_springfit| and MuJoCo's energy drift (largest
|E(t) - E(0)|, with the callback elements' potential added to MuJoCo's), then one summary line.
Exits 1 when the largest difference exceeds the tolerance: 1e-4 rad when every element is exact,
1e-3 rad with callbacks (unless --tolerance is given); 2 on bad input.
"""

import argparse
import csv
import math
import sys

try:
    import mujoco
    import numpy as np
except ImportError as e:  # pragma: no cover - reported, not tested
    print(f"verify_mujoco: {e}: install with `python3 -m pip install 'mujoco>=3.7' numpy`", file=sys.stderr)
    sys.exit(2)

CALLBACK_PREFIX = "springfit_callback_"
EXACT_TOLERANCE = 1e-4
CALLBACK_TOLERANCE = 1e-3


def value(code, d):
    """u(d) of the profile with this code."""
    if code == 1:
        return 0.5 * d * d
    if code == 2:
        return 0.25 * d ** 4
    if code == 3:
        return 1.0 - math.cos(d)
    if code == 4:
        return 0.5 * max(d, 0.0) ** 2
    if code == 5:
        return 0.5 * min(d, 0.0) ** 2
    raise ValueError(f"unknown profile code {code}")


def callbacks(model):
    """The callback elements of the model: (name, code, k, x0, a)."""
    out = []
    for i in range(model.nnumeric):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_NUMERIC, i)
        if not name.startswith(CALLBACK_PREFIX):
            continue
        adr, size = model.numeric_adr[i], model.numeric_size[i]
        data = model.numeric_data[adr:adr + size]
        if size != 3 + model.nq:
            raise ValueError(f"{name}: expected {3 + model.nq} numbers, got {size}")
        out.append((name[len(CALLBACK_PREFIX):], int(data[0]), float(data[1]), float(data[2]), np.array(data[3:])))
    return out


def passive_callback(model, cbs=None):
    """The model's callback elements as MuJoCo's `mjcb_passive` and their potential energy:
    (passive(m, d), energy(q)). `cbs` is `callbacks(model)` (read when not given)."""
    cbs = callbacks(model) if cbs is None else cbs
    # The callback elements as arrays, so one evaluation costs a few numpy operations.
    codes = np.array([c[1] for c in cbs], dtype=int)
    stiff = np.array([c[2] for c in cbs])
    x0 = np.array([c[3] for c in cbs])
    a = np.array([c[4] for c in cbs]).reshape(len(cbs), model.nq)

    def slopes(d):
        return np.select(
            [codes == 1, codes == 2, codes == 3, codes == 4, codes == 5],
            [d, d ** 3, np.sin(d), np.maximum(d, 0.0), np.minimum(d, 0.0)],
        )

    def passive(m, d):
        d.qfrc_passive[:] -= a.T @ (stiff * slopes(a @ d.qpos - x0))

    def callback_energy(q):
        return sum(k * value(int(c), float(dd)) for c, k, dd in zip(codes, stiff, a @ q - x0))

    return passive, callback_energy


def read_runs(path, nq):
    """springfit's samples per run: {run: (t, q)} with t of shape (k,) and q of shape (k, nq)."""
    runs = {}
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        cols = [f"q{i + 1}" for i in range(nq)]
        missing = [c for c in ["run", "t"] + cols if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"{path}: missing columns {missing} (a sim CSV of a {nq}-joint design expected)")
        for row in reader:
            t, q = runs.setdefault(row["run"], ([], []))
            t.append(float(row["t"]))
            q.append([float(row[c]) for c in cols])
    return {k: (np.array(t), np.array(q)) for k, (t, q) in runs.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("sim_csv")
    ap.add_argument("--duration", type=float, default=5.0, help="seconds compared (default 5)")
    ap.add_argument("--tolerance", type=float, help="rad (default 1e-4 all exact, 1e-3 with callbacks)")
    args = ap.parse_args()
    try:
        model = mujoco.MjModel.from_xml_path(args.model)
        cbs = callbacks(model)
        runs = read_runs(args.sim_csv, model.nq)
    except (ValueError, OSError) as e:
        print(f"verify_mujoco: {e}", file=sys.stderr)
        return 2
    if not runs:
        print(f"verify_mujoco: {args.sim_csv}: no samples", file=sys.stderr)
        return 2
    if model.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4:
        print("verify_mujoco: the model does not use RK4; the comparison assumes springfit's scheme", file=sys.stderr)
    tol = args.tolerance or (CALLBACK_TOLERANCE if cbs else EXACT_TOLERANCE)

    passive, callback_energy = passive_callback(model, cbs)

    mujoco.set_mjcb_passive(passive if cbs else None)
    h = model.opt.timestep
    print(f"{args.model}: {model.nq} joints, {model.ntendon} tendons, {len(cbs)} callback elements "
          f"({', '.join(c[0] for c in cbs) or 'none'}); RK4 step {h} s; {len(runs)} runs over {args.duration} s")
    worst, worst_drift = 0.0, 0.0
    try:
        for name, (t, q_ref) in runs.items():
            keep = t <= args.duration + 1e-9
            t, q_ref = t[keep], q_ref[keep]
            steps = np.rint(t / h).astype(int)
            if np.any(np.abs(steps * h - t) > 1e-6 * h):
                print(f"verify_mujoco: {name}: sample times are not multiples of the step {h}", file=sys.stderr)
                return 2
            data = mujoco.MjData(model)
            data.qpos[:] = q_ref[0]
            data.qvel[:] = 0.0
            mujoco.mj_forward(model, data)
            e0 = data.energy[0] + data.energy[1] + callback_energy(data.qpos)
            diff, drift, done = 0.0, 0.0, 0
            for k, q_want in zip(steps, q_ref):
                while done < k:
                    mujoco.mj_step(model, data)
                    done += 1
                mujoco.mj_forward(model, data)  # energy of this state (mj_step's is the step's start)
                diff = max(diff, float(np.max(np.abs(data.qpos - q_want))))
                e = data.energy[0] + data.energy[1] + callback_energy(data.qpos)
                drift = max(drift, abs(e - e0))
            worst, worst_drift = max(worst, diff), max(worst_drift, drift)
            print(f"  {name}: max |q_mujoco - q_springfit| = {diff:.3e} rad, energy drift {drift:.3e} J (E0 = {e0:.6g} J)")
    finally:
        mujoco.set_mjcb_passive(None)
    ok = worst <= tol
    print(f"{'PASS' if ok else 'FAIL'}: largest difference {worst:.3e} rad over {args.duration} s "
          f"(tolerance {tol:g} rad, {'with callbacks' if cbs else 'all elements exact'}); "
          f"largest MuJoCo energy drift {worst_drift:.3e} J")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
