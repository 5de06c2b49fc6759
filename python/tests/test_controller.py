"""springfit.Controller in a loop of our own reproduces `springfit simulate --scenario switch`."""

import csv
import json
import math

import numpy as np
import pytest

import springfit
from conftest import DEFAULT, cli

SOURCES = 6  # spring, gravity, damping, mode, energy, compensation: the simulator's flux order


def rk4_switch(design, potential, controller, rate, every):
    """The simulator's fixed-step RK4 written out in Python: state (q, q̇, ∫|P| per source), the
    same stage times and sums; records q every `every` steps."""
    n = design.dof
    damping = controller.damping
    q0, qd0 = controller.start
    steps = round(controller.duration * rate)
    h = 1.0 / rate

    def rhs(t, y):
        q, qd = y[:n], y[n:2 * n]
        spring = -potential.gradient(q)
        gravity = -design.gravity_gradient(q)
        damp = -damping * qd
        c = controller.torque(q, qd, t)
        mode, energy, comp = c.mode, c.energy_torque, c.compensation
        qdd = design.acceleration(q, qd, spring + gravity + damp + mode + energy + comp)
        flux = [abs(sum(tau * qd)) for tau in (spring, gravity, damp, mode, energy, comp)]
        return np.concatenate([qd, qdd, flux])

    y = np.concatenate([q0, qd0, np.zeros(SOURCES)])
    samples = []
    for step in range(steps + 1):
        t = step / rate
        if step % every == 0:
            samples.append((t, y[:n].copy()))
        if step == steps:
            break
        k1 = rhs(t, y)
        k2 = rhs(t + 0.5 * h, y + 0.5 * h * k1)
        k3 = rhs(t + 0.5 * h, y + 0.5 * h * k2)
        k4 = rhs(t + h, y + h * k3)
        y = y + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return samples, y[2 * n:]


def test_a_python_rk4_loop_reproduces_simulate_switch(design, fit, cli_fit, tmp_path):
    # The default design with the switch scenario cut from 100 s to its first 30 s (two mode
    # steps, at 15 s and 30 s): the Python loop takes a second per simulated second.
    text = DEFAULT.read_text().replace('"../catalogs/', f'"{DEFAULT.parent.parent / "catalogs"}/')
    switch = text.index('name = "switch"')
    cut = text[:switch] + text[switch:].replace("duration = 100.0", "duration = 30.0", 1)
    assert cut != text
    short = tmp_path / "double_pendulum.toml"
    short.write_text(cut)
    out = tmp_path / "sim"
    p = cli("simulate", short, "--bom", cli_fit / "bom.csv", "--scenario", "switch", "--out", out, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    with open(out / "sim_switch.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    want = np.array([[float(r["q1"]), float(r["q2"])] for r in rows])
    metrics = json.loads((out / "sim_switch.json").read_text())["runs"]["switch"]
    potential = fit.potential
    controller = springfit.Controller(springfit.Design.load(short), fit, scenario="switch")
    assert controller.duration == 30.0
    rate = design.simulate_settings["rate"]
    assert rate == 1000.0
    every = 10
    samples, flux = rk4_switch(design, potential, controller, rate, every)
    got = np.array([q for _, q in samples])
    assert got.shape == want.shape
    err = float(np.max(np.abs(got - want)))
    print(f"largest |q_python - q_simulate| over 30 s: {err:.3e} rad")
    assert err <= 1e-9
    share = (flux[3] + flux[4]) / flux[0]
    print(f"actuator share: python {share:.12f}, simulate {metrics['actuator_share']:.12f}")
    assert share == pytest.approx(metrics["actuator_share"], rel=1e-9)


def test_targets_are_settable_between_calls(design, fit):
    c = springfit.Controller(design, fit)
    q, qd = np.array([0.6, 1.9]), np.array([0.2, -0.1])
    off = c.torque(q, qd, 0.0)
    assert np.all(off.tau == 0.0) and c.theta_d is None and c.energy_target is None
    assert math.isfinite(off.label) and off.energy > 0.0
    c.theta_d = off.label + 0.5
    on = c.torque(q, qd, 0.0)
    assert np.any(on.mode != 0.0) and np.all(on.energy_torque == 0.0)
    assert on.label_target == pytest.approx(off.label + 0.5)
    c.energy_target = off.energy + 5.0
    more = c.torque(q, qd, 0.0)
    # τ_E = β_E M (E_d − E) q̇ injects power when E < E_d.
    assert float(more.energy_torque @ qd) > 0.0
    assert not more.saturated and more.saturation == (1.0, 1.0)
    # An energy deficit far beyond what the motors give: [controllers] max_torque holds every
    # joint within its limit, and the energy law keeps its direction (it still injects power).
    limit = np.array(design.controllers["max_torque"])
    c.energy_target = off.energy + 1e5
    big = c.torque(q, qd, 0.0)
    assert big.saturated and big.demand > limit.max() and big.saturation[1] < 1.0
    assert np.all(np.abs(big.tau) <= limit * (1.0 + 1e-12))
    assert float(big.energy_torque @ qd) > 0.0
    c.energy_target = off.energy + 5.0
    assert c.energy_law == "energy"
    c.energy_law = "negative_damping"
    nd = c.torque(q, qd, 0.0)
    assert np.allclose(nd.energy_torque, design.controllers["beta_nd"] * 5.0 * qd)
    c.theta_d = None
    c.energy_target = None
    assert np.all(c.torque(q, qd, 0.0).tau == 0.0)
    # A negative energy can never be reached: refused, naming the attribute.
    with pytest.raises(springfit.SettingError, match="energy_target.*never negative"):
        c.energy_target = -1.0
    # Inside the ε-ball the mode law is off and the label undefined.
    c.theta_d = 0.0
    inside = c.torque(design.q_eq + 0.01, qd, 0.0)
    assert inside.in_ball and math.isnan(inside.label) and np.all(inside.mode == 0.0)


def test_the_switch_scenario_schedule(design, fit):
    c = springfit.Controller(design, fit, scenario="switch")
    assert c.mode_steps[:3] == [0.0, 15.0, 30.0]
    assert c.energy_target == 10.0 and c.duration == 100.0
    assert c.label_error_deg is not None and c.label_error_deg < 0.01


def test_auto_says_why_the_label_is_exact(design, fit):
    """`label = "auto"` on an arm whose fitted log map misses (triple_pendulum: 2.4°) keeps the
    exact log map and reports the rejected fit's error; the two-joint table rejects nothing."""
    triple = springfit.Design.load(DEFAULT.parent / "triple_pendulum.toml")
    c = springfit.Controller(triple, springfit.Potential.exact(triple))
    assert c.label_error_deg is None
    assert c.label_rejected_error_deg is not None and c.label_rejected_error_deg > 0.1
    assert c.label_note == f"fitted log map error {c.label_rejected_error_deg:.2f}° > 0.1°: exact log map used"
    table = springfit.Controller(design, fit)
    assert table.label_rejected_error_deg is None and table.label_note is None
