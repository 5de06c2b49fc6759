"""The geometry over arrays: shapes, and the identities that tie exp, log, labels and potentials."""

import numpy as np
import pytest

import springfit


@pytest.fixture(scope="module")
def points(design):
    rng = np.random.default_rng(1)
    v = rng.normal(size=(200, 2))
    m = design.mass_matrix(design.q_eq)
    v /= np.sqrt(np.einsum("ki,ij,kj->k", v, m, v))[:, None]
    return v * rng.uniform(0.2, 1.8, size=(200, 1))


def test_shapes_follow_the_input(design, fit, points):
    q = design.exp(points)
    assert q.shape == (200, 2) and design.exp(points[0]).shape == (2,)
    assert design.log(q).shape == (200, 2)
    assert design.distance(q).shape == (200,) and design.distance(q[0]).shape == ()
    assert design.label(q).shape == (200,) and design.label_gradient(q).shape == (200, 2)
    assert design.mass_matrix(q).shape == (200, 2, 2) and design.mass_matrix(q[0]).shape == (2, 2)
    u = fit.potential
    assert u.value(q).shape == (200,) and u.gradient(q).shape == (200, 2) and u.hessian(q).shape == (200, 2, 2)
    assert design.gravity_gradient(q).shape == (200, 2)


def test_log_inverts_exp_and_distance_is_the_arc_length(design, points):
    q = design.exp(points)
    assert np.allclose(design.log(q), points, atol=1e-8)
    m = design.mass_matrix(design.q_eq)
    r = np.sqrt(np.einsum("ki,ij,kj->k", points, m, points))
    assert np.allclose(design.distance(q), r, atol=1e-8)


def test_the_label_and_its_gradient(design, points):
    q = design.exp(points)
    theta = design.label(q)
    want = np.angle(np.exp(2j * np.arctan2(points[:, 1], points[:, 0])))
    assert np.allclose(np.angle(np.exp(1j * (theta - want))), 0.0, atol=1e-7)
    g = design.label_gradient(q[:20])
    h = 1e-6
    for k in range(2):
        dq = np.zeros(2)
        dq[k] = h
        fd = (design.label(q[:20] + dq) - design.label(q[:20] - dq)) / (2 * h)
        assert np.allclose(g[:, k], fd, rtol=1e-4, atol=1e-5)


def test_potential_gradient_and_hessian_agree_with_differences(design, fit, points):
    u = fit.potential
    q = design.exp(points[:30])
    h = 1e-6
    for k in range(2):
        dq = np.zeros(2)
        dq[k] = h
        assert np.allclose(u.gradient(q)[:, k], (u.value(q + dq) - u.value(q - dq)) / (2 * h), rtol=1e-5, atol=1e-5)
        assert np.allclose(u.hessian(q)[:, :, k], (u.gradient(q + dq) - u.gradient(q - dq)) / (2 * h), rtol=1e-4, atol=1e-4)
    # At the equilibrium: no torque, and the Hessian is ω² M(q_eq) (the fit's normalisation).
    assert np.allclose(u.gradient(design.q_eq) + design.gravity_gradient(design.q_eq), 0.0, atol=1e-6)


def test_acceleration_solves_the_dynamics(design):
    q = np.array([0.3, 1.2])
    qd = np.array([0.5, -0.4])
    tau = np.array([1.0, -2.0])
    a = design.acceleration(q, qd, tau)
    free = design.acceleration(q, qd, np.zeros(2))
    assert np.allclose(design.mass_matrix(q) @ (a - free), tau)


def test_results_do_not_depend_on_the_batch(design, points):
    # Each point is solved on its own: a batch (parallel) gives the bytes of one-by-one calls.
    q = design.exp(points[:80])
    one = np.array([design.log(p) for p in q])
    assert np.array_equal(design.log(q), one)
