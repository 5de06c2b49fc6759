#!/usr/bin/env python3
"""Benchmarks of the Python package against its Rust baselines (benches/python_baseline.rs).

    python3 python/benches/bench.py            # both threads for the vectorised log map
    RAYON_NUM_THREADS=1 python3 python/benches/bench.py

Prints, on the default design:
* `Controller.torque(q, qdot, t)` from Python, µs per call (median / min of 5 runs of 100 000
  calls at states along the start of the switch run, the same states as the Rust baseline);
* `Design.log` over the 10 000 points of the baseline in one call, µs per point (median / min of
  3), to compare with `LogMap::log` per point in Rust (`cargo bench --bench python_baseline`).
"""

import math
import pathlib
import time

import numpy as np

import springfit

REPO = pathlib.Path(__file__).resolve().parents[2]


def points(design, count):
    """φₖ = k·π(3 − √5), sₖ = 1.9·√((k + ½)/N), qₖ = exp(sₖ uₖ), uₖ the metric unit vector of φₖ."""
    k = np.arange(count)
    phi = k * math.pi * (3.0 - math.sqrt(5.0))
    s = 1.9 * np.sqrt((k + 0.5) / count)
    u = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    m = design.mass_matrix(design.q_eq)
    u /= np.sqrt(np.einsum("ki,ij,kj->k", u, m, u))[:, None]
    return design.exp(u * s[:, None])


def main():
    design = springfit.Design.load(REPO / "designs" / "double_pendulum.toml")
    fit = design.fit()
    c = springfit.Controller(design, fit, scenario="switch")
    q0, _ = c.start
    states = []
    for k in range(1000):
        a = k * 0.01
        states.append((np.array([q0[0] * math.cos(a), q0[1] + 0.3 * math.sin(a)]),
                       np.array([0.5 * math.sin(a), -0.4 * math.cos(a)])))
    calls = 100_000
    runs = []
    for _ in range(5):
        t0 = time.perf_counter()
        for k in range(calls):
            q, qd = states[k % 1000]
            c.torque(q, qd, k * 1e-3)
        runs.append((time.perf_counter() - t0) * 1e6 / calls)
    runs.sort()
    print(f"Controller.torque from Python, {calls} calls: {runs[2]:.2f} µs / {runs[0]:.2f} µs per call")

    q = points(design, 10_000)
    runs = []
    for _ in range(4):
        t0 = time.perf_counter()
        design.log(q)
        runs.append((time.perf_counter() - t0) * 1e6 / len(q))
    runs = sorted(runs[1:])  # the first call warms up
    print(f"Design.log over 10 000 points in one call: {runs[1]:.2f} µs / {runs[0]:.2f} µs per point")


if __name__ == "__main__":
    main()
