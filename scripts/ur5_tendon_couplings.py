#!/usr/bin/env python3
"""Which tendon couplings the six-joint UR5 needs: an unlimited fit of cams on every coupling a
tendon makes, ranked, then one cam on each of the 40 ranked first (with --write-catalogue, their
catalogue; no design on it is shipped: 4.3° p99, BENCHMARKS.md, "The UR5's six joints on 40
tendon cams without a selection").

Why. catalogs/ur5_tendons.toml (every tendon over 20/40 mm pulleys crossing two or three
consecutive joints, 148 cams of 30 knots, 9,472 columns) leaves the choice of 40 cams to the
sparse selection, which does not finish in minutes on it (BENCHMARKS.md, "Tendon catalogues").
A fit whose catalogue holds no more couplings than `max_elements` needs no selection: it is one
convex fit (the withdrawn 40-cam design took 16 s). So the choice is made once, here, by
measurement, and only among couplings a tendon makes within `[parts]`' pulley limits (10–40 mm)
and `max_joints_crossed = 6` (the default is 5): the Hessian the springs must give at q_eq,
ω²M − ∇²U_gravity, has a pan–wrist-3 entry that only a coupling turning both joints gives, and
a tendon turning both crosses all six. Without
the six-joint tendons the unlimited fit of the pool below misses that entry (Hessian relative
error 0.0044) and reaches p99 15.4° only, worse than springs alone (3.0°):

1. `pool`: a cam (8 knots, automatic smoothing) on each joint (6), on every tendon over 20/40 mm
   pulleys crossing two or three consecutive joints (the `tendons` family: 142 couplings), and on
   every tendon over equal pulleys crossing four, five or six consecutive joints, on either side
   (88: the pan-to-wrist couplings q1 ± (q2 + q3 + q4) ± q5 that designs/ur5_six.toml needed
   among them), fitted without a part limit;
2. halving: the couplings ranked by the summed peak torque of their cams (`bom.csv`
   `max_torque_nm`, as scripts/ur5_couplings.py ranks), the better half refitted alone (`pool118`,
   `pool59`), until a further half would hold fewer than 40; ranked once in a single fit, the
   first 40 reached p99 4.45° only (cams that cancel each other carry large torques);
3. `tendons40`: one cam of 30 knots on each of the 40 ranked first: the catalogue written.

What it found (2026-12-06, main 43bf1b7's release binary, --threads 1): `pool` p99 1.242° (236 cams, 21.66 kg
of springs on a 16.99 kg arm), `pool118` 2.190°, `pool59` 3.983°, `tendons40` 4.324° (19.59 kg):
ranking by torque does not find 40 couplings that come near the pool; the sparse selection would,
and is what does not finish on this pool yet.

Every fit uses the design's ball r = 0.6, 576 training and 720 held-out directions, `builds = 0`,
the release binary; figures are the held-out p99 of `summary.json`.

Run: python3 scripts/ur5_tendon_couplings.py [--springfit target/release/springfit] [--out DIR]
         [--threads 2] [--count 40] [--write-catalogue catalogs/ur5_tendons40.toml]
(A fit whose folder in DIR holds its summary.json is read, not rerun: a stopped run resumes.)
"""
import argparse
import collections
import csv
import json
import os
import re
import subprocess
import sys

from own_output import foreign

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, ".."))
JOINTS = 6

MARKER = "# Written by scripts/ur5_tendon_couplings.py"
CAM = """
[[family]]
name = "{name}"
profile = "cam"
unit = "J"
couplings = {couplings}
knots = {knots}
smoothing = "auto"
max_stroke = 16.0        # mm: the follower rate is chosen so the stroke stays within it
preload_fraction = 4.0
base_radius = 120.0      # mm
roller_radius = 8.0      # mm
max_pressure_angle = 30  # degrees
"""
HEADER = """\
# One B-spline cam on each of {count} tendon couplings of the UR5's six joints (`[parts] max_joints_crossed = 6`).
# Written by scripts/ur5_tendon_couplings.py (do not edit by hand: rerun it): a cam on each joint,
# on every tendon over 20/40 mm pulleys crossing 2-3 consecutive joints and on every tendon over
# equal pulleys crossing 4-6, fitted without a part limit, ranked by their cams' summed peak
# torque, the better half refitted until a further half is below {count}; the first {count}.
# Each coupling is a tendon over pulleys of 40 mm (entries ±1) and 20 mm (±0.5) at the joints it
# crosses, or a joint's own cam: `parts.csv` names its transmission.
name = "ur5_tendons{count}"
description = "A B-spline cam on each of {count} tendon couplings ranked by scripts/ur5_tendon_couplings.py"
"""


def equal_runs(lengths):
    """Every run of consecutive joints of the given lengths over equal pulleys, either side at
    each joint after the first (which crosses on the + side: x and −x are one element)."""
    out = []
    for m in lengths:
        for first in range(JOINTS - m + 1):
            for sides in range(2 ** (m - 1)):
                v = [0] * JOINTS
                v[first] = 1
                for i in range(1, m):
                    v[first + i] = -1 if (sides >> (m - 1 - i)) & 1 else 1
                out.append(v)
    return out


