#!/usr/bin/env python3
"""Drives the exported MuJoCo model with springfit.Controller through the paper's mode switch.

    python3 examples/mujoco_switch.py [--loop hold|stage] [--out out/python_mujoco]

Fits the default design, exports it (`springfit export --mujoco`), and runs the `switch`
scenario in MuJoCo: θ_d steps by π/6 every 15 s for 100 s while τ_E holds E_d = 10 J. The
motor torques come from `Controller.torque`, the very code `springfit simulate` runs:

* `--loop hold` (default): as a robot's 1 kHz loop does, the torque is computed from the state
  at the start of each MuJoCo step and held over it (`qfrc_applied`);
* `--loop stage`: the torque is added in MuJoCo's passive-force callback, at every RK4 stage,
  as springfit's simulator applies it.

Springs MuJoCo has no element for are applied through the same callback as
scripts/verify_mujoco.py does. Prints each mode step's settling time (label within 3° of θ_d
for the rest of the step) next to `simulate`'s and exits 1 when one differs by more than 10 %.
Needs `pip install ./python 'mujoco>=3.7'`.
"""

import argparse
import math
import pathlib
import sys

import mujoco
import numpy as np

import springfit

REPO = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))
from verify_mujoco import passive_callback  # noqa: E402  (the project's callback springs)


def run(design, fit, xml, loop):
    """The switch scenario in MuJoCo: samples every 10 ms of (t, label, label_target, in_ball)."""
    model = mujoco.MjModel.from_xml_path(str(xml))
    data = mujoco.MjData(model)
    controller = springfit.Controller(design, fit, scenario="switch")
    q0, qd0 = controller.start
    data.qpos[:], data.qvel[:] = q0, qd0
    springs, _ = passive_callback(model)

    def passive(m, d):
        springs(m, d)
        if loop == "stage":
            d.qfrc_passive[:] += controller.torque(d.qpos, d.qvel, d.time).tau

    mujoco.set_mjcb_passive(passive)
    h = model.opt.timestep
    steps = round(controller.duration / h)
    every = round(0.01 / h)
    samples = []
    try:
        for k in range(steps + 1):
            t = k * h
            out = controller.torque(data.qpos, data.qvel, t)
            if k % every == 0:
                samples.append((t, out.label, out.label_target, out.in_ball))
            if k == steps:
                break
            data.qfrc_applied[:] = out.tau if loop == "hold" else 0.0
            mujoco.mj_step(model, data)
    finally:
        mujoco.set_mjcb_passive(None)
    t, label, target, in_ball = (list(x) for x in zip(*samples))
    return springfit.settling_times(t, label, target, in_ball, controller.mode_steps, controller.duration)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--loop", choices=["hold", "stage"], default="hold")
    ap.add_argument("--out", default="out/python_mujoco")
    args = ap.parse_args()
    design = springfit.Design.load(REPO / "designs" / "double_pendulum.toml")
    fit = design.fit()
    xml = design.export_mujoco(args.out, springs=fit, overwrite_edits=True)
    want = design.simulate(scenario="switch", springs=fit).summary("switch")["runs"]["switch"]["settling_s"]
    got = run(design, fit, xml, args.loop)
    print(f"{xml}: switch scenario, controller applied per {'step (1 kHz, held)' if args.loop == 'hold' else 'RK4 stage'}")
    print("step  θ_d from   simulate   MuJoCo   difference")
    worst = 0.0
    for k, (a, b) in enumerate(zip(want, got)):
        if a is None or b is None:
            rel = 0.0 if a is None and b is None else math.inf
        else:
            rel = abs(b - a) / max(a, 1e-9)
        worst = max(worst, rel)
        fa = "never" if a is None else f"{a:.2f} s"
        fb = "never" if b is None else f"{b:.2f} s"
        print(f"{k + 1:>4}  {15.0 * k:>7.0f} s  {fa:>8}  {fb:>8}  {100 * rel:7.2f} %")
    ok = worst <= 0.10 and len(got) == len(want)
    print(f"{'PASS' if ok else 'FAIL'}: largest settling-time difference {100 * worst:.2f} % (limit 10 %)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
