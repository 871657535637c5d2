#!/usr/bin/env python3
"""MuJoCo's flight of a scenario beside plant_sim's: the two trajectories, their differences.

    python examples/mujoco/compare.py MUJOCO.csv TRAJECTORY.csv [--figure FILE.png] [--tol 1e-6]

MUJOCO.csv is examples/mujoco/hexarotor.py's output, TRAJECTORY.csv `plant_sim sim`'s of the
same scenario. Both are flown by the same law and allocation (the controller process in one,
the in-process loop in the other); the physics differ: MuJoCo's RK4 on its free body with
filter actuators, plant_sim's RKMK4 with the exact actuator lag. It prints the largest
position difference, attitude difference (the Frobenius norm of R_mujoco - R_sim), thrust
difference and both runs' Lyapunov values, and draws the figure (with matplotlib). Exit 0
when the position and attitude differences stay below --tol, 1 otherwise.
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))
from trajectories import load, rotation  # noqa: E402


def position(d):
    return np.stack([d["q_03"], d["q_13"], d["q_23"]], axis=1)


def draw(path, a, b, dp, dr, rotors):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = a["t"]
    fig, ax = plt.subplots(2, 2, figsize=(12, 8))
    pa, pb = position(a), position(b)
    for i, name in enumerate("xyz"):
        ax[0, 0].plot(t, pb[:, i], lw=2.5, alpha=0.5, label=f"{name} plant_sim")
        ax[0, 0].plot(t, pa[:, i], "k--", lw=0.8, label=f"{name} MuJoCo" if i == 0 else None)
    ax[0, 0].set(title="position (m)", xlabel="t (s)")
    ax[0, 0].legend(fontsize=8)
    ax[0, 1].semilogy(t, np.maximum(b["lyapunov"], 1e-16), lw=2.5, alpha=0.5, label="plant_sim")
    ax[0, 1].semilogy(t, np.maximum(a["lyapunov"], 1e-16), "k--", lw=0.8, label="MuJoCo")
    ax[0, 1].set(title="the controller's Lyapunov function L", xlabel="t (s)")
    ax[0, 1].legend(fontsize=8)
    for j in range(rotors):
        ax[1, 0].plot(t, b[f"u_{j}"], lw=2.0, alpha=0.5)
        ax[1, 0].plot(t, a[f"u_{j}"], "k--", lw=0.6)
    ax[1, 0].set(title="rotor thrusts u_j (N): plant_sim (colour), MuJoCo (dashed)", xlabel="t (s)")
    ax[1, 1].semilogy(t, np.maximum(dp, 1e-17), label="|x_MuJoCo - x_sim| (m)")
    ax[1, 1].semilogy(t, np.maximum(dr, 1e-17), label="||R_MuJoCo - R_sim||_F")
    ax[1, 1].set(title="MuJoCo against plant_sim", xlabel="t (s)")
    ax[1, 1].legend(fontsize=8)
    fig.suptitle("hexarotor_eight: MuJoCo as the plant process, the unchanged controller_node")
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("mujoco")
    p.add_argument("trajectory")
    p.add_argument("--figure", help="draw the comparison here (needs matplotlib)")
    p.add_argument("--tol", type=float, default=1e-6, help="largest position and attitude difference")
    args = p.parse_args()
    a, b = load(args.mujoco), load(args.trajectory)
    if len(a["t"]) != len(b["t"]) or not np.array_equal(a["t"], b["t"]):
        sys.exit(f"compare: the runs' times differ ({len(a['t'])} and {len(b['t'])} rows)")
    rotors = sum(1 for k in a if k.startswith("u_cmd_"))
    dp = np.linalg.norm(position(a) - position(b), axis=1)
    dr = np.linalg.norm(rotation(a) - rotation(b), axis=(1, 2))
    du = max(np.abs(a[f"u_{j}"] - b[f"u_{j}"]).max() for j in range(rotors))
    print(
        f"compare: {len(dp)} rows; largest differences: position {dp.max():.3e} m (t = {a['t'][dp.argmax()]:.3f} s), "
        f"attitude {dr.max():.3e}, rotor thrust {du:.3e} N; L at the end {a['lyapunov'][-1]:.4e} (MuJoCo), "
        f"{b['lyapunov'][-1]:.4e} (plant_sim); the body moved {np.ptp(position(b), axis=0).round(3).tolist()} m"
    )
    if args.figure:
        draw(args.figure, a, b, dp, dr, rotors)
        print(f"compare: wrote {args.figure}")
    if not (dp.max() < args.tol and dr.max() < args.tol):
        print(f"compare: FAIL: a difference above {args.tol}")
        sys.exit(1)


if __name__ == "__main__":
    main()
