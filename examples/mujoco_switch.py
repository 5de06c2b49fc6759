#!/usr/bin/env python3
"""Drives the exported MuJoCo model with springfit.Controller through the paper's mode switch.

    python3 examples/mujoco_switch.py [--loop hold|stage] [--out out/python_mujoco]
        [--design designs/double_pendulum.toml] [--scenario switch]

Fits the design (default: the paper's double pendulum), exports it (`springfit export
--mujoco`), and runs its switch scenario in MuJoCo: on the default design θ_d steps by π/6 every
15 s for 100 s while τ_E holds E_d = 10 J; on an arm of three or more joints the scenario's
`modes = [[…], …]` are visited in turn (e.g. an arm from `random_arm.py` with a switch through
five directions, docs/simulation.md). The motor torques come from `Controller.torque`, the very
code `springfit simulate` runs:

* `--loop hold` (default): as a robot's 1 kHz loop does, the torque is computed from the state
  at the start of each MuJoCo step and held over it (`qfrc_applied`);
* `--loop stage`: the torque is added in MuJoCo's passive-force callback, at every RK4 stage,
  as springfit's simulator applies it.

Springs MuJoCo has no element for are applied through the same callback as
scripts/verify_mujoco.py does. Prints each mode step's settling time (mode error below 3° for
the rest of the step) next to `simulate`'s, and the largest motor torque, and exits 1 when a step
never settles in MuJoCo or its time differs from `simulate`'s by more than 10 % (or 0.1 s, for
steps that settle within a second).
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


def run(design, fit, xml, loop, scenario):
    """The switch scenario in MuJoCo: its settling times and the largest motor torque."""
    model = mujoco.MjModel.from_xml_path(str(xml))
    data = mujoco.MjData(model)
    controller = springfit.Controller(design, fit, scenario=scenario)
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
    peak = 0.0
    try:
        for k in range(steps + 1):
            t = k * h
            out = controller.torque(data.qpos, data.qvel, t)
            if k % every == 0:
                samples.append((t, out.label, out.label_target, out.in_ball))
            if k == steps:
                break
            peak = max(peak, float(np.max(np.abs(out.tau))))
            data.qfrc_applied[:] = out.tau if loop == "hold" else 0.0
            mujoco.mj_step(model, data)
    finally:
        mujoco.set_mjcb_passive(None)
    t, label, target, in_ball = (list(x) for x in zip(*samples))
    two = len(q0) == 2
    settling = springfit.settling_times(t, label, target, in_ball, controller.mode_steps, controller.duration, two)
    return settling, controller.mode_steps, peak


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--loop", choices=["hold", "stage"], default="hold")
    ap.add_argument("--out", default="out/python_mujoco")
    ap.add_argument("--design", default=str(REPO / "designs" / "double_pendulum.toml"))
    ap.add_argument("--scenario", default="switch")
    args = ap.parse_args()
    design = springfit.Design.load(args.design)
    fit = design.fit()
    xml = design.export_mujoco(args.out, springs=fit, overwrite_edits=True)
    sim = design.simulate(scenario=args.scenario, springs=fit).summary(args.scenario)["runs"]["switch"]
    want = sim["settling_s"]
    got, starts, peak = run(design, fit, xml, args.loop, args.scenario)
    how = "step (1 kHz, held)" if args.loop == "hold" else "RK4 stage"
    print(f"{xml}: scenario {args.scenario}, controller applied per {how}")
    print("step     from   simulate   MuJoCo   difference")
    ok = len(got) == len(want)
    worst = 0.0
    for k, (a, b) in enumerate(zip(want, got)):
        if a is None or b is None:
            diff, rel = (0.0, 0.0) if a is None and b is None else (math.inf, math.inf)
        else:
            diff, rel = abs(b - a), abs(b - a) / max(a, 1e-9)
        ok = ok and b is not None and (rel <= 0.10 or diff <= 0.1)
        worst = max(worst, rel)
        fa = "never" if a is None else f"{a:.2f} s"
        fb = "never" if b is None else f"{b:.2f} s"
        print(f"{k + 1:>4}  {starts[k]:>5.0f} s  {fa:>8}  {fb:>8}  {100 * rel:7.2f} %")
    print(f"largest motor torque in MuJoCo {peak:.2f} N·m (simulate: {sim['peak_actuator_torque_nm']:.2f} N·m), "
          f"actuator share in simulate {100 * sim['actuator_share']:.2f} %, "
          f"energy saved against the arm without springs {100 * sim['savings']['energy_saved']:.1f} %")
    print(f"{'PASS' if ok else 'FAIL'}: largest settling-time difference {100 * worst:.2f} % (limit 10 % or 0.1 s)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
