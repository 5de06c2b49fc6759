#!/usr/bin/env python3
"""Replays springfit's free releases in MuJoCo and compares the joint angles.

Usage:
    python3 scripts/verify_mujoco.py MODEL.xml SIM_FREE.csv [--duration 5] [--tolerance TOL]

MODEL.xml is the output of `springfit export DESIGN --bom BOM --mujoco`; SIM_FREE.csv the output
of `springfit simulate DESIGN --scenario free --bom BOM` with the same bill of materials. Each run
of the CSV (column `run`) starts from rest at its first sample; MuJoCo integrates it with the
model's own RK4 step, and q(t) is compared with springfit's at every sample up to --duration
seconds. Elements MuJoCo cannot represent exactly are listed in the model as
`<numeric name="springfit_callback_...">` entries [code, k, x0, a1..an] and cams as
`<numeric name="springfit_cam_...">` entries [N, h, x_lo, a1..an, c0..c_{N+1}], and applied
through `mjcb_passive`, which MuJoCo calls at every RK4 stage, so the scheme stays the same as
springfit's (`Passive` below; scripts/identify_mujoco.py imports it).

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
CAM_PREFIX = "springfit_cam_"
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


def numerics(model, prefix):
    """The model's `<numeric>` entries named prefix + NAME: (NAME, data)."""
    out = []
    for i in range(model.nnumeric):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_NUMERIC, i)
        if name.startswith(prefix):
            adr, size = model.numeric_adr[i], model.numeric_size[i]
            out.append((name[len(prefix):], np.array(model.numeric_data[adr:adr + size], dtype=float)))
    return out


def callbacks(model):
    """The callback elements of the model: (name, code, k, x0, a)."""
    out = []
    for name, data in numerics(model, CALLBACK_PREFIX):
        if len(data) != 3 + model.nq:
            raise ValueError(f"{name}: expected {3 + model.nq} numbers, got {len(data)}")
        out.append((name, int(data[0]), float(data[1]), float(data[2]), data[3:]))
    return out


def cams(model):
    """The cams of the model: (name, knots N, spacing h, first knot, a, coefficients c)."""
    out = []
    for name, data in numerics(model, CAM_PREFIX):
        count = int(data[0]) if len(data) else 0
        if count < 4 or len(data) != 3 + model.nq + count + 2:
            raise ValueError(f"{name}: expected N >= 4 and 3 + {model.nq} + N + 2 numbers, got {len(data)}")
        out.append((name, count, float(data[1]), float(data[2]), data[3:3 + model.nq], data[3 + model.nq:]))
    return out


def cam_eval(count, h, lo, c, x):
    """V(x) and V'(x) of the cam V = sum_j c_j B_j(x - lo), as springfit's `spline_sum`: inside the
    knot span the four cubic pieces, beyond it the second-order Taylor polynomial at the end."""
    t = (x - lo) / h
    end = min(max(t, 0.0), count - 1.0)
    dt = t - end
    i0 = min(int(math.floor(end)), count - 2)
    u = end - i0
    w = 1.0 - u
    c0, c1, c2, c3 = c[i0:i0 + 4]
    b = (c0 * w ** 3 + c1 * (3 * u ** 3 - 6 * u * u + 4) + c2 * (3 * w ** 3 - 6 * w * w + 4) + c3 * u ** 3) / 6.0
    b1 = 0.5 * (-c0 * w * w + c1 * (3 * u * u - 4 * u) - c2 * (3 * w * w - 4 * w) + c3 * u * u)
    b2 = c0 * w + c1 * (3 * u - 2) + c2 * (3 * w - 2) + c3 * u
    return b + dt * (b1 + 0.5 * dt * b2), (b1 + dt * b2) / h


class Passive:
    """The springs MuJoCo cannot represent itself, applied in `mjcb_passive`: the callback elements
    as arrays (a few numpy operations per call) and the cams one by one."""

    def __init__(self, model):
        cbs = callbacks(model)
        self.cams = cams(model)
        self.names = [c[0] for c in cbs] + [c[0] for c in self.cams]
        self.codes = np.array([c[1] for c in cbs], dtype=int)
        self.stiff = np.array([c[2] for c in cbs])
        self.x0 = np.array([c[3] for c in cbs])
        self.a = np.array([c[4] for c in cbs]).reshape(len(cbs), model.nq)

    def __len__(self):
        return len(self.names)

    def slopes(self, d):
        codes = self.codes
        return np.select(
            [codes == 1, codes == 2, codes == 3, codes == 4, codes == 5],
            [d, d ** 3, np.sin(d), np.maximum(d, 0.0), np.minimum(d, 0.0)],
        )

    def __call__(self, m, d):
        if len(self.codes):
            d.qfrc_passive[:] -= self.a.T @ (self.stiff * self.slopes(self.a @ d.qpos - self.x0))
        for _, count, h, lo, a, c in self.cams:
            d.qfrc_passive[:] -= a * cam_eval(count, h, lo, c, float(a @ d.qpos))[1]

    def energy(self, q):
        e = sum(k * value(int(c), float(dd)) for c, k, dd in zip(self.codes, self.stiff, self.a @ q - self.x0))
        return e + sum(cam_eval(count, h, lo, c, float(a @ q))[0] for _, count, h, lo, a, c in self.cams)

    def install(self):
        mujoco.set_mjcb_passive(self if len(self) else None)


def passive_callback(model):
    """The model's springs MuJoCo cannot represent itself (callback elements and cams) as MuJoCo's
    `mjcb_passive` and their potential energy: (passive(m, d), energy(q))."""
    springs = Passive(model)
    return springs, springs.energy


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
        cbs = Passive(model)
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

    cbs.install()
    callback_energy = cbs.energy
    h = model.opt.timestep
    print(f"{args.model}: {model.nq} joints, {model.ntendon} tendons, {len(cbs)} callback elements "
          f"({', '.join(cbs.names) or 'none'}); RK4 step {h} s; {len(runs)} runs over {args.duration} s")
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
