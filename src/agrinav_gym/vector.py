"""Many envs in few processes: ``agrinav_gym.make_vec(env_id, num_envs, workers=W)``.

Gymnasium's ``AsyncVectorEnv`` gives every env its own process, and its main process takes each
env's reply and merges each env's info dict into arrays, key by key, every step. With a step of
≈ 0.7 ms that main-process work and the pipes' wake-ups are what a wide machine waits on
(docs/design.md "What an env step costs"). Here each of ``W`` worker processes steps its share of
the envs as a Gymnasium ``SyncVectorEnv`` (which merges their infos in the worker) and replies
once per step; the main process joins ``W`` batches. The batches are exactly what one
``SyncVectorEnv`` of all the envs would return — same seeds, same autoreset, same info arrays
and masks — whatever ``W`` is (tested).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import pickle
import traceback
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.envs.registration import EnvSpec
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from scenario_gen.errors import InputError

from .registration import check_env_id

__all__ = ["BatchedVectorEnv", "make_vec"]


def make_vec(
    env_id: str,
    num_envs: int,
    workers: int | None = None,
    *,
    context: str = "spawn",
    autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
    wrappers: Sequence[Callable[[gym.Env], gym.Wrapper]] = (),
    pin_workers: bool = False,
    **kwargs: Any,
) -> BatchedVectorEnv:
    """``num_envs`` copies of ``gym.make(env_id, **kwargs)`` spread over ``workers`` processes
    (default: one per core, at most one per env), contiguous shares as equal as they go;
    ``wrappers`` (picklable: classes or module-level functions) wrap each env, in order.
    ``pin_workers`` keeps worker i on the i-th core this process may run on (Linux): the
    workers stop migrating between cores (measured in docs/design.md, "What an env step
    costs"); leave it off where other work shares the cores."""
    env_id = check_env_id(env_id)
    if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
        raise InputError("num_envs", num_envs, "allowed: an integer ≥ 1")
    if workers is None:
        workers = min(num_envs, os.cpu_count() or 1)
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= num_envs:
        raise InputError("workers", workers, f"allowed: an integer from 1 to num_envs ({num_envs})")
    if context not in mp.get_all_start_methods():
        raise InputError("context", context, f"allowed: {', '.join(mp.get_all_start_methods())}")
    try:
        mode = AutoresetMode(autoreset_mode)
    except ValueError:
        allowed = ", ".join(m.value for m in AutoresetMode)
        raise InputError("autoreset_mode", autoreset_mode, f"allowed: {allowed}") from None
    if not isinstance(pin_workers, bool):
        raise InputError("pin_workers", pin_workers, "allowed: true or false")
    if pin_workers and not hasattr(os, "sched_setaffinity"):
        raise InputError("pin_workers", pin_workers, "allowed on Linux only (sched_setaffinity)")
    wrappers = tuple(wrappers)
    for i, w in enumerate(wrappers):
        if not callable(w):
            raise InputError(f"wrappers[{i}]", w, "allowed: a callable taking and returning an env")
        try:
            pickle.dumps(w)
        except Exception:  # lambdas, local functions: a worker process cannot receive them
            raise InputError(
                f"wrappers[{i}]",
                w,
                "allowed: a picklable callable (a class or a module-level function): each "
                "worker process receives it pickled",
            ) from None
    return BatchedVectorEnv(env_id, num_envs, workers, kwargs, context, mode, wrappers, pin_workers)


class BatchedVectorEnv(VectorEnv):
    """A Gymnasium ``VectorEnv`` whose envs live ``num_envs / workers`` to a process."""

    def __init__(
        self,
        env_id: str,
        num_envs: int,
        workers: int,
        kwargs: dict[str, Any],
        context: str,
        autoreset_mode: AutoresetMode,
        wrappers: tuple[Callable[[gym.Env], gym.Wrapper], ...] = (),
        pin_workers: bool = False,
    ) -> None:
        sizes = [len(a) for a in np.array_split(np.arange(num_envs), workers)]
        self.num_envs = num_envs
        self.sizes = tuple(sizes)
        self.autoreset_mode = autoreset_mode
        self._bounds = np.concatenate([[0], np.cumsum(sizes)])
        self.closed = False
        self._layouts: dict[int, Layout] = {}
        self._uniform = False
        ctx: Any = mp.get_context(context)
        cores = sorted(os.sched_getaffinity(0)) if pin_workers else []
        self._remotes: list[Connection] = []
        self._processes: list[Any] = []
        for i, n in enumerate(sizes):
            parent, child = ctx.Pipe()
            proc = ctx.Process(
                target=_worker,
                name=f"AgriNavBatchedWorker-{i}",
                # the spec itself (pickled): a spawned worker needs no registry, so ids made
                # with register_scenario in this process work there too
                args=(child, parent, gym.spec(env_id), kwargs, n, autoreset_mode.value, wrappers),
                daemon=True,
            )
            proc.start()
            if cores:
                os.sched_setaffinity(proc.pid, {cores[i % len(cores)]})
            child.close()
            self._remotes.append(parent)
            self._processes.append(proc)
        try:
            first = self._gather()[0]
        except Exception:  # a worker's error, or its env's refusal of the kwargs
            self.close()  # no process outlives a failed start
            raise
        self.single_observation_space, self.single_action_space = first["spaces"]
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.metadata = {**first["metadata"], "autoreset_mode": autoreset_mode}
        self.render_mode = first["render_mode"]
        self.spec = first["spec"]

    @property
    def processes(self) -> list[Any]:
        return list(self._processes)

    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[Any, dict[str, Any]]:
        """As ``SyncVectorEnv.reset``: an int seeds env ``i`` with ``seed + i``; a
        ``reset_mask`` in ``options`` is split between the workers."""
        self._check_open("reset")
        allowed = f"allowed: None, an integer >= 0 or a list of {self.num_envs} of them"
        if seed is None:
            seeds: list[int | None] = [None] * self.num_envs
        elif isinstance(seed, bool | float | str | bytes):
            raise InputError("seed", seed, allowed)
        elif isinstance(seed, int | np.integer):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            try:
                seeds = list(seed)
            except TypeError:
                raise InputError("seed", seed, allowed) from None
            if len(seeds) != self.num_envs:
                raise InputError("seed", seed, allowed)
        for i, remote in enumerate(self._remotes):
            a, b = self._bounds[i], self._bounds[i + 1]
            opts = options
            if options is not None and "reset_mask" in options:
                opts = {**options, "reset_mask": np.asarray(options["reset_mask"])[a:b]}
            remote.send(("reset", (seeds[a:b], opts)))
        parts = self._gather()
        return _join([p[0] for p in parts]), self._infos([p[1] for p in parts])

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        self._check_open("step")
        if isinstance(self.action_space, gym.spaces.Box):
            # every env's row or none: a batch sliced short would step some envs only
            try:
                shape = np.shape(actions)
            except ValueError:  # ragged nested lists
                shape = None
            if shape != self.action_space.shape:
                raise InputError(
                    "actions",
                    actions if shape is None else f"shape {shape}",
                    f"allowed: shape {self.action_space.shape} (one action per env)",
                )
        for i, remote in enumerate(self._remotes):
            remote.send(("step", _slice(actions, self._bounds[i], self._bounds[i + 1])))
        parts = self._gather()
        return (
            _join([p[0] for p in parts]),
            np.concatenate([p[1] for p in parts]),
            np.concatenate([p[2] for p in parts]),
            np.concatenate([p[3] for p in parts]),
            self._infos([p[4] for p in parts]),
        )

    def _infos(self, packets: list[Packed]) -> dict[str, Any]:
        """The workers' packed infos joined: one concatenation per buffer when every worker's
        info has the same layout (the usual step), else key by key."""
        changed = False
        for i, packet in enumerate(packets):
            if packet.layout is not None and packet.layout is not self._layouts.get(i):
                self._layouts[i], changed = packet.layout, True
        layouts = [self._layouts[i] for i in range(len(packets))]
        if changed:  # compared in full only when a worker's layout changes
            self._uniform = all(lay.leaves == layouts[0].leaves for lay in layouts[1:])
        if self._uniform:
            buffers = [
                np.concatenate(b, axis=1) for b in zip(*(p.buffers for p in packets), strict=True)
            ]
            objects = [np.concatenate(o) for o in zip(*(p.objects for p in packets), strict=True)]
            return layouts[0].build(buffers, objects)
        infos = [lay.build(p.buffers, p.objects) for lay, p in zip(layouts, packets, strict=True)]
        return _join_info(infos, self.sizes)

    def render(self) -> tuple[Any, ...] | None:
        return self._each("render", ())

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        return self._each("call", (name, args, kwargs))

    def get_attr(self, name: str) -> tuple[Any, ...]:
        return self._each("get_attr", name)

    def set_attr(self, name: str, values: list[Any] | tuple[Any, ...] | Any) -> None:
        """As ``SyncVectorEnv.set_attr``: one value for every env, or a value per env."""
        if isinstance(values, list | tuple):
            if len(values) != self.num_envs:
                raise InputError("values", values, f"allowed: one value or {self.num_envs}")
            for i, remote in enumerate(self._remotes):
                a, b = self._bounds[i], self._bounds[i + 1]
                remote.send(("set_attr", (name, list(values[a:b]))))
        else:
            for remote in self._remotes:
                remote.send(("set_attr", (name, values)))
        self._gather()

    def close_extras(self, **kwargs: Any) -> None:
        for remote in self._remotes:
            try:
                remote.send(("close", None))
            except (BrokenPipeError, OSError):
                pass
        for proc, remote in zip(self._processes, self._remotes, strict=True):
            proc.join(timeout=10)
            if proc.is_alive():
                proc.terminate()
                proc.join()
            remote.close()

    def _check_open(self, what: str) -> None:
        if self.closed:
            raise InputError(what, "called after close()", "allowed: make a new vector env")

    def _each(self, cmd: str, data: Any) -> tuple[Any, ...]:
        self._check_open(cmd)
        for remote in self._remotes:
            remote.send((cmd, data))
        return tuple(x for part in self._gather() for x in part)

    def _gather(self) -> list[Any]:
        """Every worker's reply, in worker order; any failure raised once all have replied (so
        the pipes stay in step)."""
        out, errors = [], []
        refused: list[InputError] = []
        any_bad_input = False
        for i, remote in enumerate(self._remotes):
            try:
                ok, value = remote.recv()
            except EOFError:
                ok, value = False, "the process exited"
            if not ok:
                if isinstance(value, InputError):
                    refused.append(value)
                    value = (True, str(value))
                bad_input = isinstance(value, tuple) and value[0]
                errors.append(f"worker {i}: {value[1] if isinstance(value, tuple) else value}")
                any_bad_input = any_bad_input or bad_input
            out.append(value)
        if errors:
            if len(refused) == len(errors):  # bad input, as one env would refuse it: one line
                raise refused[0]
            kind = WorkerInputError if any_bad_input else WorkerError
            raise kind("\n".join(errors))
        return out

    def __del__(self) -> None:
        if not getattr(self, "closed", True):
            self.close()


def _slice(x: Any, a: int, b: int) -> Any:
    if isinstance(x, dict):
        return {k: _slice(v, a, b) for k, v in x.items()}
    if isinstance(x, tuple):
        return tuple(_slice(v, a, b) for v in x)
    return np.asarray(x)[a:b]


def _join(parts: list[Any]) -> Any:
    """Batched observations of the workers joined along the batch axis."""
    first = parts[0]
    if isinstance(first, dict):
        return {k: _join([p[k] for p in parts]) for k in first}
    if isinstance(first, tuple):
        return tuple(_join([p[i] for p in parts]) for i in range(len(first)))
    return np.concatenate(parts)


def _join_info(parts: list[dict[str, Any]], sizes: Sequence[int]) -> dict[str, Any]:
    """The workers' vector infos as one ``SyncVectorEnv`` of all the envs would have built them:
    keys in first-seen order; a key some workers lack is blank there (zero, None for objects,
    False for its ``_key`` mask); the dtype is that of the first env holding the key, as
    Gymnasium's merge makes it."""
    if len(parts) == 1:
        return parts[0]
    keys = dict.fromkeys(parts[0])
    for p in parts[1:]:
        if p.keys() != keys.keys():
            keys.update(dict.fromkeys(p))
    out: dict[str, Any] = {}
    for key in keys:
        values = [p.get(key) for p in parts]
        template = next(v for v in values if v is not None)
        if isinstance(template, dict):
            out[key] = _join_info([{} if v is None else v for v in values], sizes)
            continue
        if any(v is None for v in values):
            values = [
                _blank(template, n) if v is None else v for v, n in zip(values, sizes, strict=True)
            ]
        out[key] = np.concatenate(values, dtype=template.dtype, casting="unsafe")  # type: ignore[call-overload]
    return out


Path = tuple[str, ...]


class Layout:
    """Where each leaf of a vector info lives in a ``Packed``: its key path, and the buffer
    and row holding it (buffer -1: the object list; -2: an empty dict). A worker sends its
    layout only when it changes."""

    def __init__(self, leaves: tuple[tuple[Path, int, int], ...]) -> None:
        self.leaves = leaves

    def build(self, buffers: list[np.ndarray], objects: list[Any]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for path, b, row in self.leaves:
            d = out
            for key in path[:-1]:
                d = d.setdefault(key, {})
            d[path[-1]] = {} if b == -2 else objects[row] if b == -1 else buffers[b][row]
        return out


class Packed:
    """A vector info as a few stacked arrays (one per dtype and shape): pickling and joining
    cost per buffer, not per key."""

    __slots__ = ("buffers", "layout", "objects")

    def __init__(
        self, layout: Layout | None, buffers: list[np.ndarray], objects: list[Any]
    ) -> None:
        self.layout, self.buffers, self.objects = layout, buffers, objects


def pack(info: dict[str, Any], last: Layout | None) -> tuple[Packed, Layout]:
    """A vector info (dicts and arrays, as ``SyncVectorEnv`` builds it) packed; the layout is
    left out of the packet when it equals ``last``."""
    leaves: list[tuple[Path, int, int]] = []
    group_of: dict[tuple[str, tuple[int, ...]], int] = {}  # (dtype, shape) -> buffer index
    groups: list[list[np.ndarray]] = []
    objects: list[Any] = []

    def walk(d: dict[str, Any], path: Path) -> None:
        for key, v in d.items():
            here = (*path, key)
            if isinstance(v, dict):
                if v:
                    walk(v, here)
                else:
                    leaves.append((here, -2, 0))
            elif isinstance(v, np.ndarray) and v.dtype != object:
                b = group_of.setdefault((v.dtype.str, v.shape[1:]), len(group_of))
                if b == len(groups):
                    groups.append([])
                leaves.append((here, b, len(groups[b])))
                groups[b].append(v)
            else:
                leaves.append((here, -1, len(objects)))
                objects.append(v)

    walk(info, ())
    layout = Layout(tuple(leaves))
    same = last is not None and last.leaves == layout.leaves
    if same:
        assert last is not None
        layout = last
    buffers = [np.stack(m) for m in groups]
    return Packed(None if same else layout, buffers, objects), layout


def _blank(template: np.ndarray, n: int) -> np.ndarray:
    if template.dtype == object:
        return np.full(n, None, dtype=object)
    return np.zeros((n, *template.shape[1:]), template.dtype)


class WorkerError(RuntimeError):
    """A worker's env raised: its exception and traceback, named by worker, in the message."""


class WorkerInputError(WorkerError, ValueError):
    """A worker's env refused its input (a ValueError there, e.g. an ``InputError`` for a NaN
    action or a bad config): a ValueError here too, as the same call raises in one process."""


def _failure(exc: Exception) -> InputError | tuple[bool, str]:
    """What a worker sends for an exception: an ``InputError`` itself (raised again in the main
    process, one line as in one process), else whether it was bad input, and its text."""
    if isinstance(exc, InputError):
        try:
            pickle.dumps(exc)
            return exc
        except Exception:  # a value that does not pickle: its text instead
            return InputError(exc.field, str(exc.value), exc.allowed)
    return isinstance(exc, ValueError), f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"


def _worker(
    remote: Connection,
    parent: Connection,
    spec: EnvSpec,
    kwargs: dict[str, Any],
    n: int,
    autoreset_mode: str,
    wrappers: tuple[Callable[[gym.Env], gym.Wrapper], ...] = (),
) -> None:
    parent.close()
    try:
        venv: Any = gym.make_vec(
            spec,
            num_envs=n,
            vectorization_mode="sync",
            vector_kwargs={"autoreset_mode": AutoresetMode(autoreset_mode)},
            wrappers=list(wrappers) or None,
            **kwargs,
        )
        first = venv.envs[0]
        remote.send(
            (
                True,
                {
                    "spaces": (venv.single_observation_space, venv.single_action_space),
                    "metadata": {k: v for k, v in first.metadata.items() if k != "autoreset_mode"},
                    "render_mode": first.render_mode,
                    "spec": first.spec,
                },
            )
        )
    except Exception as exc:  # the main process raises it, naming this worker
        remote.send((False, _failure(exc)))
        remote.close()
        return
    layout: Layout | None = None
    while True:
        try:
            cmd, data = remote.recv()
        except (EOFError, KeyboardInterrupt):
            break
        try:
            if cmd == "step":
                obs, reward, term, trunc, info = venv.step(data)
                packed, layout = pack(info, layout)
                out: Any = (obs, reward, term, trunc, packed)
            elif cmd == "reset":
                obs, info = venv.reset(seed=data[0], options=data[1])
                packed, layout = pack(info, layout)
                out = (obs, packed)
            elif cmd == "render":
                out = venv.render() or ()
            elif cmd == "call":
                name, args, kw = data
                out = venv.call(name, *args, **kw)
            elif cmd == "get_attr":
                out = venv.get_attr(data)
            elif cmd == "set_attr":
                venv.set_attr(*data)
                out = ()
            elif cmd == "close":
                venv.close()
                remote.send((True, None))
                break
            else:
                raise ValueError(f"unknown command {cmd!r}")
            remote.send((True, out))
        except Exception as exc:
            remote.send((False, _failure(exc)))
    remote.close()
