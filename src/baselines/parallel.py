"""Independent tasks spread over local worker processes or a Ray cluster (the ``ray`` extra).

``agrinav dataset`` (shards), ``agrinav bench`` (episodes) and ``agrinav tune`` (each trial's
episodes) hand their tasks to ``Tasks``: run in this process (``workers=1``), in a pool of
spawned worker processes (pybullet and Embree state must not be forked), or as Ray tasks on the
cluster at ``ray`` (``local``: a one-machine cluster for this run; ``auto``; ``host:port`` or
``ray://host:port``; the nodes need this package installed). Results come back as tasks finish,
in any order: every task is a pure function of its arguments, so what a command writes does
not depend on how its tasks were spread, and a task's result can be kept the moment it comes
back (the commands' resumption).
"""

from __future__ import annotations

import contextlib
import importlib.util
import logging
import multiprocessing as mp
import os
import re
import socket
from collections.abc import Callable, Iterable, Iterator
from types import TracebackType
from typing import Any, TypeVar

from scenario_gen.errors import InputError

J = TypeVar("J")
R = TypeVar("R")

ADDRESS = re.compile(r"^(local|auto|(ray://)?[A-Za-z0-9.\-]+:[0-9]{1,5})$")


#: seconds a cluster's head has to accept a TCP connection before --ray is refused
CONNECT_TIMEOUT_S = 5.0


def check_address(address: str) -> None:
    """Before anything is written: Ray is installed and ``address`` has a usable form."""
    if not ADDRESS.match(address):
        raise InputError("--ray", address, "allowed: local, auto, host:port or ray://host:port")
    if importlib.util.find_spec("ray") is None:
        raise InputError(
            "--ray", address, "needs Ray: pip install 'agrinav-gym[ray]' (or omit --ray)"
        )
    if address not in ("local", "auto"):
        # ray.init retries an unreachable head for minutes, printing as it goes
        host, _, port = address.removeprefix("ray://").rpartition(":")
        try:
            socket.create_connection((host, int(port)), timeout=CONNECT_TIMEOUT_S).close()
        except OSError as exc:
            raise InputError(
                "--ray",
                address,
                f"cannot be reached ({exc.strerror or exc}); allowed: a running cluster's "
                "head (host:port, or ray://host:port for Ray Client), local or auto",
            ) from None


#: worker processes a command may start per core: beyond this they only queue for the cores
OVERSUBSCRIBE = 4


def check_spread(workers: int, ray: str | None) -> None:
    """The ``--workers`` and ``--ray`` of a command, checked before anything runs."""
    if workers < 1:
        raise InputError("--workers", workers, "allowed: an integer >= 1")
    cores = os.cpu_count() or 1
    if workers > OVERSUBSCRIBE * cores:
        raise InputError(
            "--workers",
            workers,
            f"allowed: at most {OVERSUBSCRIBE * cores} ({OVERSUBSCRIBE} per core of this "
            f"machine's {cores}): more only share the cores, each holding its own simulator "
            "(≈ 0.2 GB); --ray spreads past one machine",
        )
    if ray is not None and workers != 1:
        raise InputError(
            "--workers", workers, "allowed: 1 with --ray (the cluster's CPUs set the parallelism)"
        )
    if ray is not None:
        check_address(ray)


def connect(address: str) -> tuple[Any, bool]:
    """The ``ray`` module connected to ``address``, and whether this call started Ray (and
    so must shut it down); a process already connected keeps its cluster."""
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


class Tasks:
    """Where a command's tasks run; a context manager (the pool or the cluster connection
    lives for the block, so a command that maps several batches starts its workers once).
    ``workers`` > 1 starts at most that many processes, and none before the first batch."""

    def __init__(self, workers: int = 1, ray: str | None = None) -> None:
        check_spread(workers, ray)
        self.workers, self.address = workers, ray
        self._pool: Any = None
        self._ray: Any = None
        self._started = False

    def __enter__(self) -> Tasks:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close(kill=kind is not None)

    def close(self, kill: bool = False) -> None:
        """Stop the workers (at once when ``kill``: a failed or interrupted command)."""
        if self._pool is not None:
            if kill:
                self._pool.terminate()
            else:
                self._pool.close()
            self._pool.join()
            self._pool = None
        if self._ray is not None and self._started:
            self._ray.shutdown()
        self._ray = None

    @property
    def parallel(self) -> bool:
        return self.address is not None or self.workers > 1

    def map(self, fn: Callable[[J], R], jobs: Iterable[J]) -> Iterator[R]:
        """``fn(job)`` of every job, as each finishes (any order). ``fn`` must be a module-level
        function and the jobs picklable where the tasks leave this process."""
        todo = list(jobs)
        if not todo:
            return
        if self.address is not None:
            yield from self._map_ray(fn, todo)
        elif self.workers == 1:
            yield from map(fn, todo)
        else:
            if self._pool is None:
                ctx = mp.get_context("spawn")  # pybullet and Embree state must not be forked
                self._pool = ctx.Pool(min(self.workers, len(todo)))
            yield from self._pool.imap_unordered(fn, todo)

    def _map_ray(self, fn: Callable[[J], R], todo: list[J]) -> Iterator[R]:
        if self._ray is None:
            assert self.address is not None
            self._ray, self._started = connect(self.address)
        ray = self._ray
        task = ray.remote(num_cpus=1, max_retries=2)(fn)
        pending = [task.remote(j) for j in todo]
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                yield ray.get(done[0])
        finally:
            for ref in pending:  # an interrupted batch leaves nothing running
                with contextlib.suppress(Exception):
                    ray.cancel(ref, force=True)
