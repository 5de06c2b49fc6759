#!/usr/bin/env python3
"""How well can *any* smooth potential do on a ball? Polynomial potentials fitted without the
element classes' restrictions, ball by ball, to show where the accuracy limit is the ball's and
not the catalogue's.

Why. A strict normal mode's potential exists on every valid ball (docs/theory.md): U = ½ ω² r²,
r the metric distance from q_eq. But r² is singular where geodesics from q_eq focus (a conjugate
point), and the largest valid ball of `springfit check` ends exactly where the first one is met.
Close to that radius the potential a spring set has to imitate bends ever more sharply, and every
finite family of smooth functions falls behind. This script measures how far behind, with the
richest family it can fit directly: every polynomial in q − q_eq of degree ≤ D (no signs, no
couplings, no parts), its linear and quadratic terms fixed by the equilibrium and the Hessian match
(∇U(q_eq) = 0, ∇²U(q_eq) = ω² M(q_eq)) as in the fit, the rest by least squares on the fit's own
tangentiality rows (docs/theory.md, "The fit"; each row divided by ω² s |γ̇|, as springfit does).
A spring set whose profiles are polynomials of degree ≤ D (linear and cubic springs) lies in this
family; cranks, compression springs and cams do not, so the figures are a yardstick, not a bound
(on the six-joint UR5's ball 0.6, far from any conjugate point, degree 6 gives 2.77° where 40 cams
give 0.38°: polynomials in q serve badly where joints turn by radians).

Samples come from springfit's own geodesics (the Python package's `Design.exp`, velocities by
central differences, `scripts/ur5_pursuit.py`'s sampler): random directions with `--per` points
each, training and judging sets apart.

Beside each radius's polynomials, springfit's own fit of the design's catalogue on the same ball
(no budget, `builds = 0`, its own directions: the rows marked "catalogue"), for comparison.

Run: python3 scripts/radius_limit.py [DESIGN] [--radii 0.3 0.4 0.47 0.52] [--degrees 4 6 8]
         [--train 1152] [--test 1000] [--per 20] [--no-catalogue]
Needs the Python package (README, "Python package"). About three minutes on two cores for the
defaults on designs/pendulum5.toml.

What it printed (2026-12-04, designs/pendulum5.toml, largest valid radius 0.5257): see
BENCHMARKS.md, "Whole arms" (the five-link pendulum's accuracy against the ball's radius).
"""
import argparse
import itertools
import os
import re
import sys
import time
import tomllib

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from ur5_pursuit import Rows, gravity_hessian, samples  # noqa: E402  (the same sampler and rows as the pursuit)

REPO = os.path.normpath(os.path.join(HERE, ".."))
RIDGE = 1e-10  # on the free coefficients, times the rows: only keeps the normal equations regular


def exponents(n, lo, hi):
    """Exponent vectors of every monomial of n variables with degree lo…hi."""
    out = []
    for d in range(lo, hi + 1):
        for combo in itertools.combinations_with_replacement(range(n), d):
            e = np.zeros(n, dtype=int)
            for i in combo:
                e[i] += 1
            out.append(e)
    return np.array(out).reshape(-1, n)


def monomial_gradients(x, exps, scale):
    """∂/∂q of each monomial Π (Δq_j/scale)^e_j at the rows of x = Δq: N × n × K."""
    N, n = x.shape
    if len(exps) == 0:
        return np.zeros((N, n, 0))
    D = exps.sum(axis=1).max()
    powers = np.ones((N, n, D + 1))
    for d in range(1, D + 1):
        powers[:, :, d] = powers[:, :, d - 1] * (x / scale)
    G = np.zeros((N, n, len(exps)))
    for i in range(n):
        lowered = exps.copy()
        lowered[:, i] -= 1
        active = exps[:, i] > 0
        val = np.ones((N, int(active.sum())))
        for j in range(n):
            val *= powers[:, j, :][:, lowered[active, j]]
        G[:, i, active] = val * exps[active, i] / scale
    return G


