#!/usr/bin/env python3
"""Ray Tune searches the EqT gains (kp, kd) that minimise a Monte Carlo cost.

Each trial flies the extended paper's Monte Carlo study (its random initial attitudes and
rates, the seed's reference, 20 s) with the trial's gains, through ``eqtrack.montecarlo``,
and scores it with

    J(kp, kd) = mean over runs of t_s  +  0.1 * mean over runs of E_20

where ``t_s`` is the run's settling time (the first time after which the attitude error
``||I - R_d^T R||_F`` stays below 0.1; a run that never settles counts the whole 20 s) and
``E_20`` its control effort ``sum ||tau_k|| h`` over the 20 s (N m s). The first term asks for
fast convergence from anywhere, the second charges the torque it costs. The paper's gains
(kp = 1, kd = 0.5) are scored with the same runs for comparison.

    python examples/python/tune_gains.py --samples 40 --runs 100

Needs ``pip install ./python "ray[tune]"``. The trials go to ``--out`` (a CSV per trial and
``trials.csv``); Ray's own files to a temporary directory.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import sys
import tempfile

import numpy as np

import eqtrack

HORIZON = 20.0
EFFORT_WEIGHT = 0.1


def cost(kp: float, kd: float, runs: int, seed: int) -> dict:
    """The Monte Carlo cost of the gains, and its two terms."""
    cols = eqtrack.montecarlo(
        runs=runs,
        seed=seed,
        laws=("eqt",),
        threads=1,
        overrides={"controller": {"kp": kp, "kd": kd}},
    )
    settle = np.where(np.isnan(cols["settling_time"]), HORIZON, cols["settling_time"])
    effort = cols["effort_0_20"]
    return {
        "cost": float(settle.mean() + EFFORT_WEIGHT * effort.mean()),
        "mean_settling_time": float(settle.mean()),
        "mean_effort_0_20": float(effort.mean()),
        "unsettled": int(np.isnan(cols["settling_time"]).sum()),
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--samples", type=int, default=40, help="Tune trials (default 40)")
    p.add_argument("--runs", type=int, default=100, help="Monte Carlo runs per trial (default 100)")
    p.add_argument("--seed", type=int, default=1, help="seed of the runs' initial conditions")
    p.add_argument("--out", default="out/tune", help="where trials.csv goes")
    p.add_argument("--cpus", type=int, default=None, help="CPUs of the local Ray cluster")
    a = p.parse_args()
    if a.samples < 1 or a.runs < 1:
        p.error("--samples and --runs must be at least 1")

    os.environ.setdefault("RAY_AUTH_MODE", "disabled")
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    import ray
    from ray import tune

    ray.init(num_cpus=a.cpus, include_dashboard=False, log_to_driver=False)
    runs, seed = a.runs, a.seed

    def objective(config):
        return cost(config["kp"], config["kd"], runs, seed)

    with tempfile.TemporaryDirectory() as storage:
        tuner = tune.Tuner(
            objective,
            param_space={"kp": tune.loguniform(0.1, 10.0), "kd": tune.loguniform(0.1, 10.0)},
            tune_config=tune.TuneConfig(metric="cost", mode="min", num_samples=a.samples),
            run_config=tune.RunConfig(storage_path=storage, name="eqtrack_gains", verbose=0),
        )
        results = tuner.fit()
        rows = []
        for r in results:
            if r.error is not None:
                print(f"a trial failed: {r.error}", file=sys.stderr)
                return 1
            rows.append({**r.config, **{k: r.metrics[k] for k in
                                        ("cost", "mean_settling_time", "mean_effort_0_20", "unsettled")}})
    ray.shutdown()
    rows.sort(key=lambda r: r["cost"])
    os.makedirs(a.out, exist_ok=True)
    path = os.path.join(a.out, "trials.csv")
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    best = rows[0]
    paper = cost(1.0, 0.5, runs, seed)
    if not all(math.isfinite(r["cost"]) for r in rows):
        print("a trial's cost is not finite", file=sys.stderr)
        return 1
    print(f"{len(rows)} trials of {runs} runs each; cost J = mean t_s + {EFFORT_WEIGHT} * mean E_20")
    print(f"best:  kp = {best['kp']:.4g}, kd = {best['kd']:.4g}: J = {best['cost']:.4f} "
          f"(mean t_s {best['mean_settling_time']:.3f} s, mean E_20 {best['mean_effort_0_20']:.3f}, "
          f"{best['unsettled']} unsettled)")
    print(f"paper: kp = 1, kd = 0.5: J = {paper['cost']:.4f} "
          f"(mean t_s {paper['mean_settling_time']:.3f} s, mean E_20 {paper['mean_effort_0_20']:.3f}, "
          f"{paper['unsettled']} unsettled)")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
