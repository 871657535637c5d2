"""The Ray engine: a local cluster's sweep equals the local engine and the command line, and
a worker killed mid-sweep (found through Ray's state API, killed by its pid) is retried with
the result unchanged."""

import os
import pathlib
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import eqtrack
from conftest import cli, read_csv, same_bits

import ray
ENV = dict(os.environ, RAY_AUTH_MODE="disabled", RAY_USAGE_STATS_ENABLED="0")
os.environ.update(RAY_AUTH_MODE="disabled", RAY_USAGE_STATS_ENABLED="0")


def equal(a, b):
    assert list(a) == list(b)
    for k in a:
        if k == "law":
            assert list(a[k]) == list(b[k])
        else:
            assert same_bits(a[k], b[k]), f"column {k} differs"


def test_a_two_worker_cluster_equals_the_local_engine_and_the_cli(plant_sim, tmp_path):
    code, _, err = cli(plant_sim, "montecarlo", "--runs", "30", "--seed", "5", "--out", str(tmp_path))
    assert code == 0, err
    header, csv_cols = read_csv(tmp_path / "runs.csv")
    local = eqtrack.montecarlo(runs=30, seed=5)
    assert list(local) == header
    for name in header:
        if name != "law":
            assert same_bits(local[name], csv_cols[name]), name
    # a local cluster of 2 CPUs (two workers), 7 shards: more shards than workers
    on_ray = eqtrack.montecarlo(runs=30, seed=5, engine="ray", num_cpus=2, shards=7)
    equal(on_ray, local)
    assert not ray.is_initialized(), "the engine shuts down the cluster it started"


def _ray_cli(*args):
    ray_bin = pathlib.Path(sys.executable).parent / "ray"
    return subprocess.run([str(ray_bin), *args], env=ENV, capture_output=True, text=True, timeout=120)


DRIVER = """
import sys, numpy as np, eqtrack
cols = eqtrack.montecarlo(runs=200, seed=2, laws=("eqt", "gt", "nog"), engine="ray",
                          address="auto", shards=2, overrides={"duration": 100.0})
np.savez(sys.argv[1], **{k: np.asarray(v) for k, v in cols.items()})
"""


def test_a_worker_killed_mid_sweep_is_retried_and_the_result_is_unchanged(tmp_path):
    from ray.util.state import list_tasks

    started = _ray_cli("start", "--head", "--num-cpus=2", "--disable-usage-stats")
    assert started.returncode == 0, started.stderr
    try:
        out = tmp_path / "ray.npz"
        driver = subprocess.Popen([sys.executable, "-c", DRIVER, str(out)], env=ENV)
        killed = None
        deadline = time.monotonic() + 90
        while killed is None and time.monotonic() < deadline and driver.poll() is None:
            try:
                running = list_tasks(
                    filters=[("name", "=", "eqtrack_shard"), ("state", "=", "RUNNING")],
                    raise_on_missing_output=False,
                )
            except Exception:  # the state API comes up with the dashboard
                running = []
            for t in running:
                pid = getattr(t, "worker_pid", None)
                if pid:
                    os.kill(pid, signal.SIGKILL)
                    killed = pid
                    break
            time.sleep(0.2)
        assert killed is not None, "no running shard task was found to kill"
        assert driver.wait(timeout=300) == 0, "the sweep failed after its worker was killed"
        retried = list_tasks(filters=[("name", "=", "eqtrack_shard")], detail=True,
                             raise_on_missing_output=False)
        assert any(getattr(t, "attempt_number", 0) >= 1 for t in retried), \
            "Ray ran no second attempt of the killed task"
    finally:
        _ray_cli("stop", "--force")
    got = np.load(out)
    expected = eqtrack.montecarlo(runs=200, seed=2, laws=("eqt", "gt", "nog"),
                                  overrides={"duration": 100.0})
    for k in expected:
        if k == "law":
            assert list(got[k]) == list(expected[k])
        else:
            assert same_bits(got[k], expected[k]), f"column {k} differs"
