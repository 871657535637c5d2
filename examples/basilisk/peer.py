#!/usr/bin/env python3
"""A peer law side by side: Basilisk's own flight software flies the slew eqtrack's law flew.

    python examples/basilisk/peer.py --scenario scenarios/wheels_profile.toml \\
        --eqtrack OUT/eqtrack/basilisk.csv --out OUT [--figure FILE.png]

The scenario is a rest-to-rest C² slew on reaction wheels: two waypoints in its `[reference]
waypoints` file, the geodesic between them timed by the quintic minimum-jerk scaling
(docs/maths.md, "Paths through waypoints"). --eqtrack is examples/basilisk/spacecraft.py's
flight of it, eqtrack's law through the plant process. This script flies the same spacecraft,
wheels and limits in Basilisk with Basilisk's own modules: `simpleNav` (no noise),
`attTrackingError` on the same profile (written into an `AttRefMsg` each control period),
`mrpFeedback` and `rwMotorTorque` (the minimum-norm map to the wheels), every control period.

The gains: Basilisk's examples give `mrpFeedback` K = 3.5 and P = 30 (integral off) for their
900/800/600 kg m² hub, gains read from the linearised loop `I θ'' + P θ' + (K/4) θ = 0` (an MRP
is a quarter of a small angle): a damping ratio of 0.53 and a time constant 2I/P of 60 s about
the largest axis. The same rule gives this spacecraft's gains from eqtrack's: eqtrack's law has
the stiffness `tr K − K_ii` = 2 k_p per axis and the damping k_d (the linearised loop of
docs/maths.md, "The geometric integral"), so K = 4·2 k_p and P = k_d make the two linearised
loops one. The integral stays
off in both, as in the examples.

For each flight it computes the settling time (the attitude within 1 mrad of the slew's end
and staying there to the end of the run, at least 5 s), the largest error from the profile,
the peak and total wheel torque (the motors' torques after Basilisk's limits; the total is
Σ_i ∫|u_i| dt), the peak wheel speed and the final error, prints them as a table, and writes
peer.csv (Basilisk's flight) and peer_table.md into --out and, with matplotlib, the figure.
"""
import argparse
import csv
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "python"))
from spacecraft import Spacecraft, fail, load_scenario, write_rows  # noqa: E402
from trajectories import angle_between, load, rotation  # noqa: E402

SETTLE, HOLD = 1e-3, 5.0


def hat(x):
    return np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]])


def exp_so3(r):
    """exp(hat r) by Rodrigues' formula."""
    r = np.asarray(r, dtype=float)
    t = np.linalg.norm(r)
    if t < 1e-12:
        return np.eye(3) + hat(r)
    k = hat(r / t)
    return np.eye(3) + math.sin(t) * k + (1 - math.cos(t)) * k @ k


def log_so3(m):
    """The rotation vector of m (angle below pi)."""
    c = (np.trace(m) - 1) / 2
    w = np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]]) / 2
    t = math.atan2(np.linalg.norm(w), c)
    return w if t < 1e-12 else w * (t / math.sin(t))


class Profile:
    """The scenario's rest-to-rest slew: R_d(t) = R_0 exp(s(σ) ξ), ξ = log(R_0ᵀ R_1),
    s = 10σ³ − 15σ⁴ + 6σ⁵, σ = (t − t_0)/(t_1 − t_0), held at its ends
    (docs/maths.md, "Paths through waypoints")."""

    def __init__(self, s, scenario_path):
        ref = s.get("reference", {})
        name = ref.get("waypoints")
        if not isinstance(name, str):
            fail(2, "reference.waypoints: the peer comparison flies a waypoint slew")
        path = os.path.join(os.path.dirname(os.path.abspath(scenario_path)), name)
        with open(path) as f:
            rows = [r for r in csv.DictReader(f)]
        if len(rows) != 2:
            fail(2, f"reference.waypoints: one rest-to-rest slew (two waypoints), not {len(rows)}")
        (self.t0, r0), (self.t1, r1) = [
            (float(r["t"]), [float(r[k]) for k in ("rx", "ry", "rz")]) for r in rows
        ]
        self.r0, self.r1 = exp_so3(r0), exp_so3(r1)
        self.xi = log_so3(self.r0.T @ self.r1)

    def at(self, t):
        """(R_d, ω_d in the world, ω̇_d in the world)."""
        d = self.t1 - self.t0
        x = min(max((t - self.t0) / d, 0.0), 1.0)
        s = 10 * x**3 - 15 * x**4 + 6 * x**5
        s1 = (30 * x**2 - 60 * x**3 + 30 * x**4) / d
        s2 = (60 * x - 180 * x**2 + 120 * x**3) / d**2
        if x in (0.0, 1.0):
            s1 = s2 = 0.0
        # ξ commutes with exp(sξ): the rate is s' ξ in the reference's axes, s' R_0 ξ in the world
        world = self.r0 @ self.xi
        return self.r0 @ exp_so3(s * self.xi), s1 * world, s2 * world


