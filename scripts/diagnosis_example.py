#!/usr/bin/env python3
"""The diagnosis example of docs/guide.md ("When the fit is poor"), regenerated.

`designs/planar_three.toml` with only the pair families of `catalogs/chain.toml` (its two triple
families dropped), `accept_p99_deg = 0.1` so that the diagnosis runs, `mass_weight = 0.0` (the
accuracy alone): `springfit fit` prints the fit's p99 and the diagnosis. Then each of the first
`--try` additions it ranks is added to the catalogue alone (a family on that coupling with that
profile, at the offsets a catalogue gives it: 12 crank phases, 9 compression offsets per side)
and the design fitted again, to show how the shares rank what a fit then measures.

Run: python3 scripts/diagnosis_example.py [--springfit target/release/springfit] [--try 3]
About a minute on two cores (each fit about 10 s of CPU). The same case is tests/diagnosis.rs.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

FAMILY = {
    "linear": 'profile = "linear"\nunit = "N*m/rad"\noffsets = "equilibrium"',
    "cubic": 'profile = "cubic"\nunit = "N*m/rad^3"\noffsets = "equilibrium"',
    "crank": 'profile = "crank"\nunit = "N*m"\noffsets = { phases = 12 }',
    "compression": 'profile = "compression"\nside = "both"\nunit = "N*m/rad"\noffsets = { grid = 9 }',
}


def fmt(x):
    return ("%g" % x).replace("-", "−") if x < 0 else "%g" % x


def fit(springfit, folder, design):
    out = os.path.join(folder, "out")
    run = subprocess.run([springfit, "--threads", "1", "fit", design, "--out", out],
                         capture_output=True, text=True, cwd=folder)
    if run.returncode != 0:
        sys.exit(run.stderr)
    with open(os.path.join(out, "summary.json")) as f:
        return run.stdout, json.load(f)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--springfit", default=os.path.join(ROOT, "target", "release", "springfit"))
    ap.add_argument("--try", dest="tries", type=int, default=3, help="additions to fit one by one")
    args = ap.parse_args()
    with open(os.path.join(ROOT, "catalogs", "chain.toml")) as f:
        chain = f.read()
    pairs = chain[: chain.index('[[family]]\nname = "triple crank"')]
    with open(os.path.join(ROOT, "designs", "planar_three.toml")) as f:
        design = f.read()
    design = design.replace('catalog = "../catalogs/chain.toml"', 'catalog = "catalog.toml"')
    design = design.replace("[fit]\n", "[fit]\naccept_p99_deg = 0.1\nmass_weight = 0.0\n", 1)
    with tempfile.TemporaryDirectory() as tmp:
        def case(name, catalogue):
            folder = os.path.join(tmp, name)
            os.makedirs(folder)
            with open(os.path.join(folder, "catalog.toml"), "w") as f:
                f.write(catalogue)
            with open(os.path.join(folder, "arm.toml"), "w") as f:
                f.write(design)
            return fit(args.springfit, folder, "arm.toml")

        stdout, summary = case("pairs", pairs)
        print("pair families only: p99 %.2f°" % summary["residual_deg"]["p99_abs"])
        lines = stdout.splitlines()
        start = next(i for i, l in enumerate(lines) if l.startswith("diagnosis ("))
        for line in lines[start:]:
            if not (line.startswith("diagnosis (") or line.startswith("  ")):
                break
            print(line)
        for a in summary["diagnosis"]["additions"][: args.tries]:
            coupling = ", ".join("%g" % x for x in a["coupling"])
            family = '\n[[family]]\nname = "added"\n%s\ncouplings = [[%s]]\n' % (FAMILY[a["profile"]], coupling)
            _, s = case("added-%s-%s" % (a["profile"], coupling.replace(", ", "_")), pairs + family)
            print("added alone: %s on (%s): p99 %.2f° (share %.0f %%)"
                  % (a["profile"], ", ".join(fmt(x) for x in a["coupling"]), s["residual_deg"]["p99_abs"],
                     100 * a["share"]))


if __name__ == "__main__":
    main()
