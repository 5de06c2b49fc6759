#!/usr/bin/env python3
"""Do two springfit builds give the same fits? For every shipped design (or the ones named), run
`springfit fit` with each binary and compare bom.csv, residuals.csv, summary.json (without its
timings) and the cams' files byte for byte.

Where bytes differ, every number is compared instead and the largest relative difference per file
is printed, so a change of rounding (another factorisation, another summation order) shows as
"differs in the last digits: largest relative difference 3e-15" and anything else as a failure.

    python3 scripts/same_outputs.py --before OLD_BINARY --after target/release/springfit
    python3 scripts/same_outputs.py --before OLD --after NEW --designs double_pendulum ur5_lift_elbow
    python3 scripts/same_outputs.py --before OLD --after NEW --tolerance 1e-12

Exit code 0 when every file is byte-identical, or (with --tolerance) within the relative tolerance
in every number and equal in every other field; 1 otherwise. A reference binary comes from a
checkout of the older commit: `git worktree add /tmp/before <commit> && cargo build --release
--manifest-path /tmp/before/Cargo.toml`.
"""

import argparse
import json
import math
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
COMPARED = ["bom.csv", "residuals.csv", "summary.json"]
NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def run_fit(binary, design, out, threads):
    cmd = [binary, "--quiet", "fit", str(design), "--out", str(out), "--threads", str(threads)]
    r = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr.strip()}")


def without_timings(text):
    data = json.loads(text)
    data.pop("timings_s", None)
    return data


def fields(text):
    """The text split into fields: numbers as floats, everything else as text."""
    out = []
    for tok in re.split(r"[,\s\[\]{}:\"]+", text):
        if not tok:
            continue
        out.append(float(tok) if NUMBER.match(tok) else tok)
    return out


def relative(a, b):
    if a == b or (math.isnan(a) and math.isnan(b)):
        return 0.0
    return abs(a - b) / max(abs(a), abs(b), 1e-300)


def compare_text(name, old, new):
    """None when equal; else (largest relative difference, or None if non-numeric fields differ)."""
    if name.endswith(".json"):
        old = json.dumps(without_timings(old), sort_keys=True, indent=0)
        new = json.dumps(without_timings(new), sort_keys=True, indent=0)
    if old == new:
        return None
    a, b = fields(old), fields(new)
    if len(a) != len(b):
        return (None, f"{len(a)} fields before, {len(b)} after")
    worst = 0.0
    for x, y in zip(a, b):
        if isinstance(x, float) and isinstance(y, float):
            worst = max(worst, relative(x, y))
        elif x != y:
            return (None, f"`{x}` before, `{y}` after")
    return (worst, None)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", required=True, help="the reference springfit binary")
    ap.add_argument("--after", default=str(REPO / "target/release/springfit"), help="the binary under test")
    ap.add_argument("--designs", nargs="*", help="design names (default: every file in designs/)")
    ap.add_argument("--tolerance", type=float, default=0.0, help="largest relative difference accepted in numbers")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--keep", help="keep the outputs in this folder")
    args = ap.parse_args()

    names = args.designs or sorted(p.stem for p in (REPO / "designs").glob("*.toml"))
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="springfit-same-"))
    failures = 0
    for name in names:
        design = REPO / "designs" / f"{name}.toml"
        before, after = root / "before" / name, root / "after" / name
        for binary, out in [(args.before, before), (args.after, after)]:
            run_fit(binary, design, out, args.threads)
        files = COMPARED + sorted(
            str(p.relative_to(before)) for p in (before / "cams").glob("*") if p.suffix in (".toml", ".csv")
        ) if (before / "cams").is_dir() else COMPARED
        lines, bad = [], False
        for f in files:
            old_path, new_path = before / f, after / f
            if not old_path.exists() and not new_path.exists():
                continue
            if not new_path.exists() or not old_path.exists():
                lines.append(f"  {f}: written by only one of the two")
                failures += 1
                bad = True
                continue
            d = compare_text(f, old_path.read_text(), new_path.read_text())
            if d is None:
                continue
            worst, why = d
            if worst is None:
                lines.append(f"  {f}: differs: {why}")
                failures += 1
                bad = True
            elif worst <= args.tolerance:
                lines.append(f"  {f}: differs in the last digits: largest relative difference {worst:.1e}")
            else:
                lines.append(f"  {f}: differs: largest relative difference {worst:.1e}")
                failures += 1
                bad = True
        verdict = "identical" if not lines else ("differs" if bad else "within tolerance")
        print(f"{name}: {verdict} ({', '.join(files) if len(files) <= 4 else f'{len(files)} files'})")
        for line in lines:
            print(line)
    print(f"{len(names)} designs, {failures} files beyond tolerance {args.tolerance:g}; outputs in {root}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