def fly_basilisk(s, args, wheels, inertia, profile):
    """Basilisk's own flight software on the slew; the rows as spacecraft.py writes them."""
    from Basilisk.architecture import messaging
    from Basilisk.fswAlgorithms import attTrackingError, mrpFeedback, rwMotorTorque
    from Basilisk.simulation import simpleNav
    from Basilisk.utilities import RigidBodyKinematics as rbk

    craft = Spacecraft(s, wheels, inertia)
    craft.check(s, wheels, inertia)
    sim, h = craft.sim, craft.h
    sim.CreateNewProcess("fsw", 10).addTask(sim.CreateNewTask("control", craft.macros.sec2nano(h)))
    nav = simpleNav.SimpleNav()
    nav.ModelTag = "nav"
    nav.scStateInMsg.subscribeTo(craft.sc.scStateOutMsg)
    ref_msg = messaging.AttRefMsg()
    err = attTrackingError.attTrackingError()
    err.ModelTag = "attError"
    err.attNavInMsg.subscribeTo(nav.attOutMsg)
    err.attRefInMsg.subscribeTo(ref_msg)
    vehicle = messaging.VehicleConfigMsgPayload()
    vehicle.ISCPntB_B = inertia.flatten().tolist()  # as the examples: the hub's inertia
    vehicle_msg = messaging.VehicleConfigMsg().write(vehicle)
    rw_params = craft.factory.getConfigMessage()
    ctl = mrpFeedback.mrpFeedback()
    ctl.ModelTag = "mrpFeedback"
    kp, kd = s["controller"]["kp"], s["controller"]["kd"]
    ctl.K, ctl.P, ctl.Ki = 4 * 2 * kp, kd, -1.0
    ctl.guidInMsg.subscribeTo(err.attGuidOutMsg)
    ctl.vehConfigInMsg.subscribeTo(vehicle_msg)
    ctl.rwParamsInMsg.subscribeTo(rw_params)
    ctl.rwSpeedsInMsg.subscribeTo(craft.rws.rwSpeedOutMsg)
    motors = rwMotorTorque.rwMotorTorque()
    motors.ModelTag = "rwMotorTorque"
    motors.controlAxes_B = [1, 0, 0, 0, 1, 0, 0, 0, 1]
    motors.vehControlInMsg.subscribeTo(ctl.cmdTorqueOutMsg)
    motors.rwParamsInMsg.subscribeTo(rw_params)
    craft.rws.rwMotorCmdInMsg.subscribeTo(motors.rwMotorTorqueOutMsg)
    for priority, m in enumerate([motors, ctl, err, nav]):
        sim.AddModelToTask("control", m, ModelPriority=priority + 1)

    def reference(t):
        r_d, w, dw = profile.at(t)
        p = messaging.AttRefMsgPayload()
        p.sigma_RN = list(rbk.C2MRP(r_d.T))
        p.omega_RN_N, p.domega_RN_N = list(w), list(dw)
        ref_msg.write(p, craft.macros.sec2nano(t))

    reference(0.0)
    craft.start()
    steps = round((args.duration or s["duration"]) / h)
    rows = []
    for k in range(steps + 1):
        r, omega, speeds = craft.state()
        u_cmd = list(motors.rwMotorTorqueOutMsg.read().motorTorque)[: craft.count]
        if k < steps:
            reference((k + 1) * h)
            sim.ConfigureStopTime(craft.macros.sec2nano(h * (k + 1)))
            sim.ExecuteSimulation()
        applied = craft.applied() if k < steps else [float("nan")] * craft.count
        rows.append([k * h] + list(r.flatten()) + list(omega) + speeds + [float("nan")] + u_cmd + applied)
    return rows, craft.count


