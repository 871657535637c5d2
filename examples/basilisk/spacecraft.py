#!/usr/bin/env python3
"""A spacecraft on reaction wheels flown in Basilisk: a plant process in Python, flown by the
unchanged controller.

    python3 -m venv .venv && .venv/bin/pip install bsk==2.12.1 iceoryx2==0.10.0
    controller_node --scenario scenarios/wheels_slew.toml --name bsk              # one terminal
    .venv/bin/python examples/basilisk/spacecraft.py --name bsk --out out/bsk     # another

Basilisk (AVS Lab) integrates the scenario's spacecraft: its hub (`spacecraft.Spacecraft`, the
inertia of `[plant] inertia`, Basilisk's convention too: the whole body with the wheels locked)
and its `[[vehicle.wheel]]` as a `reactionWheelStateEffector` of balanced wheels, with their
torque, speed and power limits and their friction (Coulomb, static with the Stribeck effect,
viscous), on Basilisk's own RK4, `plant_substeps` steps a control period. Each period of the
scenario this process publishes the hub's attitude and rate and the wheels' speeds (relative
to the body) on the run's iceoryx2 state board (the wire of docs/wire.md, protocol 10, with
iceoryx2's own Python bindings), waits for the controller's command for that state, and drives
the wheels' motors with its `u_cmd` over the period (Basilisk holds a motor command until the
next). It is a plant the way a board is one: no scenario fingerprint, its own physics, and the
controller allocates.

It writes `basilisk.csv` (t, the attitude R row-major as q_ij, the body rate v_i, the wheels'
speeds wheel_speed_i, the controller's L, u_cmd_j and the motor torques Basilisk applied after
its limits u_j) into --out. examples/basilisk/compare.py puts it beside `plant_sim sim` of the
same scenario.

The scenario's tables are checked before Basilisk starts, naming the key (exit 2): an SO(3)
scenario, wheels only, each wheel's axis, inertia, limits and friction, and the plant's
inertia less the wheels' spin inertias positive definite. Then the Basilisk model built from
them is read back and compared with the scenario (exit 2 on a difference). Exit codes: 0
flown, 1 the run failed, 2 the scenario or the model is refused.
"""
import argparse
import csv
import math
import os
import sys
import time
import tomllib

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
import plant_wire  # noqa: E402  (the wire's ctypes layout and the plant's boards)
from observe import MAX_WHEELS  # noqa: E402
from plant_wire import SO3  # noqa: E402

WHO = "basilisk-plant"


def fail(code, msg):
    plant_wire.fail(WHO, code, msg)


