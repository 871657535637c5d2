#!/usr/bin/env python3
"""What Python costs over Rust: one Controller.compute call, and eqtrack.simulate against
`plant_sim sim` on the same scenario (BENCHMARKS.md, "16. From Python: what a call costs").

    python examples/python/overhead.py [--plant-sim target/release/plant_sim]
"""

import argparse
import os
import statistics
import subprocess
import tempfile
import time
import timeit

import numpy as np

import eqtrack

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--plant-sim", default=os.path.join(REPO, "target", "release", "plant_sim"))
    p.add_argument("--repeat", type=int, default=7)
    a = p.parse_args()
    seed = os.path.join(REPO, "scenarios", "seed.toml")

    ctrl = eqtrack.Controller(seed)
    q = np.eye(3)
    v = np.array([0.1, -0.2, 0.3])
    q_d = np.eye(3)
    v_d = np.zeros(3)
    tau_d = np.array([1.0, 0.0, 0.0])
    n = 200_000
    per_call = min(timeit.repeat(lambda: ctrl.compute(q, v, q_d, v_d, tau_d), number=n, repeat=a.repeat)) / n
    print(f"Controller.compute (SO(3) EqT, float64 numpy inputs): {per_call * 1e9:.0f} ns per call "
          f"(best of {a.repeat} x {n})")
    lists = min(timeit.repeat(lambda: ctrl.compute(q.tolist(), v.tolist(), q_d.tolist(), v_d.tolist(),
                                                   tau_d.tolist()), number=n // 10, repeat=a.repeat)) / (n // 10)
    print(f"Controller.compute with Python lists (converted by numpy.asarray): {lists * 1e9:.0f} ns per call")

    def sim():
        t0 = time.perf_counter()
        eqtrack.simulate(seed)
        return time.perf_counter() - t0

    def cli(out):
        t0 = time.perf_counter()
        subprocess.run([a.plant_sim, "sim", "--scenario", seed, "--out", out], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        return time.perf_counter() - t0

    with tempfile.TemporaryDirectory() as out:
        py = [sim() for _ in range(a.repeat)]
        rs = [cli(out) for _ in range(a.repeat)]
    print(f"eqtrack.simulate(seed): median {statistics.median(py) * 1e3:.1f} ms "
          f"(the loop, the columns and the summary)")
    print(f"plant_sim sim --scenario seed: median {statistics.median(rs) * 1e3:.1f} ms "
          f"(the process, the loop, trajectory.csv, summary.json and the figures)")


if __name__ == "__main__":
    main()