def fit_and_judge(design, omega, radius, degree, train, test):
    """p99 residual angle (degrees) on `test` of the degree-`degree` polynomial potential fitted on
    `train`, and per quarter of the ball."""
    n = design.dof
    q_eq = np.asarray(design.q_eq)
    M0 = np.asarray(design.mass_matrix(q_eq))
    hessian = omega ** 2 * M0 - gravity_hessian(design, q_eq)   # of the springs' part, U − U_g
    g0 = -np.asarray(design.gravity_gradient(q_eq))  # the springs' gradient at q_eq
    exps = exponents(n, 3, degree)

    def fixed_gradient(rows):
        return g0[None, :] + rows.dq @ hessian          # ∇ of the fixed linear and quadratic part

    def residual_rows(rows):
        """Rows (N·(n−1) × K) and right-hand side of the tangentiality equations."""
        G = monomial_gradients(rows.dq, exps, radius)
        R = np.einsum("ncj,njk->nck", rows.W, G) * rows.wt[:, None, None]
        known = rows.gg + fixed_gradient(rows)
        b = -np.einsum("ncj,nj->nc", rows.W, known) * rows.wt[:, None]
        return R.reshape(b.size, len(exps)), b.reshape(-1)

    R, b = residual_rows(train)
    c = np.linalg.solve(R.T @ R + RIDGE * len(b) * np.eye(len(exps)), R.T @ b) if len(exps) else np.zeros(0)
    grad = test.gg + fixed_gradient(test) + np.einsum("njk,k->nj", monomial_gradients(test.dq, exps, radius), c)
    v = np.linalg.solve(test.M, grad[:, :, None])[:, :, 0]
    cos = np.einsum("ni,ni->n", grad, test.qd) / np.sqrt(
        np.einsum("ni,ni->n", grad, v) * np.einsum("ni,nij,nj->n", test.qd, test.M, test.qd))
    angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    s = test.s
    bands = [np.percentile(angle[(s > radius * k / 4) & (s <= radius * (k + 1) / 4)], 99) for k in range(4)]
    return len(exps), np.percentile(angle, 99), bands


def fit_key(text, key, value):
    """The design text with `key = value` in its [fit] table: the key's line replaced where the
    table has one, else added under the table's header (a table added at the end if there is
    none). Other tables' keys of the same name ([sweep] builds) are left alone."""
    lines = text.split("\n")
    header = next((i for i, l in enumerate(lines) if l.strip() == "[fit]"), None)
    if header is None:
        return text.rstrip("\n") + f"\n\n[fit]\n{key} = {value}\n"
    end = next((i for i in range(header + 1, len(lines)) if lines[i].lstrip().startswith("[")), len(lines))
    for i in range(header + 1, end):
        if re.match(rf"\s*{re.escape(key)}\s*=", lines[i]):
            lines[i] = f"{key} = {value}"
            return "\n".join(lines)
    lines.insert(header + 1, f"{key} = {value}")
    return "\n".join(lines)


def catalogue_fit(path, radius):
    """springfit's fit of the design's own catalogue on the ball of `radius`, without a budget:
    (springs, candidates, p99, p99 per band) from its summary."""
    import springfit
    text = open(path).read()
    text = re.sub(r"(?m)^radius = .*$", f"radius = {radius!r}", text)
    text = fit_key(fit_key(text, "max_elements", "0"), "builds", "0")
    summary = springfit.Design.from_toml(text, path=path).fit().summary
    return (summary["used"], summary["candidates"], summary["residual_deg"]["p99_abs"],
            [b["stats"]["p99_abs"] for b in summary["bands"]])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("design", nargs="?", default=os.path.join(REPO, "designs", "pendulum5.toml"))
    ap.add_argument("--radii", type=float, nargs="+", default=[0.3, 0.4, 0.47, 0.52])
    ap.add_argument("--degrees", type=int, nargs="+", default=[4, 6, 8])
    ap.add_argument("--train", type=int, default=1152, help="training directions")
    ap.add_argument("--test", type=int, default=1000, help="judging directions")
    ap.add_argument("--per", type=int, default=20, help="points per geodesic")
    ap.add_argument("--no-catalogue", action="store_true", help="skip springfit's own fits")
    a = ap.parse_args()
    import springfit
    t0 = time.time()
    design = springfit.Design.load(a.design)
    with open(a.design, "rb") as f:
        omega = tomllib.load(f).get("fit", {}).get("frequency", 1.0)
    region = design.check(strict=False)["region"]
    print(f"{design.name}: {design.dof} joints, ω = {omega} rad/s, largest valid radius "
          f"{region.get('largest_radius')} ({(region.get('limit') or {}).get('kind', 'probe')})")
    print("| radius | potential | free coefficients (catalogue: candidates) | p99 | p99 by quarter of the ball |")
    print("| ---: | --- | ---: | ---: | --- |")
    for radius in a.radii:
        train = Rows(design, *samples(design, a.train, a.per, seed=1, radius=radius), omega=omega)
        test = Rows(design, *samples(design, a.test, a.per, seed=2, radius=radius), omega=omega)
        for degree in a.degrees:
            k, p99, bands = fit_and_judge(design, omega, radius, degree, train, test)
            print(f"| {radius:g} | polynomial of degree {degree} | {k} | {p99:.2f}° | "
                  + ", ".join(f"{x:.2f}°" for x in bands) + " |", flush=True)
        if not a.no_catalogue:
            used, candidates, p99, bands = catalogue_fit(a.design, radius)
            print(f"| {radius:g} | the catalogue: {used} of {candidates} springs | {candidates} | {p99:.2f}° | "
                  + ", ".join(f"{x:.2f}°" for x in bands) + " |", flush=True)
    print(f"{time.time() - t0:.0f} s")


if __name__ == "__main__":
    sys.exit(main())
