#!/usr/bin/env python3
"""Fits the paper's arm from Python and plots the residual angles with matplotlib.

    python3 examples/fit_histogram.py [--out out/python_fit]

The fit is `springfit fit`'s (the same bill of materials, byte for byte); its files go to the
output folder, and the histogram of the residual angles on the held-out geodesics is saved there
as residuals_matplotlib.png. Needs `pip install ./python matplotlib`.
"""

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")  # no display needed
import matplotlib.pyplot as plt
import numpy as np

import springfit

REPO = pathlib.Path(__file__).resolve().parents[1]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--design", default=str(REPO / "designs" / "double_pendulum.toml"))
    ap.add_argument("--out", default="out/python_fit")
    args = ap.parse_args()

    design = springfit.Design.load(args.design)
    fit = design.fit(progress=lambda stage: print(f"  {stage}"))
    folder = fit.write(args.out)
    s = fit.summary["residual_deg"]
    print(f"{design.name}: {fit.used} springs, residual angle p99 {s['p99_abs']:.4f}°, max {s['max_abs']:.4f}°")
    print(f"bill of materials: {len(fit.bom)} rows; total stiffness of the linear springs "
          f"{np.nansum(fit.bom_array['stiffness'][fit.bom_array['profile'] == 'linear']):.3f} N·m/rad")

    angles = fit.residuals
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.hist(angles, bins=60, color="#4477aa")
    ax.axvline(s["p99_abs"], color="#cc6677", ls="--", label=f"|angle| p99 = {s['p99_abs']:.3f}°")
    ax.axvline(-s["p99_abs"], color="#cc6677", ls="--")
    ax.set_xlabel("residual angle on held-out geodesics (°)")
    ax.set_ylabel("samples")
    ax.set_title(f"{design.name}: {fit.used} springs")
    ax.legend()
    fig.tight_layout()
    png = pathlib.Path(folder) / "residuals_matplotlib.png"
    fig.savefig(png, dpi=120)
    print(f"wrote {folder} and {png}")


if __name__ == "__main__":
    main()
