"""What a long command has finished so far, kept beside its output so a killed run resumes.

``agrinav bench`` and ``agrinav tune`` write their output folder whole at the end
(``scenario_gen.atomic.output_dir``); every finished task (an episode) is also written at once
to ``.<out>.partial/`` next to it, each file whole or absent (write, then rename). The same
command run again on the same ``--out`` reads those back and runs only the tasks that are
missing; the folder goes once the output is in place. It belongs to one command: a run whose
arguments (or package version, or the bytes of the files it read: ``input_digest``, or the
project's code: ``code_digest``) differ is refused while it exists, unless ``--force``, which
discards it.
"""

from __future__ import annotations

import hashlib
import json
import re
import shutil
from functools import partial
from pathlib import Path
from typing import Any

from scenario_gen.atomic import atomic_write
from scenario_gen.errors import InputError

RUN = "run.json"
KEY = re.compile(r"^[A-Za-z0-9_.-]+$")


def input_digest(path: Path) -> dict[str, str]:
    """What a command read from ``path`` (a file, or a folder's files: a checkpoint), for its
    journal's identity: a resumed run must read the same bytes, not only the same names."""
    h = hashlib.sha256()
    real = path.resolve()
    files = [real] if real.is_file() else sorted(p for p in real.iterdir() if p.is_file())
    for f in files:
        h.update(f.name.encode() + b"\0")
        with f.open("rb") as fh:
            for chunk in iter(partial(fh.read, 1 << 20), b""):
                h.update(chunk)
    return {"path": str(real), "sha256": h.hexdigest()}


#: the packages whose code makes a task's result: an edit between a killed run and its resume
#: (an editable install keeps its version) must not mix episodes of two codes in one table
PACKAGES = ("agrinav_gym", "baselines", "policies", "scenario_gen")
_SKIPPED = ("__pycache__",)
_SKIPPED_SUFFIXES = (".pyc", ".so", ".pyd", ".o")


def code_digest() -> str:
    """sha256 over the projects' package files (names and bytes; compiled files left out,
    their sources are in): ≈ 65 ms for the ≈ 7 MB."""
    import importlib

    h = hashlib.sha256()
    for name in PACKAGES:
        root = Path(importlib.import_module(name).__file__ or "").parent
        files = sorted(
            f
            for f in root.rglob("*")
            if f.is_file()
            and not any(part in _SKIPPED for part in f.relative_to(root).parts)
            and not f.name.endswith(_SKIPPED_SUFFIXES)
        )
        for f in files:
            h.update(f"{name}/{f.relative_to(root).as_posix()}".encode() + b"\0")
            h.update(f.read_bytes())
    return h.hexdigest()


class Journal:
    """The finished tasks of the command ``identity`` (a JSON-able mapping) writing ``out``;
    the code that runs them is part of it (``code_digest``)."""

    def __init__(self, out: str | Path, identity: dict[str, Any]) -> None:
        self.out = Path(out).absolute()
        self.path = self.out.parent / f".{self.out.name}.partial"
        # as it reads back
        self.identity = json.loads(json.dumps({**identity, "code": code_digest()}))

    def open(self, force: bool = False, what: str = "--out") -> dict[str, dict[str, Any]]:
        """Start or resume (call with the output's lock held); returns the finished tasks by
        key. Another command's journal is refused, or discarded with ``force``."""
        run = self.path / RUN
        if self.path.is_dir():
            try:
                have = json.loads(run.read_text())
            except (OSError, ValueError):
                have = None  # killed before its run.json was whole: nothing to resume
            if have is not None and have != self.identity:
                if not force:
                    raise InputError(
                        what,
                        str(self.out),
                        f"has the unfinished tasks of another run in {self.path} "
                        f"({_differs(have, self.identity)}); allowed: the same command to "
                        "resume it, or --force to discard it",
                    )
                have = None
            if have is None:
                shutil.rmtree(self.path)
        if not self.path.is_dir():
            self.path.mkdir(parents=True)
            atomic_write(run, lambda tmp: tmp.write_text(json.dumps(self.identity, indent=1)))
        done = {}
        for f in sorted(self.path.glob("*.json")):
            if f.name == RUN:
                continue
            try:
                done[f.stem] = json.loads(f.read_text())
            except (OSError, ValueError):
                f.unlink(missing_ok=True)  # not whole: run it again
        return done

    def save(
        self, key: str, payload: dict[str, Any], blobs: dict[str, bytes] | None = None
    ) -> None:
        """Keep task ``key``'s result (and files named ``key.<suffix>``; written before the
        JSON, which marks the task done)."""
        if not KEY.match(key):
            raise ValueError(f"bad journal key {key!r}")
        for suffix, data in (blobs or {}).items():
            atomic_write(self.path / f"{key}.{suffix}", partial(_write_bytes, data=data))
        atomic_write(self.path / f"{key}.json", lambda tmp: tmp.write_text(json.dumps(payload)))

    def blob(self, key: str, suffix: str) -> bytes:
        return (self.path / f"{key}.{suffix}").read_bytes()

    def remove(self) -> None:
        shutil.rmtree(self.path, ignore_errors=True)


def _write_bytes(path: Path, data: bytes) -> int:
    return path.write_bytes(data)


def _differs(have: Any, want: dict[str, Any]) -> str:
    if not isinstance(have, dict):
        return "unreadable"
    keys = sorted(k for k in set(have) | set(want) if have.get(k) != want.get(k))

    def shown(d: dict[str, Any], k: str) -> str:
        return repr(d[k]) if k in d else "not set"

    def said(k: str) -> str:
        if k == "inputs" and isinstance(have.get(k), list):  # digests say nothing to a reader
            old = {str(d.get("path")): d.get("sha256") for d in have[k] if isinstance(d, dict)}
            new = {str(d["path"]): d["sha256"] for d in want.get(k) or []}
            changed = sorted(p for p in set(old) | set(new) if old.get(p) != new.get(p))
            return f"the files read changed since ({', '.join(changed)})"
        if k == "code":
            return "the project's code changed since (an edit, or another install)"
        return f"{k} {shown(have, k)} there, {shown(want, k)} now"

    # the arguments first: a run of another command differs in its code too, which then
    # goes unsaid
    named = [k for k in keys if k != "code"] or keys
    return ", ".join(said(k) for k in named[:3])
