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
scripts/verify_mujoco.py does. Prints the controllers' gains (derived from the arm where the
design leaves them out), each mode step's settling time (mode error below 3° for the rest of the
step) next to `simulate`'s, and from the MuJoCo run itself: the largest motor torque per joint
against `[controllers] max_torque`, the actuator share (∫|P_θ| + ∫|P_E|)/∫|P_U| and what the
springs save against the same motion without them (energy ∫|τᵀq̇| dt with τ_act against
τ_act + τ_spring, sums over the 1 kHz steps). Exits 1 when a step never settles in MuJoCo, its
time differs from `simulate`'s by more than 10 % (or 0.1 s, for steps that settle within a
second), a motor torque leaves the limits or the actuator share exceeds 5 %.
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
    """The switch scenario in MuJoCo: its settling times, the largest motor torque per joint and
    the run's powers (actuators, springs, and the actuators of the arm without springs)."""
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
    peak = np.zeros(len(q0))
    # ∫|P| dt over the steps: the actuators' laws, the springs, the actuators alone (τ_act) and on
    # the arm without springs (τ_act + τ_spring, τ_spring = −∂U_e/∂q).
    flux = {"laws": 0.0, "springs": 0.0, "with": 0.0, "without": 0.0}
    try:
        for k in range(steps + 1):
            t = k * h
            out = controller.torque(data.qpos, data.qvel, t)
            if k % every == 0:
                samples.append((t, out.label, out.label_target, out.in_ball))
            if k == steps:
                break
            qd = np.array(data.qvel)
            tau = np.array(out.tau)
            spring = -np.asarray(fit.potential.gradient(np.array(data.qpos)))
            flux["laws"] += (abs(np.dot(out.mode, qd)) + abs(np.dot(out.energy_torque, qd))) * h
            flux["springs"] += abs(np.dot(spring, qd)) * h
            flux["with"] += abs(np.dot(tau, qd)) * h
            flux["without"] += abs(np.dot(tau + spring, qd)) * h
            peak = np.maximum(peak, np.abs(tau))
            data.qfrc_applied[:] = out.tau if loop == "hold" else 0.0
            mujoco.mj_step(model, data)
    finally:
        mujoco.set_mjcb_passive(None)
    t, label, target, in_ball = (list(x) for x in zip(*samples))
    two = len(q0) == 2
    settling = springfit.settling_times(t, label, target, in_ball, controller.mode_steps, controller.duration, two)
    return settling, controller.mode_steps, peak, flux


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
    simulation = design.simulate(scenario=args.scenario, springs=fit)
    sim = simulation.summary(args.scenario)["runs"]["switch"]
    gains = simulation.gains
    want = sim["settling_s"]
    got, starts, peak, flux = run(design, fit, xml, args.loop, args.scenario)
    how = "step (1 kHz, held)" if args.loop == "hold" else "RK4 stage"
    print(f"{xml}: scenario {args.scenario}, controller applied per {how}")
    print(f"gains: k_theta {gains['k_theta']:.4g}, epsilon {gains['epsilon']:.4g} rad, beta_e {gains['beta_e']:.4g}, "
          f"beta_nd {gains['beta_nd']:.4g}; from the arm: {', '.join(gains['from_arm']) or 'none'}")
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
    limits = design.controllers["max_torque"]
    within = limits is None or all(p <= m + 1e-9 for p, m in zip(peak, limits))
    share = flux["laws"] / max(flux["springs"], 1e-300)
    saved = 1.0 - flux["with"] / max(flux["without"], 1e-300)
    joints = ", ".join(f"{p:.2f}" for p in peak)
    bound = "no limit" if limits is None else "limits [" + ", ".join(f"{m:g}" for m in limits) + "]"
    print(f"largest motor torque per joint in MuJoCo [{joints}] N·m ({bound}; simulate: "
          f"{sim['peak_actuator_torque_nm']:.2f} N·m)")
    print(f"actuator share in MuJoCo {100 * share:.2f} % (simulate {100 * sim['actuator_share']:.2f} %); "
          f"energy saved against the arm without springs in MuJoCo {100 * saved:.1f} % "
          f"({flux['with']:.3f} J vs {flux['without']:.3f} J; simulate {100 * sim['savings']['energy_saved']:.1f} %)")
    settled = all(b is not None for b in got)
    ok = ok and settled and within and share <= 0.05
    print(f"{'PASS' if ok else 'FAIL'}: every step settles {'yes' if settled else 'no'}, largest settling-time "
          f"difference {100 * worst:.2f} % (limit 10 % or 0.1 s), torques within the limits "
          f"{'yes' if within else 'no'}, actuator share {100 * share:.2f} % (limit 5 %)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
