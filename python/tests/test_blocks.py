"""The building blocks step on numpy arrays; shapes and values are checked."""

import numpy as np
import pytest

import eqtrack
from conftest import REPO

SEED = REPO / "scenarios" / "seed.toml"


def hat(w):
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def expm_so3(w):
    t = np.linalg.norm(w)
    k = hat(w / t)
    return np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * k @ k


def test_the_controller_is_the_simulations_law():
    # at t = 0 the simulation's law sees the initial state and the reference's start
    run = eqtrack.simulate(SEED, duration=0.01)
    c = run.columns
    q = np.array([[c[f"q_{i}{j}"][0] for j in range(3)] for i in range(3)])
    v = np.array([c[f"v_{i}"][0] for i in range(3)])
    ctrl = eqtrack.Controller(SEED)
    assert ctrl.group == "so3"
    # the seed's reference starts at the identity, at rest, with tau_d(0) = (1, 0, 0)
    tau, lyap = ctrl.compute(q, v, np.eye(3), np.zeros(3), [1.0, 0.0, 0.0])
    assert np.array_equal(tau, [c["tau_0"][0], c["tau_1"][0], c["tau_2"][0]])
    assert lyap == c["lyapunov"][0]
    # at the desired state with no feedforward there is nothing to do
    zero, l0 = ctrl.compute(np.eye(3), np.zeros(3), np.eye(3), np.zeros(3))
    assert np.array_equal(zero, np.zeros(3)) and l0 == 0.0


def test_the_controller_checks_shapes_and_values():
    ctrl = eqtrack.Controller(SEED)
    with pytest.raises(ValueError, match=r"q: expected shape \(3, 3\), got \(4, 4\)"):
        ctrl.compute(np.eye(4), np.zeros(3), np.eye(3), np.zeros(3))
    with pytest.raises(ValueError, match=r"v: expected shape \(3,\), got \(2,\)"):
        ctrl.compute(np.eye(3), [0.0, 0.0], np.eye(3), np.zeros(3))
    bad = np.eye(3)
    bad[1, 1] = np.nan
    with pytest.raises(ValueError, match="q_d: entry 4 is NaN, not a finite number"):
        ctrl.compute(np.eye(3), np.zeros(3), bad, np.zeros(3))
    with pytest.raises(ValueError, match="v_d: not an array of numbers"):
        ctrl.compute(np.eye(3), np.zeros(3), np.eye(3), ["a", "b", "c"])
    se3 = eqtrack.Controller(REPO / "scenarios" / "se3_circle.toml")
    assert se3.group == "se3"
    tau, _ = se3.compute(np.eye(4), np.zeros(6), np.eye(4), np.zeros(6))
    assert tau.shape == (6,)


def test_the_filters_converge_and_check_their_inputs():
    world = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    r_true = expm_so3(np.array([0.3, -0.2, 0.5]))
    body = world @ r_true  # rows: R^T d
    bias = np.array([0.01, -0.02, 0.005])
    cf = eqtrack.ComplementaryFilter(1.0, 0.1, world, [1.0, 1.0])
    eqf = eqtrack.EquivariantFilter(0.01, 0.001, world, [0.01, 0.01])
    for f in (cf, eqf):
        for _ in range(10000):
            r_hat, rate, b_hat, started = f.step(0.01, bias, body)
        assert started
        assert np.linalg.norm(r_hat - r_true) < 1e-3
        assert np.linalg.norm(b_hat - bias) < 1e-3
        assert np.linalg.norm(rate) < 1e-3
    assert eqf.covariance.shape == (6, 6)
    assert np.all(np.diag(eqf.covariance) > 0)
    with pytest.raises(ValueError, match=r"directions: expected shape \(2, 3\), got \(3, 3\)"):
        cf.step(0.01, bias, np.eye(3))
    with pytest.raises(ValueError, match="gyro: entry 0 is inf"):
        cf.step(0.01, [np.inf, 0, 0], body)
    with pytest.raises(ValueError, match="h: NaN is not a finite positive period"):
        eqf.step(float("nan"), bias, body)
    with pytest.raises(ValueError, match="kp"):
        eqtrack.ComplementaryFilter(-1.0, 0.1, world, [1.0, 1.0])
    with pytest.raises(ValueError, match=r"weights: expected shape \(2,\)"):
        eqtrack.ComplementaryFilter(1.0, 0.1, world, [1.0])


def test_the_allocator_is_the_scenarios():
    a = eqtrack.Allocator(REPO / "scenarios" / "hexarotor_eqf.toml")
    assert a.count == 6
    demand = np.array([0.1, -0.2, 0.05, 0.0, 0.0, 20.0])
    u, achieved, status = a.allocate(demand)
    assert u.shape == (6,) and status == 0
    assert np.allclose(achieved, demand, atol=1e-9)
    with pytest.raises(ValueError, match=r"demand: expected shape \(6,\), got \(3,\)"):
        a.allocate([1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="has no \\[vehicle\\]"):
        eqtrack.Allocator(SEED)
