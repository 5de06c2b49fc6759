#!/usr/bin/env python3
"""A catalogue with one B-spline cam on each of many couplings of an n-joint arm: every joint,
every pair (q_i + q_j and q_i − q_j), every run of three or more adjacent joints, and random
integer couplings beside them.

Why. A cam on x = a·q gives its coupling any smooth profile (docs/catalogue.md, "Cams"), so a
catalogue of cams asks only which couplings the potential needs; this writes a broad one to try
before choosing (`[fit] max_elements`) or moving the couplings (scripts/ur5_pursuit.py). The
random couplings have entries drawn uniformly from −E…E (at least two joints, first non-zero
entry positive, no repeats), from Python's `random.Random(seed)`, so a seed gives the same
catalogue on every machine.

Run: python3 scripts/cam_catalogue.py --joints 5 --random 40 --seed 5 --entries 1 --out FILE
         [--knots 30]
BENCHMARKS.md ("Whole arms") fits `designs/pendulum5.toml` with two of these (71 and 151 cams).
"""
import argparse
import itertools
import random
import sys

from own_output import foreign

HEADER = "# Written by scripts/cam_catalogue.py"


def couplings(n, extra, seed, entries):
    """The structured couplings, then `extra` random ones."""
    out = []
    for i in range(n):
        out.append([1 if k == i else 0 for k in range(n)])
    for i, j in itertools.combinations(range(n), 2):
        for sign in (1, -1):
            v = [0] * n
            v[i], v[j] = 1, sign
            out.append(v)
    for length in range(3, n + 1):
        for start in range(n - length + 1):
            out.append([1 if start <= k < start + length else 0 for k in range(n)])
    seen = {tuple(v) for v in out}
    rng = random.Random(seed)
    while extra > 0:
        v = [rng.randint(-entries, entries) for _ in range(n)]
        if sum(x != 0 for x in v) < 2:
            continue
        if next(x for x in v if x != 0) < 0:
            v = [-x for x in v]
        if tuple(v) in seen:
            continue
        seen.add(tuple(v))
        out.append(v)
        extra -= 1
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--joints", type=int, required=True)
    ap.add_argument("--random", type=int, default=0, help="random couplings beside the structured ones")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--entries", type=int, default=1, help="random entries from −E…E")
    ap.add_argument("--knots", type=int, default=30)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    if a.joints < 2 or a.entries < 1:
        ap.error("need --joints ≥ 2 and --entries ≥ 1")
    if a.random > (2 * a.entries + 1) ** a.joints // 2:
        ap.error("more random couplings asked for than there are")
    # Never replace a file this script did not write (a catalogue of the user's own).
    if foreign(a.out, HEADER, lines=1):
        ap.error(f"{a.out} exists and was not written by this script: choose another --out")
    cs = couplings(a.joints, a.random, a.seed, a.entries)
    rows = ",\n".join("  [" + ", ".join(str(x) for x in c) + "]" for c in cs)
    with open(a.out, "w") as f:
        f.write(f"{HEADER} --joints {a.joints} --random {a.random} --seed {a.seed} "
                f"--entries {a.entries} --knots {a.knots}\n")
        f.write(f'name = "cams on {len(cs)} couplings"\n')
        f.write(f'description = "A B-spline cam on every joint, pair and run of {a.joints} joints and on '
                f'{a.random} random couplings"\n\n')
        f.write(f'[[family]]\nname = "disc cam"\nprofile = "cam"\nunit = "J"\nknots = {a.knots}\n')
        f.write(f"couplings = [\n{rows},\n]\n")
    print(f"{a.out}: {len(cs)} cams")


if __name__ == "__main__":
    sys.exit(main())
