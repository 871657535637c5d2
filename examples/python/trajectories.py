"""Reading a flight's CSV (`plant_sim`'s trajectory.csv, or a Python plant's output) for the
comparisons of examples/mujoco/ and examples/basilisk/."""
import csv
import sys

import numpy as np


def load(path):
    """The file's columns by name, as float arrays (exits naming the file when it has no rows)."""
    with open(path) as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"compare: {path} has no rows")
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def rotation(d):
    """The attitude R (body to world) of every row, from its q_ij columns."""
    return np.stack([np.stack([d[f"q_{i}{j}"] for j in range(3)], axis=1) for i in range(3)], axis=1)


def angle_between(ra, rb):
    """The angle (rad) of the rotation R_a^T R_b at every row, from its skew part (accurate for
    the small angles compared here) and its trace (for the large ones)."""
    m = np.einsum("kji,kjl->kil", ra, rb)
    skew = np.stack([m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]], axis=1) / 2
    s = np.linalg.norm(skew, axis=1)
    c = (np.trace(m, axis1=1, axis2=2) - 1) / 2
    return np.arctan2(s, c)
