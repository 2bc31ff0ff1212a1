"""Shards as Ray tasks, for datasets that outgrow one machine (the ``ray`` extra).

Each task makes one whole shard in memory (``perception.shard_bytes``: the same function of
(spec, seed, index) as a local worker, so the bytes are the same) and returns it; the driver
writes it with the same write-then-rename, so the output folder need not be shared with the
cluster's nodes, and resumption and the no-op rerun work as for local runs. The nodes need
this package installed (``pip install agrinav-gym``) in the Python the cluster runs.
"""

from __future__ import annotations

import importlib.util
import logging
import re
from collections.abc import Iterator
from typing import Any

from scenario_gen.errors import InputError

from .perception import shard_bytes
from .spec import PerceptionSpec

ADDRESS = re.compile(r"^(local|auto|(ray://)?[A-Za-z0-9.\-]+:[0-9]{1,5})$")


def check_address(address: str) -> None:
    """Before anything is written: Ray is installed and ``address`` has a usable form."""
    if not ADDRESS.match(address):
        raise InputError("--ray", address, "allowed: local, auto, host:port or ray://host:port")
    if importlib.util.find_spec("ray") is None:
        raise InputError(
            "--ray", address, "needs Ray: pip install 'agrinav-gym[ray]' (or omit --ray)"
        )


def _connect(address: str) -> Any:
    import ray

    if ray.is_initialized():
        return ray, False
    try:
        if address == "local":  # a one-machine cluster for this run (to try it out)
            ray.init(include_dashboard=False, log_to_driver=False, logging_level=logging.ERROR)
        else:
            ray.init(address=address, log_to_driver=False, logging_level=logging.ERROR)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        raise InputError(
            "--ray",
            address,
            f"cannot connect ({exc}); allowed: local, auto, or a cluster's host:port / "
            "ray://host:port",
        ) from None
    return ray, True


def ray_shards(
    spec: PerceptionSpec, seed: int, todo: list[int], address: str
) -> Iterator[tuple[int, int, bytes]]:
    """(index, frames, tar bytes) of the shards ``todo``, as the cluster finishes them."""
    ray, started = _connect(address)
    try:
        task = ray.remote(num_cpus=1, max_retries=2)(shard_bytes)
        pending = [task.remote(spec, seed, i) for i in todo]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            yield ray.get(done[0])
    finally:
        if started:
            ray.shutdown()