def rows(couplings):
    return "[\n  " + ",\n  ".join("[" + ", ".join(fmt(x) for x in c) + "]" for c in couplings) + ",\n]"


def fmt(x):
    return str(int(x)) if float(x).is_integer() else repr(float(x))


def pool_catalogue():
    text = 'name = "ur5_tendon_pool"\ndescription = "cams on every joint and tendon coupling"\n'
    text += CAM.format(name="joint cam", couplings='"joints"', knots=8)
    text += CAM.format(name="tendon cam", couplings="{ tendons = { radii_mm = [20, 40], max_crossed = 3 } }", knots=8)
    text += CAM.format(name="long tendon cam", couplings=rows(equal_runs([4, 5, 6])), knots=8)
    return text


def design(catalogue, max_elements):
    """designs/ur5_six.toml with the catalogue, the part limit and the sampling of the search.
    `accept_p99_deg = 180`: no fit here is judged poor, so none runs `fit`'s diagnosis (a refit of
    the whole pool for each screened coupling, which took longer than the fit on this pool)."""
    text = open(os.path.join(REPO, "designs", "ur5_six.toml")).read()
    text = re.sub(r'^catalog = ".*"$', f'catalog = "{catalogue}"', text, count=1, flags=re.M)
    text = text.replace('"../robots/', '"' + os.path.join(REPO, "robots") + "/")
    fit = (f"max_elements = {max_elements}\ntraining_directions = 576\n"
           "evaluation_directions = 720\nbuilds = 0\naccept_p99_deg = 180\n")
    text, n = re.subn(r"^max_elements = 40.*$\n", fit, text, count=1, flags=re.M)
    assert n == 1, "designs/ur5_six.toml has no `max_elements = 40` line"
    return text + "\n[parts]\nmax_joints_crossed = 6\n"


def fit(springfit, out, name, catalogue_text, max_elements, threads):
    cat = os.path.join(out, f"{name}_catalogue.toml")
    des = os.path.join(out, f"{name}.toml")
    open(cat, "w").write(catalogue_text)
    open(des, "w").write(design(cat, max_elements))
    res = os.path.join(out, name)
    # A fit whose folder holds its summary already is read, not rerun (a run resumed).
    if not os.path.exists(os.path.join(res, "summary.json")):
        cmd = [springfit, "--quiet", "--threads", str(threads), "fit", des, "--out", res]
        subprocess.run(cmd, check=True, stderr=subprocess.DEVNULL)
    s = json.load(open(os.path.join(res, "summary.json")))
    bom = list(csv.DictReader(open(os.path.join(res, "bom.csv"))))
    r = s["residual_deg"]
    print("%s: %d parts, p99 %.3f°, max %.3f°, fit %.0f s"
          % (name, s["used"], r["p99_abs"], r["max_abs"], s["timings_s"]["total"]), flush=True)
    return bom


def ranked(unlimited, count):
    """The unlimited bill's couplings by their cams' summed peak torque, largest first (ties by
    the coupling's text)."""
    torque = collections.defaultdict(float)
    for r in unlimited:
        if r["max_torque_nm"]:
            torque[r["coupling"]] += float(r["max_torque_nm"])
    order = sorted(torque.items(), key=lambda kv: (-kv[1], kv[0]))
    return [[float(x) for x in c.split(";")] for c, _ in order[:count]]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--springfit", default=os.path.join(REPO, "target", "release", "springfit"))
    ap.add_argument("--out", default="ur5_tendon_couplings")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--count", type=int, default=40)
    ap.add_argument("--write-catalogue", help="write the cams' catalogue here")
    a = ap.parse_args()
    # Never replace a catalogue this script did not write (one of the user's own).
    if a.write_catalogue and foreign(a.write_catalogue, MARKER):
        ap.error(f"{a.write_catalogue} exists and was not written by this script: choose another --write-catalogue")
    os.makedirs(a.out, exist_ok=True)
    bom = fit(a.springfit, a.out, "pool", pool_catalogue(), 0, a.threads)
    # Halving: keep the half of the couplings with the largest summed peak torque and refit them,
    # until the next half would be fewer than `count`; then the first `count`.
    while True:
        kept = len({r["coupling"] for r in bom})
        if kept // 2 < a.count:
            break
        half = ranked(bom, kept // 2)
        bom = fit(a.springfit, a.out, f"pool{len(half)}",
                  "name = \"ur5_tendon_pool\"\ndescription = \"halved\"\n"
                  + CAM.format(name="tendon cam", couplings=rows(half), knots=8), 0, a.threads)
    couplings = ranked(bom, a.count)
    cams = HEADER.format(count=a.count) + CAM.format(name="tendon cam", couplings=rows(couplings), knots=30)
    fit(a.springfit, a.out, f"tendons{a.count}", cams, 0, a.threads)
    if a.write_catalogue:
        open(a.write_catalogue, "w").write(cams)
        print(f"wrote {a.write_catalogue}")


if __name__ == "__main__":
    sys.exit(main())
