#!/usr/bin/env python3
"""Which couplings the six-joint UR5 needs: a search over random couplings, then one cam on each
of the 40 it ranks first (catalogs/ur5_cams.toml, where scripts/ur5_pursuit.py starts the search
for the couplings of designs/ur5_six_cams.toml, withdrawn since: couplings like these have no
transmission within `[parts]`, README).

Why. designs/ur5_six.toml with catalogs/ur5_span.toml (every joint, every pair, every adjacent
triple and eight pan-wrist couplings) stops near p99 2.3° however many springs it keeps, and the
error sits in the outer band of the ball, where the wrists turn by radians. Whether that is the
element class (springs on transmission coordinates a·q) or the couplings the catalogue offers is
a question this script answers by measurement:

1. `random`: ur5_span.toml plus cranks (8 phases) and linear springs on 100 random couplings
   (entries drawn from {-2, -1, 0, 0, 1, 1, 2}, at least three joints, seed 3), fitted without a
   spring limit;
2. `random40`: the same catalogue with at most 40 springs (restarts 16);
3. `cams40`: one B-spline cam (30 knots, automatic smoothing) on each of 40 couplings: those of
   the 40-spring bill in its order, then the unlimited bill's couplings by their summed peak
   torque. A cam gives its coupling any smooth profile as one part (one of `max_elements`).

Every fit uses the design's ball r = 0.6, 576 training and 720 held-out directions (the six-joint
default trains on 1152; on the shipped design it moves the cams' p99 by 4 %), `builds = 0`, the release
binary; figures are the held-out p99 of `summary.json`. The machine's two cores take about
fifteen minutes for the three fits.

Run: python3 scripts/ur5_couplings.py [--springfit target/release/springfit] [--out DIR]
         [--threads 2] [--write-catalogue catalogs/ur5_cams.toml]
(DIR must not hold an earlier run's outputs: `springfit fit` does not overwrite them.)

What it found (2026-12-03, f71a17f; BENCHMARKS.md, "Whole arms"): `random` p99 1.275° (518 springs, outer band 1.78°), against
3.10° for ur5_span.toml at the same directions; `random40` 2.37°; `cams40` 1.35° (outer band
1.95°), against 3.08° for ur5_span.toml's 40 springs. The couplings, not the element class, held
the six-joint fit at 2.3°; 40 parts on ranked couplings halve its error but do not reach 1°.
"""
import argparse
import collections
import csv
import json
import os
import random
import re
import subprocess
import sys

from own_output import foreign

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, ".."))

MARKER = "# Written by scripts/ur5_couplings.py"
CAM_HEADER = """\
# One B-spline cam on each of 40 couplings of the UR5's six joints: where scripts/ur5_pursuit.py starts.
# Written by scripts/ur5_couplings.py (do not edit by hand: rerun it): the couplings of a 40-spring
# fit from ur5_span.toml plus cranks and linear springs on 100 random couplings, in the bill's
# order, then the couplings of the unlimited fit from the same catalogue ranked by summed peak
# torque. A cam on x = a·q realises any smooth V(x) (docs/catalogue.md, "Cams") and counts as one
# part; couplings of four to six joints are differentials, like ur5_span.toml's pan-wrist cranks.
name = "ur5_cams"
description = "A B-spline cam on each of 40 couplings ranked by scripts/ur5_couplings.py"
"""

CAM_FAMILY = """
[[family]]
name = "disc cam"
profile = "cam"
unit = "J"
couplings = [
  {couplings}
]
knots = 30
smoothing = "auto"
max_stroke = 16.0        # mm: the follower rate is chosen so the stroke stays within it
preload_fraction = 4.0
base_radius = 120.0      # mm
roller_radius = 8.0      # mm
max_pressure_angle = 30  # degrees
"""


def random_couplings(count=100, seed=3):
    """`count` distinct couplings of six joints, each naming at least three, first entry > 0."""
    rng = random.Random(seed)
    found = set()
    while len(found) < count:
        v = [rng.choice([-2, -1, 0, 0, 1, 1, 2]) for _ in range(6)]
        if sum(1 for x in v if x) < 3:
            continue
        first = next(x for x in v if x)
        found.add(tuple(-x for x in v) if first < 0 else tuple(v))
    return sorted(found)


