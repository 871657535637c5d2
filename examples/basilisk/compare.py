#!/usr/bin/env python3
"""Basilisk's flight of a reaction-wheel scenario beside plant_sim's: the differences.

    python examples/basilisk/compare.py BASILISK.csv TRAJECTORY.csv [--figure FILE.png]
        [--attitude 1e-6] [--speed 1e-6]

BASILISK.csv is examples/basilisk/spacecraft.py's output, TRAJECTORY.csv `plant_sim sim`'s of
the same scenario. Both are flown by the same law and allocation (the controller process in
one, the in-process loop in the other); the physics differ: Basilisk's RK4 on the hub's MRPs
and the wheels' speeds, plant_sim's RKMK4 on the rotation group. It prints the largest
attitude difference (the angle of R_bsk^T R_sim), body-rate difference and wheel-speed
difference, where each first exceeds 1e-9, and both runs' final
Lyapunov values, and draws the figure (with matplotlib). Exit 0 when the attitude and
wheel-speed differences stay below --attitude (rad) and --speed (rad/s), 1 otherwise.
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))
from trajectories import angle_between, load, rotation  # noqa: E402


def wheels(d):
    return sum(1 for k in d if k.startswith("wheel_speed_"))


def draw(path, a, b, dr, dw, title):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, n = a["t"], wheels(a)
    fig, ax = plt.subplots(2, 2, figsize=(12, 8))
    for i in range(n):
        ax[0, 0].plot(t, b[f"wheel_speed_{i}"], lw=2.5, alpha=0.5, label=f"wheel {i} plant_sim")
        ax[0, 0].plot(t, a[f"wheel_speed_{i}"], "k--", lw=0.8, label="Basilisk" if i == 0 else None)
    ax[0, 0].set(title="wheel speeds relative to the body (rad/s)", xlabel="t (s)")
    ax[0, 0].legend(fontsize=8)
    ax[0, 1].semilogy(t, np.maximum(b["lyapunov"], 1e-16), lw=2.5, alpha=0.5, label="plant_sim")
    ax[0, 1].semilogy(t, np.maximum(a["lyapunov"], 1e-16), "k--", lw=0.8, label="Basilisk")
    ax[0, 1].set(title="the controller's Lyapunov function L", xlabel="t (s)")
    ax[0, 1].legend(fontsize=8)
    for j in range(n):
        ax[1, 0].plot(t, b[f"u_{j}"], lw=2.0, alpha=0.5)
        ax[1, 0].plot(t, a[f"u_{j}"], "k--", lw=0.6)
    ax[1, 0].set(title="motor torques u_j (N m): plant_sim (colour), Basilisk (dashed)", xlabel="t (s)")
    ax[1, 1].semilogy(t, np.maximum(dr, 1e-17), label="attitude (rad)")
    ax[1, 1].semilogy(t, np.maximum(dw, 1e-17), label="largest wheel speed (rad/s)")
    ax[1, 1].set(title="Basilisk against plant_sim", xlabel="t (s)")
    ax[1, 1].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def first_above(t, x, level):
    above = np.nonzero(x > level)[0]
    return f"{t[above[0]]:.2f} s" if len(above) else "never"


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("basilisk")
    p.add_argument("trajectory")
    p.add_argument("--figure", help="draw the comparison here (needs matplotlib)")
    p.add_argument("--title", default="Basilisk as the plant process, the unchanged controller_node")
    p.add_argument("--attitude", type=float, default=1e-6, help="largest attitude difference (rad)")
    p.add_argument("--speed", type=float, default=1e-6, help="largest wheel-speed difference (rad/s)")
    args = p.parse_args()
    a, b = load(args.basilisk), load(args.trajectory)
    if len(a["t"]) != len(b["t"]) or not np.array_equal(a["t"], b["t"]):
        sys.exit(f"compare: the runs' times differ ({len(a['t'])} and {len(b['t'])} rows)")
    n = wheels(a)
    if n == 0 or n != wheels(b):
        sys.exit(f"compare: {n} wheels in {args.basilisk}, {wheels(b)} in {args.trajectory}")
    t = a["t"]
    dr = angle_between(rotation(a), rotation(b))
    dv = np.max([np.abs(a[f"v_{i}"] - b[f"v_{i}"]) for i in range(3)], axis=0)
    dw = np.max([np.abs(a[f"wheel_speed_{i}"] - b[f"wheel_speed_{i}"]) for i in range(n)], axis=0)
    top = max(np.abs(b[f"wheel_speed_{i}"]).max() for i in range(n))
    print(
        f"compare: {len(t)} rows, {n} wheels; largest differences: attitude {dr.max():.3e} rad "
        f"(t = {t[dr.argmax()]:.2f} s), body rate {dv.max():.3e} rad/s, wheel speed {dw.max():.3e} rad/s "
        f"(t = {t[dw.argmax()]:.2f} s; the wheels up to {top:.1f} rad/s)"
    )
    print(
        f"compare: first above 1e-9 (rad, rad/s): attitude {first_above(t, dr, 1e-9)}, "
        f"wheel speed {first_above(t, dw, 1e-9)}; L at the end {a['lyapunov'][-1]:.4e} (Basilisk), "
        f"{b['lyapunov'][-1]:.4e} (plant_sim)"
    )
    if args.figure:
        draw(args.figure, a, b, dr, dw, args.title)
        print(f"compare: wrote {args.figure}")
    if not (dr.max() < args.attitude and dw.max() < args.speed):
        print(f"compare: FAIL: a difference above {args.attitude} rad or {args.speed} rad/s")
        sys.exit(1)


if __name__ == "__main__":
    main()
