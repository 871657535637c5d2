"""eqtrack from Python: equivariant tracking control on matrix Lie groups.

The numbers are the command line's: :func:`simulate` runs ``plant_sim sim``'s closed loop and
:func:`montecarlo` the study of ``plant_sim montecarlo``, through the same Rust libraries,
with the GIL released while Rust works. The building blocks (:class:`Controller`,
:class:`ComplementaryFilter`, :class:`EquivariantFilter`, :class:`Allocator`, :class:`Detector`)
step on numpy arrays. A bad input raises ``ValueError`` naming what is wrong, with the message the command
line gives for the same mistake.
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, Iterable, Optional, Sequence, Union

import numpy as np

from . import _native
from ._native import Allocator, ComplementaryFilter, Controller, Detector, EquivariantFilter

__all__ = [
    "Allocator",
    "ComplementaryFilter",
    "Controller",
    "Detector",
    "EquivariantFilter",
    "Run",
    "builtin_scenario",
    "montecarlo",
    "simulate",
]

Scenario = Union[str, "os.PathLike[str]"]
LAWS = ("eqt", "gt", "nog", "asym")


def builtin_scenario(name: str) -> str:
    """The TOML text of a built-in scenario (``seed``, ``montecarlo``, ``se3_circle``,
    ``se2_circle``)."""
    return _native.builtin_scenario(name)


class Run:
    """One simulated run: ``columns`` holds exactly ``trajectory.csv``'s columns (name to a
    float64 array, an empty cell as NaN) and ``summary`` equals ``summary.json``."""

    def __init__(self, header: Sequence[str], columns: Sequence[np.ndarray], summary: str):
        self.columns: Dict[str, np.ndarray] = dict(zip(header, columns))
        self.summary: Dict[str, Any] = json.loads(summary)

    def to_pandas(self):
        """The columns as a ``pandas.DataFrame`` (needs pandas)."""
        import pandas as pd

        return pd.DataFrame(self.columns)

    def __repr__(self) -> str:
        rows = len(next(iter(self.columns.values()))) if self.columns else 0
        return f"Run(scenario={self.summary.get('scenario')!r}, rows={rows}, columns={len(self.columns)})"


def simulate(scenario: Scenario, **overrides: Any) -> Run:
    """Runs ``scenario`` (a path, or TOML text) in this process, as ``plant_sim sim``.

    Keyword arguments override the scenario's keys before it is checked; a dict overrides a
    table key by key: ``simulate("seed.toml", law="gt", controller={"kd": 2.0})``, or
    ``controller={"error_frame": "world"}`` for the papers' form of EqT (the default forms its
    error at the reference; docs/maths.md, "World-frame invariance").
    """
    header, columns, summary = _native.simulate(scenario, overrides or None)
    return Run(header, columns, summary)


def _as_columns(d: Dict[str, Any]) -> Dict[str, np.ndarray]:
    out = dict(d)
    out["law"] = np.array(out["law"], dtype=str)
    return out


def montecarlo(
    scenario: Optional[Scenario] = None,
    runs: int = 200,
    seed: int = 1,
    laws: Iterable[str] = LAWS,
    engine: str = "local",
    **engine_options: Any,
) -> Dict[str, np.ndarray]:
    """The extended paper's Monte Carlo study: ``runs`` samples drawn from ``seed``, each
    flown by every law in ``laws``. Returns ``runs.csv``'s columns (``run``, ``law``, the
    sample ``rx … wz``, ``final_attitude_error``, ``effort_0_5``, ``effort_0_20``,
    ``settling_time`` with NaN for a run that did not settle), equal to ``plant_sim
    montecarlo``'s ``runs.csv`` whatever the engine.

    ``engine="local"``: this process, ``threads=`` worker threads (default one per core).
    ``engine="ray"``: seed-indexed shards as Ray tasks (see :func:`eqtrack.ray_engine.run`):
    ``address=`` a running cluster (default: start a local one), ``shards=`` how many (default
    twice the cluster's CPUs), ``overrides=`` scenario keys, ``max_retries=`` per task (Ray's
    default 3).
    """
    laws = list(laws)
    overrides = engine_options.pop("overrides", None)
    text = _native.scenario_text(scenario, overrides)
    if engine == "local":
        unknown = set(engine_options) - {"threads"}
        if unknown:
            raise ValueError(f"engine 'local': unknown option(s) {sorted(unknown)} (known: threads)")
        return _as_columns(_native.montecarlo(text, runs, seed, laws, engine_options.get("threads")))
    if engine == "ray":
        from . import ray_engine

        return _as_columns(ray_engine.run(text, runs, seed, laws, **engine_options))
    raise ValueError(f"engine: {engine!r} is not an engine (possible values: local, ray)")
