"""Running a perception dataset: shards in parallel workers (``baselines.parallel``), resumable,
with a progress bar."""

from __future__ import annotations

import json
import os
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tqdm import tqdm

from scenario_gen.atomic import (
    check_creatable,
    lock_output,
    make_parents,
    mark_output,
    remove_empty,
)
from scenario_gen.errors import InputError, Notice
from scenario_gen.schema import parse_json, to_mapping

from ..parallel import Tasks, check_spread
from .perception import SPLIT_SEEDS, check, save_shard, shard_frames, split_of, write_shard
from .spec import SCHEMA_VERSION, PerceptionSpec

MANIFEST = "dataset.json"
#: what the dataset card (``card.write_card``) writes beside the shards
CARD_FILES = ("README.md", "mosaic.png")


def shard_name(i: int) -> str:
    return f"shard-{i:06d}.tar"


def _manifest(spec: PerceptionSpec, seed: int, shards: int) -> dict[str, Any]:
    return {
        "format": "agrinav-perception",
        "schema": SCHEMA_VERSION,
        "digest": spec.digest(),
        "seed": seed,
        "shards": shards,
        "frames_per_shard": spec.frames_per_shard,
        "splits": {
            name: {
                "scenario_seeds": list(seeds),
                "shards": [shard_name(i) for i in range(shards) if split_of(i) == name],
            }
            for name, seeds in SPLIT_SEEDS.items()
        },
        "spec": to_mapping(spec),
    }


