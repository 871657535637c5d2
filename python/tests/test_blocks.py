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


def test_the_planar_blocks_take_se2():
    # SE(2): a planar body 1 m along x of its reference, at rest, is pulled back along -x
    # (the force k_x |x| = 2 N of se2_circle's K), with no torque and no sideways force
    ctrl = eqtrack.Controller(REPO / "scenarios" / "se2_circle.toml")
    assert ctrl.group == "se2"
    q = np.eye(3)
    q[0, 2] = 1.0
    tau, lyapunov = ctrl.compute(q, np.zeros(3), np.eye(3), np.zeros(3))
    assert np.allclose(tau, [0.0, -2.0, 0.0], atol=1e-12), tau
    assert abs(lyapunov - 1.0) < 1e-12  # k_x |x|^2 / 2
    # the vessel's four planar thrusters give any (torque, f_x, f_y) within their range
    a = eqtrack.Allocator(REPO / "scenarios" / "se2_vessel.toml")
    assert a.count == 4
    demand = np.array([1.0, 20.0, -10.0])
    u, achieved, status = a.allocate(demand)
    assert u.shape == (4,) and status == 0
    assert np.allclose(achieved, demand, atol=1e-9)
    with pytest.raises(ValueError, match=r"demand: expected shape \(3,\), got \(6,\)"):
        a.allocate(np.zeros(6))


def test_the_detector_flies_as_the_simulations_controller():
    # pil_rov_detect: thruster 1 dies unannounced at 1.4 s; stepped on the states, the law's
    # wrenches and the times the simulation logged, the block allocates the same commands,
    # bit for bit, and finds what the simulation's controller found, when it found it. With
    # no weight and no buoyancy the allocation's demand is the law's wrench itself (less a
    # zero restoring wrench), which trajectory.csv logs
    scenario = REPO / "scenarios" / "pil_rov_detect.toml"
    neutral = {"vehicle": {"gravity": 0.0, "buoyancy": 0.0}}
    run = eqtrack.simulate(scenario, **neutral)
    c = run.columns
    d = eqtrack.Detector(scenario, neutral)
    assert d.count == 8 and d.failed == []
    found, suspects = [], 0
    for k in range(len(c["t"])):
        q = np.array([[c[f"q_{i}{j}"][k] for j in range(4)] for i in range(4)])
        v = np.array([c[f"v_{i}"][k] for i in range(6)])
        wrench = np.array([c[f"demand_{i}"][k] for i in range(6)])
        out = d.step(c["t"][k], q, v, wrench)
        assert np.array_equal(out["u_cmd"], [c[f"u_cmd_{j}"][k] for j in range(8)]), k
        assert out["status"] == c["alloc_status"][k]
        suspects += out["suspect"] is not None
        if out["detection"] is not None:
            found.append((round(c["t"][k], 9), out["detection"]))
    logged = run.summary["vehicle"]["detections"]
    assert [(t, f["actuator"], f["kind"], f["value"]) for t, f in found] == [
        (x["t"], x["actuator"], x["kind"], x["value"]) for x in logged
    ]
    assert logged[0]["actuator"] == 1 and logged[0]["kind"] == "dead"
    assert d.failed == [1]
    assert 0 < suspects < len(c["t"]), "it tests once calibrated, not before"


def test_the_detector_checks_its_scenario_and_its_inputs():
    scenario = REPO / "scenarios" / "pil_rov_detect.toml"
    with pytest.raises(ValueError, match=r"has no \[fault_detection\]"):
        eqtrack.Detector(REPO / "scenarios" / "rov_failure.toml")
    with pytest.raises(ValueError, match=r"has no \[vehicle\]"):
        eqtrack.Detector(SEED)
    with pytest.raises(ValueError, match="fault_detection.window"):
        eqtrack.Detector(scenario, {"fault_detection": {"window": 0.0}})
    # a step takes no wheel speeds: a vehicle with reaction wheels is refused, naming the key
    with pytest.raises(ValueError, match=r"vehicle\.wheel: the Detector does not take"):
        eqtrack.Detector(REPO / "scenarios" / "wheels_slew.toml", {"fault_detection": {"window": 0.1}})
    d = eqtrack.Detector(scenario)
    q, v, tau = np.eye(4), np.zeros(6), np.zeros(6)
    with pytest.raises(ValueError, match=r"v: expected shape \(6,\), got \(3,\)"):
        d.step(0.0, q, v[:3], tau)
    with pytest.raises(ValueError, match=r"q: expected shape \(4, 4\)"):
        d.step(0.0, np.eye(3), v, tau)
    with pytest.raises(ValueError, match="wrench: entry 2 is NaN"):
        d.step(0.0, q, v, [0.0, 0.0, float("nan"), 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="applied: entry 0 is inf"):
        d.step(0.0, q, v, tau, applied=[float("inf")] + [0.0] * 5)
    with pytest.raises(ValueError, match="t: NaN is not a finite time"):
        d.step(float("nan"), q, v, tau)
    # a refused step changes nothing: the next one is still the first
    out = d.step(0.0, q, v, tau)
    assert out["detection"] is None and out["suspect"] is None and out["alarms"] == 0
