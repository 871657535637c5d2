"""The Python examples run: Ray Tune with a tiny budget (the paper's gains scored beside its
best), and the seed figure with matplotlib."""

import csv
import math
import subprocess
import sys

import pytest

from conftest import REPO


def test_the_tune_example_runs_with_a_tiny_budget(tmp_path):
    import ray.tune  # noqa: F401  (the example needs it)
    p = subprocess.run(
        [sys.executable, str(REPO / "examples/python/tune_gains.py"), "--samples", "3", "--runs", "4",
         "--cpus", "2", "--out", str(tmp_path)],
        capture_output=True, text=True, timeout=600,
    )
    assert p.returncode == 0, p.stdout + p.stderr
    best = [l for l in p.stdout.splitlines() if l.startswith("best:")]
    paper = [l for l in p.stdout.splitlines() if l.startswith("paper:")]
    assert best and paper, p.stdout
    with open(tmp_path / "trials.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 3
    costs = [float(r["cost"]) for r in rows]
    assert costs == sorted(costs) and all(math.isfinite(c) for c in costs)
    for r in rows:
        assert 0.1 <= float(r["kp"]) <= 10.0 and 0.1 <= float(r["kd"]) <= 10.0
    # the best trial's cost is the one printed
    assert f"J = {costs[0]:.4f}" in best[0]


def test_the_seed_figure_script_draws_the_seed_run(tmp_path):
    import matplotlib  # noqa: F401  (the script needs it)
    out = tmp_path / "seed.png"
    p = subprocess.run([sys.executable, str(REPO / "examples/python/seed_figure.py"), "--out", str(out)],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout + p.stderr
    assert out.stat().st_size > 10_000
    # the seed's L, as docs/simulations.md states it: 18.17 at t = 0, 0.0327 at t = 20 s
    assert "L: 18.17 at t = 0, 0.03272 at t = 20.0 s" in p.stdout