def prepare(spec: PerceptionSpec, out: Path, seed: int, frames: int) -> tuple[int, list[int]]:
    """Check everything, claim ``out`` (new, or this spec's unfinished dataset) and return the
    shard count and the shards still to write."""
    if frames < 1:
        raise InputError("--frames", frames, "allowed: an integer >= 1")
    shards = -(-frames // spec.frames_per_shard)
    if out.is_symlink():  # as every output folder: the link's target is what gets written
        raise InputError(
            "--out",
            str(out),
            f"is a symbolic link (to {os.readlink(out)}); allowed: a real folder path, e.g. "
            "the folder it points to",
        )
    if out.exists() and not out.is_dir():
        raise InputError("--out", str(out), "exists and is not a directory")
    man = out / MANIFEST
    if out.is_dir() and any(out.iterdir()):
        if not man.is_file():
            raise InputError(
                "--out",
                str(out),
                "holds files that are not a dataset; allowed: a new or empty folder",
            )
        try:
            have = parse_json(man.read_bytes(), "--out", f"{out}/{MANIFEST}")
        except OSError as exc:
            raise InputError("--out", str(out), f"has an unreadable {MANIFEST} ({exc})") from None
        if not isinstance(have, dict):
            raise InputError("--out", str(out), f"has a {MANIFEST} that is not a JSON object")
        mine = _manifest(spec, seed, shards)
        for k in ("format", "schema", "digest", "seed", "shards"):
            if have.get(k) != mine[k]:
                raise InputError(
                    "--out",
                    str(out),
                    f"holds another dataset ({k} {have.get(k)!r}, this run {mine[k]!r}); "
                    "allowed: the same spec, seed and --frames (in whole shards of "
                    "spec.frames_per_shard), or a new folder",
                )
    check(spec)
    if shards * spec.frames_per_shard != frames:
        warnings.warn(
            Notice(
                f"--frames {frames} is written as {shards} whole shard(s) of "
                f"spec.frames_per_shard {spec.frames_per_shard}: "
                f"{shards * spec.frames_per_shard} frames"
            ),
            stacklevel=2,
        )
    out.mkdir(parents=True, exist_ok=True)
    if not man.is_file():
        tmp = out / f".{MANIFEST}.tmp"
        tmp.write_text(json.dumps(_manifest(spec, seed, shards), indent=1, default=list))
        tmp.replace(man)
        mark_output(out, "dataset")
    for stale in out.glob(".*.tmp*"):  # a killed run's partial shard or card file
        stale.unlink(missing_ok=True)
    todo = [i for i in range(shards) if not (out / shard_name(i)).is_file()]
    return shards, todo


def _work(args: tuple[PerceptionSpec, int, int, str, bool]) -> tuple[int, int, float]:
    spec, seed, i, out, overlap = args
    t0 = time.perf_counter()
    n = write_shard(shard_frames(spec, seed, i), Path(out) / shard_name(i), overlap)
    return i, n, time.perf_counter() - t0


def generate(
    spec: PerceptionSpec,
    out: str | Path,
    seed: int,
    frames: int,
    workers: int = 1,
    card: Callable[[Path], None] | None = None,
    ray: str | None = None,
) -> int:
    """Write the dataset's missing shards (``workers`` processes, or Ray tasks on the cluster
    at ``ray``: ``local``, ``auto`` or an address); returns the frames written by this call.
    A finished dataset is a no-op."""
    check_spread(workers, ray)
    out = Path(out)
    check_creatable(out.absolute(), "--out")
    made = make_parents(out.absolute())
    try:
        # A second run on the same --out is refused while this one holds it (two used to race
        # and both fail, advising to "free the space").
        with lock_output(out.absolute(), "--out"):
            return _generate(spec, out, seed, frames, workers, card, ray)
    except BaseException:
        remove_empty(made)  # the parent folders this run made, when nothing was kept in them
        raise


def _generate(
    spec: PerceptionSpec,
    out: Path,
    seed: int,
    frames: int,
    workers: int,
    card: Callable[[Path], None] | None,
    ray: str | None,
) -> int:
    existed = out.exists()
    fresh = not existed or (out.is_dir() and not any(out.iterdir()))
    written = shards = 0
    try:
        shards, todo = prepare(spec, out, seed, frames)
        procs = max(1, min(workers, len(todo)))
        # a core the workers leave idle encodes each frame while the next one renders
        overlap = procs < (os.cpu_count() or 1)
        jobs = [(spec, seed, i, str(out), overlap) for i in todo]
        with (
            tqdm(total=len(todo) * spec.frames_per_shard, unit="frame", desc="dataset") as bar,
            Tasks(procs if ray is None else 1, ray) as tasks,
        ):
            if ray is not None:  # the cluster returns each shard's bytes: written here
                from .cluster import shard_task

                for i, n, data in tasks.map(shard_task, [(spec, seed, i) for i in todo]):
                    save_shard(data, out / shard_name(i))
                    written += n
                    bar.update(n)
            else:  # local workers write their shards themselves
                for _, n, _ in tasks.map(_work, jobs):
                    written += n
                    bar.update(n)
        if card is not None and (todo or not all((out / f).is_file() for f in CARD_FILES)):
            card(out)  # a finished dataset's rerun writes nothing
    except BaseException as exc:  # a full disk, a lost cluster, Ctrl-C: leave no partial file
        done = _clean_up(out, fresh, existed)
        if isinstance(exc, (KeyboardInterrupt, SystemExit)):  # Ctrl-C, SIGTERM: say what stays
            print(f"dataset: stopped; {_kept(out, done, shards)}", file=sys.stderr)
        if not isinstance(exc, OSError):
            raise
        raise OSError(
            exc.errno,
            f"writing the dataset in {out} failed ({exc.strerror or exc}); "
            + ("free the space; " if done else "")
            + _kept(out, done, shards),
        ) from None
    return written


def _kept(out: Path, done: int, shards: int) -> str:
    if not done:
        return "nothing was kept"
    return (
        f"{done} of {shards} shards are complete and kept in {out}: rerun the same command to "
        "resume"
    )


def _clean_up(out: Path, fresh: bool, existed: bool) -> int:
    """After a failed run: remove the partial shards and card files (the pool's workers were
    stopped mid-write) and, when no shard is whole and the folder was new or empty, what the
    run wrote in it (the manifest) and the folder if the run made it. Returns the number of
    whole shards kept."""
    if not out.is_dir():
        return 0
    for part in out.glob(".*.tmp-*"):  # shards and card files (``atomic_write``)
        part.unlink(missing_ok=True)
    done = len(list(out.glob("shard-*.tar")))
    if done == 0 and fresh:
        for f in out.iterdir():
            f.unlink(missing_ok=True)
        if not existed:
            out.rmdir()
    return done
