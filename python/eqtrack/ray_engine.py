"""The Monte Carlo study on a Ray cluster, as seed-indexed shards.

Each task flies one shard (the runs whose index is ``I`` modulo ``N``, on one thread) and
returns its bytes, those ``plant_sim montecarlo --shard I/N`` writes to ``shard.bin``; the
driver merges them as ``--merge`` does. The result is therefore the unsharded study's,
bit for bit, whatever the number of workers or shards, and a task Ray reruns after its
worker died computes the same bytes again (tasks have no side effects).
"""

from __future__ import annotations

from typing import Any, Dict, List, Optional

from . import _native


def _shard(text: Optional[str], runs: int, seed: int, laws: List[str], index: int, count: int) -> bytes:
    return _native.montecarlo_shard(text, runs, seed, laws, index, count)


def run(
    text: Optional[str],
    runs: int,
    seed: int,
    laws: List[str],
    address: Optional[str] = None,
    shards: Optional[int] = None,
    max_retries: int = 3,
    num_cpus: Optional[int] = None,
) -> Dict[str, Any]:
    """Runs the study over Ray: connects to ``address`` (``"auto"``: the local cluster
    ``ray start`` began; ``None``: start one in this process with ``num_cpus``), maps the
    shards and merges them."""
    import ray

    if shards is not None and shards < 1:
        raise ValueError("shards: must be at least 1")
    started = False
    if not ray.is_initialized():
        if address is None:
            ray.init(num_cpus=num_cpus, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
        started = True
    try:
        if shards is None:
            shards = max(1, 2 * int(ray.cluster_resources().get("CPU", 1)))
        task = ray.remote(num_cpus=1, max_retries=max_retries)(_shard).options(name="eqtrack_shard")
        refs = [task.remote(text, runs, seed, laws, i, shards) for i in range(shards)]
        parts = ray.get(refs)
        return _native.montecarlo_merge(text, runs, seed, laws, parts)
    finally:
        if started:
            ray.shutdown()
