#!/usr/bin/env python3
"""Reference mass matrices, gravity torques and Coriolis terms of the shipped UR5 from Pinocchio.

springfit's spatial chain (CRBA + RNEA, src/model/spatial.rs) and URDF reader
(src/model/urdf.rs) are checked against an independent rigid-body library: Pinocchio reads
robots/ur5/ur5_robot.urdf, locks the joints springfit holds (buildReducedModel) and evaluates, at
random configurations,

  mass_matrix     M(q)                       (pinocchio.crba, symmetrised)
  gravity_torque  ∂U_g/∂q = g(q)             (pinocchio.computeGeneralizedGravity, g = (0, 0, -9.81))
  coriolis        h(q, v) = C(q, v) v         (pinocchio.rnea with zero gravity and zero acceleration)

Written to tests/fixtures/ur5_pinocchio.json; tests/urdf_model.rs compares to 1e-9 relative.

Usage (Pinocchio is the PyPI package `pin`):
  python3 -m venv /tmp/pinenv && /tmp/pinenv/bin/pip install pin==4.1.0 numpy
  /tmp/pinenv/bin/python scripts/make_urdf_fixtures.py
"""

import json
import pathlib

import numpy as np
import pinocchio as pin

ROOT = pathlib.Path(__file__).resolve().parent.parent
URDF = ROOT / "robots" / "ur5" / "ur5_robot.urdf"
OUT = ROOT / "tests" / "fixtures" / "ur5_pinocchio.json"
GRAVITY = [0.0, 0.0, -9.81]

# (moving joints from the base outwards, held joints and their angles in rad)
CASES = [
    (["shoulder_lift_joint", "elbow_joint"],
     {"shoulder_pan_joint": 0.0, "wrist_1_joint": -np.pi / 2, "wrist_2_joint": 0.0, "wrist_3_joint": 0.0}),
    (["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint"],
     {"wrist_1_joint": -np.pi / 2, "wrist_2_joint": 0.0, "wrist_3_joint": 0.0}),
    (["shoulder_lift_joint", "elbow_joint", "wrist_1_joint"],
     {"shoulder_pan_joint": 0.7, "wrist_2_joint": -1.1, "wrist_3_joint": 0.4}),
    (["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"],
     {}),
]
POINTS = 8


def main():
    full = pin.buildModelFromUrdf(str(URDF))
    rng = np.random.default_rng(20261201)
    out = {
        "source": "scripts/make_urdf_fixtures.py",
        "pinocchio": pin.__version__,
        "urdf": "robots/ur5/ur5_robot.urdf",
        "gravity": GRAVITY,
        "cases": [],
    }
    for joints, locked in CASES:
        q_ref = pin.neutral(full)
        lock_ids = []
        for name, value in locked.items():
            jid = full.getJointId(name)
            q_ref[full.joints[jid].idx_q] = value
            lock_ids.append(jid)
        model = pin.buildReducedModel(full, lock_ids, q_ref) if lock_ids else full
        names = [model.names[i] for i in range(1, model.njoints)]
        assert names == joints, (names, joints)
        model.gravity.linear = np.array(GRAVITY)
        data = model.createData()
        zero_g = model.copy()
        zero_g.gravity.linear = np.zeros(3)
        zdata = zero_g.createData()
        points = []
        for _ in range(POINTS):
            q = rng.uniform(-np.pi, np.pi, model.nq)
            v = rng.uniform(-2.0, 2.0, model.nv)
            m = pin.crba(model, data, q)
            m = np.triu(m) + np.triu(m, 1).T
            g = pin.computeGeneralizedGravity(model, data, q)
            h = pin.rnea(zero_g, zdata, q, v, np.zeros(model.nv))
            points.append({
                "q": q.tolist(),
                "v": v.tolist(),
                "mass_matrix": m.tolist(),
                "gravity_torque": g.tolist(),
                "coriolis": h.tolist(),
            })
        out["cases"].append({"joints": joints, "locked": locked, "points": points})
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {OUT.relative_to(ROOT)}: {len(CASES)} joint sets × {POINTS} configurations")


if __name__ == "__main__":
    main()