def metrics(d, profile):
    """The table's numbers for a flight `d` (columns as spacecraft.py writes them)."""
    t = d["t"]
    n = sum(1 for k in d if k.startswith("wheel_speed_"))
    r = rotation(d)
    to_end = angle_between(r, np.repeat(profile.r1[None], len(t), axis=0))
    from_profile = angle_between(r, np.stack([profile.at(x)[0] for x in t]))
    outside = np.nonzero(to_end >= SETTLE)[0]
    first = 0 if len(outside) == 0 else outside[-1] + 1
    settled = t[first] if first < len(t) and t[-1] - t[first] >= HOLD else None
    u = np.stack([d[f"u_{j}"][:-1] for j in range(n)])
    h = t[1] - t[0]
    return {
        "settling time (s)": "never" if settled is None else f"{settled:.2f}",
        "largest error from the profile (rad)": f"{from_profile.max():.3e}",
        "peak wheel torque (N m)": f"{np.abs(u).max():.3e}",
        "total wheel torque (N m s)": f"{np.abs(u).sum() * h:.4f}",
        "peak wheel speed (rad/s)": f"{max(np.abs(d[f'wheel_speed_{i}']).max() for i in range(n)):.1f}",
        "final error (rad)": f"{to_end[-1]:.3e}",
    }


def draw(path, flights, profile, title):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(15, 4.5))
    for (name, d), style in zip(flights, ["-", "--"]):
        t, r = d["t"], rotation(d)
        ax[0].semilogy(t, np.maximum(angle_between(r, np.repeat(profile.r1[None], len(t), axis=0)), 1e-9),
                       style, label=name)
        ax[1].semilogy(t, np.maximum(angle_between(r, np.stack([profile.at(x)[0] for x in t])), 1e-12),
                       style, label=name)
        n = sum(1 for k in d if k.startswith("wheel_speed_"))
        for i in range(n):
            ax[2].plot(t, d[f"wheel_speed_{i}"], style, lw=1, label=f"{name}" if i == 0 else None)
    ax[0].axhline(SETTLE, color="grey", lw=0.5)
    ax[0].set(title="error from the slew's end (rad)", xlabel="t (s)")
    ax[1].set(title="error from the profile (rad)", xlabel="t (s)")
    ax[2].set(title="wheel speeds (rad/s)", xlabel="t (s)")
    for a in ax:
        a.legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default=os.path.join(HERE, "..", "..", "scenarios", "wheels_profile.toml"))
    p.add_argument("--eqtrack", required=True, help="spacecraft.py's flight of the scenario (basilisk.csv)")
    p.add_argument("--duration", type=float, help="seconds to fly (default: the scenario's)")
    p.add_argument("--out", default="out/basilisk-peer")
    p.add_argument("--figure", help="draw the two flights here (needs matplotlib)")
    p.add_argument("--title", default="the same slew: eqtrack's EqT through the plant process, Basilisk's mrpFeedback")
    args = p.parse_args()
    s, wheels, inertia = load_scenario(args.scenario)
    profile = Profile(s, args.scenario)
    rows, count = fly_basilisk(s, args, wheels, inertia, profile)
    os.makedirs(args.out, exist_ok=True)
    write_rows(os.path.join(args.out, "peer.csv"), rows, count)
    ours, theirs = load(args.eqtrack), load(os.path.join(args.out, "peer.csv"))
    if len(ours["t"]) != len(theirs["t"]):
        sys.exit(f"peer: {args.eqtrack} has {len(ours['t'])} rows, Basilisk's flight {len(theirs['t'])}")
    m = [metrics(ours, profile), metrics(theirs, profile)]
    gains = f"K = {4 * 2 * s['controller']['kp']:g}, P = {s['controller']['kd']:g}"
    lines = [
        f"| {s.get('name', '')} | eqtrack EqT (k_p = {s['controller']['kp']:g}, k_d = {s['controller']['kd']:g}) "
        f"| Basilisk mrpFeedback + rwMotorTorque ({gains}) |",
        "|---|---|---|",
    ] + [f"| {k} | {m[0][k]} | {m[1][k]} |" for k in m[0]]
    table = "\n".join(lines)
    print(table)
    with open(os.path.join(args.out, "peer_table.md"), "w") as f:
        f.write(table + "\n")
    if args.figure:
        draw(args.figure, [("eqtrack EqT", ours), ("Basilisk mrpFeedback", theirs)], profile, args.title)
        print(f"peer: wrote {args.figure}")


if __name__ == "__main__":
    main()