def rows(couplings):
    return ",\n  ".join("[" + ", ".join(str(x) for x in c) + "]" for c in couplings)


def random_catalogue(couplings):
    base = open(os.path.join(REPO, "catalogs", "ur5_span.toml")).read()
    base = base.replace('name = "ur5_span"', 'name = "ur5_random"', 1)
    return base + f"""
[[family]]
name = "random crank"
profile = "crank"
unit = "N*m"
couplings = [
  {rows(couplings)}
]
offsets = {{ phases = 8 }}

[[family]]
name = "random linear"
profile = "linear"
unit = "N*m/rad"
couplings = [
  {rows(couplings)}
]
offsets = "equilibrium"
"""


def design(catalogue, max_elements):
    """designs/ur5_six.toml with the catalogue, the budget and the sampling of the search."""
    text = open(os.path.join(REPO, "designs", "ur5_six.toml")).read()
    text = re.sub(r'^catalog = ".*"$', f'catalog = "{catalogue}"', text, count=1, flags=re.M)
    text = text.replace('"../robots/', '"' + os.path.join(REPO, "robots") + "/")
    fit = (f"max_elements = {max_elements}\ntraining_directions = 576\n"
           "evaluation_directions = 720\nbuilds = 0\n")
    text, n = re.subn(r"^max_elements = 40.*$\n", fit, text, count=1, flags=re.M)
    assert n == 1, "designs/ur5_six.toml has no `max_elements = 40` line"
    return text


def fit(springfit, out, name, catalogue_text, max_elements, threads):
    cat = os.path.join(out, f"{name}_catalogue.toml")
    des = os.path.join(out, f"{name}.toml")
    open(cat, "w").write(catalogue_text)
    open(des, "w").write(design(cat, max_elements))
    res = os.path.join(out, name)
    cmd = [springfit, "--quiet", "--threads", str(threads), "fit", des, "--out", res]
    subprocess.run(cmd, check=True, stderr=subprocess.DEVNULL)
    s = json.load(open(os.path.join(res, "summary.json")))
    bom = list(csv.DictReader(open(os.path.join(res, "bom.csv"))))
    r = s["residual_deg"]
    bands = ", ".join("%.2f°" % b["stats"]["p99_abs"] for b in s["bands"])
    print("%s: %d parts, p99 %.3f°, max %.3f°, bands p99 %s, fit %.0f s"
          % (name, s["used"], r["p99_abs"], r["max_abs"], bands, s["timings_s"]["total"]), flush=True)
    return bom


def ranked(limited, unlimited, count=40):
    """The limited bill's couplings in its order, then the unlimited bill's by peak torque."""
    chosen = []
    for r in limited:
        if r["coupling"] not in chosen:
            chosen.append(r["coupling"])
    torque = collections.defaultdict(float)
    for r in unlimited:
        if r["max_torque_nm"]:
            torque[r["coupling"]] += float(r["max_torque_nm"])
    for c, _ in sorted(torque.items(), key=lambda kv: -kv[1]):
        if len(chosen) >= count:
            break
        if c not in chosen:
            chosen.append(c)
    return [tuple(int(x) for x in c.split(";")) for c in chosen[:count]]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--springfit", default=os.path.join(REPO, "target", "release", "springfit"))
    ap.add_argument("--out", default="ur5_couplings")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--write-catalogue", help="write the 40 cams' catalogue here")
    a = ap.parse_args()
    # Never replace a catalogue this script did not write (one of the user's own).
    if a.write_catalogue and foreign(a.write_catalogue, MARKER):
        ap.error(f"{a.write_catalogue} exists and was not written by this script: choose another --write-catalogue")
    os.makedirs(a.out, exist_ok=True)
    cat = random_catalogue(random_couplings())
    unlimited = fit(a.springfit, a.out, "random", cat, 0, a.threads)
    limited = fit(a.springfit, a.out, "random40", cat, 40, a.threads)
    couplings = ranked(limited, unlimited)
    cams = CAM_HEADER + CAM_FAMILY.format(couplings=rows(couplings))
    fit(a.springfit, a.out, "cams40", cams, 0, a.threads)
    if a.write_catalogue:
        open(a.write_catalogue, "w").write(cams)
        print(f"wrote {a.write_catalogue}")


if __name__ == "__main__":
    sys.exit(main())
