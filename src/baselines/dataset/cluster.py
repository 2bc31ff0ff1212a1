"""Shards as Ray tasks, for datasets that outgrow one machine (the ``ray`` extra).

Each task makes one whole shard in memory (``perception.shard_bytes``: the same function of
(spec, seed, index) as a local worker, so the bytes are the same) and returns it; the driver
writes it with the same write-then-rename, so the output folder need not be shared with the
cluster's nodes, and resumption and the no-op rerun work as for local runs. The nodes need
this package installed (``pip install agrinav-gym``) in the Python the cluster runs. Where the
tasks run is ``baselines.parallel``'s, shared with ``agrinav bench`` and ``agrinav tune``.
"""

from __future__ import annotations

from ..parallel import ADDRESS, check_address
from .perception import shard_bytes
from .spec import PerceptionSpec

__all__ = ["ADDRESS", "check_address", "shard_task"]


def shard_task(job: tuple[PerceptionSpec, int, int]) -> tuple[int, int, bytes]:
    """(index, frames, tar bytes) of shard ``index`` of (spec, seed, index)."""
    return shard_bytes(*job)
