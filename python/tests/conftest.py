"""Shared helpers: the repository, the command line's binary and its outputs."""

import csv
import os
import pathlib
import subprocess

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def plant_sim():
    """The release `plant_sim` (scripts/python.sh builds it; PLANT_SIM overrides)."""
    path = os.environ.get("PLANT_SIM", str(REPO / "target" / "release" / "plant_sim"))
    if not os.access(path, os.X_OK):
        pytest.fail(f"plant_sim not built at {path} (scripts/python.sh builds it)")
    return path


def read_csv(path):
    """A CSV's columns as float64 arrays (an empty cell as NaN), strings where not numbers."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    cols = {}
    for j, name in enumerate(header):
        cells = [r[j] for r in body]
        try:
            cols[name] = np.array([float(c) if c != "" else np.nan for c in cells])
        except ValueError:
            cols[name] = np.array(cells, dtype=str)
    return header, cols


def cli(plant_sim, *args):
    """Runs plant_sim; returns (exit code, stdout, stderr)."""
    p = subprocess.run([plant_sim, *args], capture_output=True, text=True, timeout=600)
    return p.returncode, p.stdout, p.stderr


def same_bits(a, b):
    """Equal float64 arrays bit for bit (NaN equal to NaN)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))