def number(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def checked_run(s):
    """The run's keys the plant reads, checked (exit 2 naming the key): `control_period` and
    `duration` finite and > 0, `plant_substeps` a whole number >= 1, `[initial] rotation` and
    `velocity` three finite numbers each."""
    for key in ("control_period", "duration"):
        x = s.get(key)
        if not (number(x) and x > 0):
            fail(2, f"{key}: a finite number > 0, not {x!r}")
    n = s.get("plant_substeps", 1)
    if not (isinstance(n, int) and not isinstance(n, bool) and n >= 1):
        fail(2, f"plant_substeps: a whole number >= 1, not {n!r}")
    for key in ("rotation", "velocity"):
        x = s.get("initial", {}).get(key, [0.0, 0.0, 0.0])
        if not (isinstance(x, list) and len(x) == 3 and all(number(v) for v in x)):
            fail(2, f"initial.{key}: three finite numbers, not {x!r}")


def checked_wheels(s):
    """The scenario's wheels, checked as `plant_sim` checks them (exit 2 naming the key):
    the run's keys (`checked_run`); an SO(3) scenario with one to six `[[vehicle.wheel]]` and no
    thrusters; each axis three finite numbers, not zero; `inertia`, `max_torque`, `max_speed`
    finite and > 0; friction finite and >= 0, `stribeck_speed` > 0 where given, `max_power` > 0 where given; the
    initial `speed` within +-`max_speed`; `[plant] inertia` a symmetric 3x3 matrix whose part
    with the wheels free, I - sum Js g g^T, is positive definite. Returns the wheels with unit
    axes and the plant's inertia."""
    checked_run(s)
    if s.get("group") != "so3":
        fail(2, f"group: the Basilisk plant flies SO(3) spacecraft, not {s.get('group')!r}")
    v = s.get("vehicle", {})
    if v.get("actuator"):
        fail(2, "vehicle.actuator: the Basilisk plant flies reaction wheels only")
    wheels = v.get("wheel", [])
    if not 1 <= len(wheels) <= MAX_WHEELS:
        fail(2, f"vehicle.wheel: 1 to {MAX_WHEELS} wheels, not {len(wheels)}")
    out = []
    for i, w in enumerate(wheels):
        key = f"vehicle.wheel[{i}]"
        axis = w.get("axis")
        if not (isinstance(axis, list) and len(axis) == 3 and all(number(x) for x in axis)):
            fail(2, f"{key}.axis: three finite numbers, not {axis!r}")
        norm = math.sqrt(sum(x * x for x in axis))
        if norm == 0.0:
            fail(2, f"{key}.axis: a zero axis")
        for name in ("inertia", "max_torque", "max_speed"):
            x = w.get(name)
            if not (number(x) and x > 0):
                fail(2, f"{key}.{name}: a finite number > 0, not {x!r}")
        for name in ("friction_coulomb", "friction_static", "friction_viscous"):
            x = w.get(name, 0.0)
            if not (number(x) and x >= 0):
                fail(2, f"{key}.{name}: a finite number >= 0, not {x!r}")
        for name in ("stribeck_speed", "max_power"):
            x = w.get(name)
            if x is not None and not (number(x) and x > 0):
                fail(2, f"{key}.{name}: a finite number > 0, not {x!r}")
        speed = w.get("speed", 0.0)
        if not (number(speed) and abs(speed) <= w["max_speed"]):
            fail(2, f"{key}.speed: within +-max_speed, not {speed!r}")
        out.append(dict(w, axis=[x / norm for x in axis], speed=float(speed)))
    inertia = s.get("plant", {}).get("inertia")
    try:
        big_i = np.array(inertia, dtype=float)
    except (TypeError, ValueError):
        fail(2, f"plant.inertia: a 3x3 matrix, not {inertia!r}")
    if big_i.shape != (3, 3) or not np.all(np.isfinite(big_i)) or not np.allclose(big_i, big_i.T):
        fail(2, f"plant.inertia: a symmetric 3x3 matrix of finite numbers, not {inertia!r}")
    free = big_i - sum(w["inertia"] * np.outer(w["axis"], w["axis"]) for w in out)
    if np.linalg.eigvalsh(free).min() <= 0:
        fail(2, "plant.inertia: with the wheels free, I - sum Js g g^T is not positive definite")
    return out, big_i


def load_scenario(path):
    """The scenario at `path` with its wheels and inertia checked (`checked_wheels`); exit 2
    naming the file when it cannot be read as TOML."""
    try:
        with open(path, "rb") as f:
            s = tomllib.load(f)
    except (OSError, tomllib.TOMLDecodeError) as e:
        fail(2, f"{path}: {e}")
    wheels, inertia = checked_wheels(s)
    return s, wheels, inertia


def rotation_to_mrp(r):
    """The MRP of [BN] for our Q = exp(hat(r)), which maps body to world: [BN] = Q^T, so
    sigma_BN = e tan(theta/4) with r = theta e."""
    r = np.asarray(r, dtype=float)
    theta = np.linalg.norm(r)
    return (r / theta) * math.tan(theta / 4) if theta > 0 else np.zeros(3)


def mrp_to_dcm(sigma):
    """[BN] from sigma_BN (Schaub and Junkins): I + (8 [s]^2 - 4 (1 - s^2) [s]) / (1 + s^2)^2."""
    s = np.asarray(sigma, dtype=float)
    x = np.array([[0, -s[2], s[1]], [s[2], 0, -s[0]], [-s[1], s[0], 0]])
    s2 = s @ s
    return np.eye(3) + (8 * x @ x - 4 * (1 - s2) * x) / (1 + s2) ** 2


class Spacecraft:
    """The Basilisk simulation of the scenario's spacecraft, stepped one control period at a
    time: the hub and the wheels' effector in one task of `plant_substeps` steps a period (the
    wheels first), the motor command a message both read."""

    def __init__(self, s, wheels, inertia):
        from Basilisk.architecture import messaging
        from Basilisk.simulation import reactionWheelStateEffector, spacecraft
        from Basilisk.utilities import SimulationBaseClass, macros, simIncludeRW

        self.messaging, self.macros = messaging, macros
        self.h = float(s["control_period"])
        substeps = int(s.get("plant_substeps", 1))
        step = macros.sec2nano(self.h / substeps)
        if step * substeps != macros.sec2nano(self.h):
            fail(2, f"plant_substeps: the control period {self.h} s is not a whole number of nanosecond steps")
        self.sim = SimulationBaseClass.SimBaseClass()
        # the dynamics before any flight software at the same time (examples/basilisk/peer.py)
        self.sim.CreateNewProcess("plant", 100).addTask(self.sim.CreateNewTask("dynamics", step))
        sc = spacecraft.Spacecraft()
        sc.ModelTag = "hub"
        sc.hub.mHub = 1.0  # the attitude does not depend on it: no force acts
        sc.hub.IHubPntBc_B = inertia.tolist()
        init = s.get("initial", {})
        sc.hub.sigma_BNInit = [[x] for x in rotation_to_mrp(init.get("rotation", [0.0, 0.0, 0.0]))]
        sc.hub.omega_BN_BInit = [[float(x)] for x in init.get("velocity", [0.0, 0.0, 0.0])]
        factory = simIncludeRW.rwFactory()
        for i, w in enumerate(wheels):
            friction = [float(w.get(k, 0.0)) for k in ("friction_coulomb", "friction_static", "friction_viscous")]
            factory.create(
                "custom",
                w["axis"],
                Js=float(w["inertia"]),
                u_max=float(w["max_torque"]),
                Omega_max=float(w["max_speed"]) / macros.RPM,  # the factory takes rpm
                Omega=w["speed"] / macros.RPM,
                P_max=float(w.get("max_power", -1.0)),
                useRWfriction=friction[0] > 0,
                fCoulomb=friction[0],
                fStatic=friction[1],
                cViscous=friction[2],
                betaStatic=float(w.get("stribeck_speed", -1.0)),
                label=f"RW{i}",
            )
        self.factory = factory
        self.rws = reactionWheelStateEffector.ReactionWheelStateEffector()
        self.rws.ModelTag = "wheels"
        factory.addToSpacecraft("wheels", self.rws, sc)
        # the wheels read their command before the hub integrates
        self.sim.AddModelToTask("dynamics", self.rws, ModelPriority=2)
        self.sim.AddModelToTask("dynamics", sc, ModelPriority=1)
        self.cmd = messaging.ArrayMotorTorqueMsg()
        self.rws.rwMotorCmdInMsg.subscribeTo(self.cmd)
        self.sc, self.count = sc, len(wheels)

    def start(self):
        self.sim.InitializeSimulation()
        # the t = 0 state messages are written by a first execution to time 0
        self.sim.ConfigureStopTime(0)
        self.sim.ExecuteSimulation()

    def check(self, s, wheels, inertia):
        """The model built is the scenario's (to 1e-12): the hub's inertia and each wheel's axis,
        Js, torque and speed limits, friction and initial speed, read back from Basilisk."""
        want = {"hub inertia": (np.array(self.sc.hub.IHubPntBc_B), inertia)}
        for i, (rw, w) in enumerate(zip(self.factory.rwList.values(), wheels)):
            want[f"wheel {i} axis"] = (np.array(rw.gsHat_B).ravel(), np.array(w["axis"]))
            want[f"wheel {i} Js"] = (rw.Js, w["inertia"])
            want[f"wheel {i} u_max"] = (rw.u_max, w["max_torque"])
            want[f"wheel {i} Omega_max"] = (rw.Omega_max, w["max_speed"])
            want[f"wheel {i} speed"] = (rw.Omega, w["speed"])
            want[f"wheel {i} friction"] = (
                [rw.fCoulomb, rw.fStatic, rw.cViscous],
                [w.get(k, 0.0) for k in ("friction_coulomb", "friction_static", "friction_viscous")],
            )
        for what, (got, expected) in want.items():
            if not np.allclose(got, expected, rtol=1e-12, atol=1e-15):
                fail(2, f"the model's {what} is {got}, the scenario's {expected}")

    def perturb(self):
        """A planted error: wheel 0's spin inertia 0.1 % larger than the scenario's."""
        rw = next(iter(self.factory.rwList.values()))
        rw.Js *= 1.001

    def state(self):
        """(R, omega, wheel speeds): R body to world, omega in body axes, the speeds relative to
        the body."""
        st = self.sc.scStateOutMsg.read()
        speeds = list(self.rws.rwSpeedOutMsg.read().wheelSpeeds)[: self.count]
        return mrp_to_dcm(st.sigma_BN).T, np.array(st.omega_BN_B), speeds

    def step(self, k, torques):
        """The motors' torques held over period k (from t_k to t_k+1)."""
        p = self.messaging.ArrayMotorTorqueMsgPayload()
        p.motorTorque = list(torques)
        self.cmd.write(p, self.sim.TotalSim.CurrentNanos)
        self.sim.ConfigureStopTime(self.macros.sec2nano(self.h * (k + 1)))
        self.sim.ExecuteSimulation()

    def applied(self):
        """The motor torques Basilisk applied over the last period, after its limits."""
        return [self.rws.rwOutMsgs[i].read().u_current for i in range(self.count)]


def fly(args, s, craft, wire):
    """The lockstep loop: state k out, command k in, the motors driven over the period."""
    h = craft.h
    steps = round((args.duration or s["duration"]) / h)
    count = craft.count
    rows, accounted = [], [0.0] * 3
    for k in range(steps + 1):
        r, omega, speeds = craft.state()
        c, u_cmd, accounted = wire.exchange(k, h, r.flatten(), omega, accounted, count, speeds)
        if k < steps:
            craft.step(k, u_cmd)
        applied = craft.applied() if k < steps else [float("nan")] * count
        rows.append([k * h] + list(r.flatten()) + list(omega) + speeds + [c.lyapunov] + u_cmd + applied)
    wire.bye(steps + 1, h)
    return rows


def write_rows(path, rows, count):
    """A flight's rows as CSV: t, q_ij (R row-major), v_i, wheel_speed_i, lyapunov, u_cmd_j, u_j."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(
            ["t"]
            + [f"q_{i}{j}" for i in range(3) for j in range(3)]
            + [f"v_{i}" for i in range(3)]
            + [f"wheel_speed_{i}" for i in range(count)]
            + ["lyapunov"]
            + [f"u_cmd_{j}" for j in range(count)]
            + [f"u_{j}" for j in range(count)]
        )
        w.writerows([[repr(float(x)) for x in r] for r in rows])


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--name", default="basilisk", help="the run name (controller_node --name)")
    p.add_argument("--scenario", default=os.path.join(HERE, "..", "..", "scenarios", "wheels_slew.toml"))
    p.add_argument("--duration", type=float, help="seconds to fly (default: the scenario's)")
    p.add_argument("--out", default="out/basilisk", help="where basilisk.csv goes")
    p.add_argument(
        "--perturb",
        action="store_true",
        help="after the model check, make wheel 0's spin inertia 0.1 %% larger (a planted error the comparison must catch)",
    )
    p.add_argument("--check-only", action="store_true", help="check the scenario and the model, then exit")
    args = p.parse_args()
    s, wheels, inertia = load_scenario(args.scenario)
    craft = Spacecraft(s, wheels, inertia)
    craft.check(s, wheels, inertia)
    if args.check_only:
        print(f"{WHO}: {args.scenario}: the model is the scenario's ({len(wheels)} wheels)")
        return
    if args.perturb:
        craft.perturb()
    craft.start()
    import iceoryx2 as iox2

    iox2.set_log_level_from_env_or(iox2.LogLevel.Error)
    node = iox2.NodeBuilder.new().create(iox2.ServiceType.Ipc)
    wire = plant_wire.Wire(node, args.name, SO3, WHO)
    started = time.monotonic()
    rows = fly(args, s, craft, wire)
    os.makedirs(args.out, exist_ok=True)
    path = os.path.join(args.out, "basilisk.csv")
    write_rows(path, rows, craft.count)
    print(f"{WHO}: {len(rows)} cycles in {time.monotonic() - started:.2f} s; wrote {path}")


if __name__ == "__main__":
    main()
