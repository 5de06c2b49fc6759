#!/usr/bin/env python3
"""A robot from example-robot-data: the UR5's shoulder lift and elbow, fitted from Python.

    python3 examples/urdf_robot.py [--out out/python_ur5]

Reads the UR5 URDF that the `example-robot-data` pip package installs, writes the design in
memory (the two joints that move, the others held, gravity, the equilibrium and region of
designs/ur5_lift_elbow.toml), checks it, fits springs from catalogs/ur5_lift_elbow.toml and
prints the mass matrix at the equilibrium, the largest valid region and the fit's residuals.
Needs `pip install ./python example-robot-data`.
"""

import argparse
import importlib.metadata
import pathlib

import numpy as np

import springfit

REPO = pathlib.Path(__file__).resolve().parents[1]


def ur5_urdf():
    """The UR5 URDF of the example-robot-data package (installed as data, no Python module)."""
    for f in importlib.metadata.files("example-robot-data") or []:
        if f.name == "ur5_robot.urdf":
            return pathlib.Path(f.locate()).resolve()
    raise SystemExit("example-robot-data has no ur5_robot.urdf: `pip install example-robot-data`")


DESIGN = """
name = "ur5_lift_elbow_python"
description = "UR5 from example-robot-data: shoulder lift + elbow with gravity"
catalog = "{catalog}"

[robot]
urdf = "{urdf}"
joints = ["shoulder_lift_joint", "elbow_joint"]
locked = {{ shoulder_pan_joint = 0.0, wrist_1_joint = "-pi/2", wrist_2_joint = 0.0, wrist_3_joint = 0.0 }}
gravity = [0.0, 0.0, -9.81]

[equilibrium]
q = ["-pi/4", "pi/2"]

[region]
kind = "ball"
radius = 0.8

[fit]
frequency = 6.0
solver = "qp"
max_elements = 12
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out/python_ur5")
    args = ap.parse_args()
    urdf = ur5_urdf()
    text = DESIGN.format(urdf=urdf.as_posix(), catalog=(REPO / "catalogs" / "ur5_lift_elbow.toml").as_posix())
    design = springfit.Design.from_toml(text, path=pathlib.Path(args.out) / "design.toml")
    check = design.check()
    print(f"{urdf}: joints {check['joints']}, q_eq {np.round(check['q_eq'], 4)}")
    print(f"mass matrix at q_eq:\n{np.round(check['mass_matrix'], 4)}")
    print(f"gravity torque at q_eq: {np.round(check['gravity_torque'], 3)} N·m; "
          f"largest valid ball radius {check['region']['largest_radius']:.3f}")
    fit = design.fit()
    s = fit.summary["residual_deg"]
    print(f"fit: {fit.used} springs, residual p99 {s['p99_abs']:.4f}°, max {s['max_abs']:.4f}°")
    # The springs hold the arm's weight at the equilibrium: ∇U_e + ∇U_g = 0 there.
    print(f"|∇U_e + ∇U_g| at q_eq: {np.linalg.norm(fit.potential.gradient(design.q_eq) + design.gravity_gradient(design.q_eq)):.2e} N·m")
    print(f"wrote {fit.write(args.out + '/fit', overwrite_edits=True)}")


if __name__ == "__main__":
    main()
