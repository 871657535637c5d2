#!/usr/bin/env python3
"""The hexarotor flown in MuJoCo: a plant process in Python, flown by the unchanged controller.

    python3 -m venv .venv && .venv/bin/pip install mujoco==4.0.0 iceoryx2==0.10.0 matplotlib
    controller_node --scenario scenarios/hexarotor_eight.toml --name mj          # one terminal
    .venv/bin/python examples/mujoco/hexarotor.py --name mj --out out/mujoco     # another

MuJoCo integrates examples/mujoco/hexarotor.xml: the scenario's body, gravity and six tilted
rotors as site actuators with their lag and limits. Each period of the scenario this process
publishes the body's state on the run's iceoryx2 state board (the wire of docs/wire.md,
protocol 10, with iceoryx2's own Python bindings), waits for the controller's command for that
state, and drives the rotors with its `u_cmd` over the period. It is a plant the way a board
is one: no scenario fingerprint, its own physics, and the controller allocates. It writes
`mujoco.csv` (t, the pose Q row-major as q_ij, V, the controller's L, u_cmd_j and the rotors'
output u_j) into --out. examples/mujoco/compare.py puts it beside `plant_sim sim` of the same
scenario. Exit codes: 0 flown, 1 the run failed, 2 the model and the scenario disagree.
"""
import argparse
import csv
import math
import os
import sys
import time
import tomllib

import iceoryx2 as iox2
import mujoco
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
import plant_wire  # noqa: E402  (the wire's ctypes layout and the plant's boards)
from plant_wire import SE3  # noqa: E402


def fail(code, msg):
    plant_wire.fail("mujoco-plant", code, msg)


def check_model(model, s):
    """The MuJoCo model is the scenario's vehicle: mass, inertia, gravity, the step, and each
    rotor's site, axis, drag torque, range and lag (to 1e-9)."""
    v, inertia = s["vehicle"], s["plant"]["inertia"]
    want = {
        "mass": (model.body_mass[1], inertia[3][3]),
        "inertia": (list(model.body_inertia[1]), [inertia[i][i] for i in range(3)]),
        "gravity": (list(model.opt.gravity), [0.0, 0.0, -v.get("gravity", 0.0)]),
        "time step": (model.opt.timestep, s["control_period"] / s.get("plant_substeps", 1)),
        "rotor count": (model.nu, len(v["actuator"])),
    }
    for j, a in enumerate(v["actuator"]):
        ax = np.array(a["axis"]) / np.linalg.norm(a["axis"])
        c = a.get("torque_per_thrust", 0.0)
        want[f"rotor {j} site"] = (list(model.site_pos[j]), a["position"])
        want[f"rotor {j} gear"] = (list(model.actuator_gear[j]), list(ax) + list(c * ax))
        want[f"rotor {j} range"] = (list(model.actuator_ctrlrange[j]), [a["min"], a["max"]])
        want[f"rotor {j} lag"] = (model.actuator_dynprm[j][0], v.get("actuator_time_constant", 0.0))
    for what, (got, expected) in want.items():
        if not np.allclose(got, expected, rtol=0, atol=1e-9):
            fail(2, f"the model's {what} is {got}, the scenario's {expected}")


def initial_state(model, data, s):
    """The scenario's [initial]: rotation vector, position, body velocity (omega, v)."""
    init = s["initial"]
    r = np.array(init.get("rotation", [0.0, 0.0, 0.0]), dtype=float)
    angle = np.linalg.norm(r)
    axis = r / angle if angle > 0 else np.zeros(3)
    quat = np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * axis])
    data.qpos[:3] = init.get("position", [0.0, 0.0, 0.0])
    data.qpos[3:7] = quat
    vel = np.array(init.get("velocity", [0.0] * 6), dtype=float)
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, quat)
    data.qvel[:3] = rot.reshape(3, 3) @ vel[3:]  # MuJoCo: world-frame linear velocity
    data.qvel[3:6] = vel[:3]  # and body-frame angular velocity
    mujoco.mj_forward(model, data)


def pose_and_velocity(data):
    """Q (4x4) and V = (omega, v), both in the body frame."""
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, data.qpos[3:7])
    rot = rot.reshape(3, 3)
    q = np.eye(4)
    q[:3, :3] = rot
    q[:3, 3] = data.qpos[:3]
    v = np.concatenate([data.qvel[3:6], rot.T @ data.qvel[:3]])
    return q, v


def fly(args, s, model, data, wire):
    """The lockstep loop: state k out, command k in, the rotors driven over the period."""
    h = s["control_period"]
    substeps = round(h / model.opt.timestep)
    steps = round((args.duration or s["duration"]) / h)
    count = len(s["vehicle"]["actuator"])
    rows, accounted = [], [0.0] * 6
    for k in range(steps + 1):
        q, v = pose_and_velocity(data)
        c, u_cmd, accounted = wire.exchange(k, h, q.flatten(), v, accounted, count)
        data.ctrl[:] = u_cmd
        if k == 0:
            data.act[:] = np.clip(u_cmd, model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1])
        rows.append([k * h] + list(q.flatten()) + list(v) + [c.lyapunov] + u_cmd + list(data.act))
        if k < steps:
            for _ in range(substeps):
                mujoco.mj_step(model, data)
    wire.bye(steps + 1, h)
    return rows, count


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--name", default="mujoco", help="the run name (controller_node --name)")
    p.add_argument("--scenario", default=os.path.join(HERE, "..", "..", "scenarios", "hexarotor_eight.toml"))
    p.add_argument("--model", default=os.path.join(HERE, "hexarotor.xml"))
    p.add_argument("--duration", type=float, help="seconds to fly (default: the scenario's)")
    p.add_argument("--out", default="out/mujoco", help="where mujoco.csv goes")
    p.add_argument(
        "--perturb",
        action="store_true",
        help="after the model check, make rotor 0 push 0.1 %% harder (a planted error the comparison must catch)",
    )
    args = p.parse_args()
    with open(args.scenario, "rb") as f:
        s = tomllib.load(f)
    model = mujoco.MjModel.from_xml_path(args.model)
    check_model(model, s)
    if args.perturb:
        model.actuator_gear[0] *= 1.001
    data = mujoco.MjData(model)
    initial_state(model, data, s)
    iox2.set_log_level_from_env_or(iox2.LogLevel.Error)
    node = iox2.NodeBuilder.new().create(iox2.ServiceType.Ipc)
    wire = plant_wire.Wire(node, args.name, SE3, "mujoco-plant")
    started = time.monotonic()
    rows, count = fly(args, s, model, data, wire)
    os.makedirs(args.out, exist_ok=True)
    path = os.path.join(args.out, "mujoco.csv")
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(
            ["t"]
            + [f"q_{i}{j}" for i in range(4) for j in range(4)]
            + [f"v_{i}" for i in range(6)]
            + ["lyapunov"]
            + [f"u_cmd_{j}" for j in range(count)]
            + [f"u_{j}" for j in range(count)]
        )
        w.writerows([[repr(float(x)) for x in r] for r in rows])
    print(f"mujoco-plant: {len(rows)} cycles in {time.monotonic() - started:.2f} s; wrote {path}")


if __name__ == "__main__":
    main()
