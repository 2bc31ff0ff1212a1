"""``agrinav``: the command line.

Each subcommand lives in its own module with ``add(subparsers)``; this module only parses and
dispatches. Bad input anywhere (``InputError``) prints one line naming the field, the value and
what is allowed, and exits 2; SIGTERM unwinds like an exception, so no command leaves a
half-written output folder behind (a stopped training run keeps the checkpoints it finished,
as it says).
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import os
import signal
import sys
import warnings
from collections.abc import Sequence
from types import FrameType
from typing import Any, NoReturn

from scenario_gen.errors import InputError, Notice

from . import bench, dataset, demo, export, export_policy, scenario, studio, train, tune
from .args import StoreOnce, StoreTrueOnce

COMMANDS = (scenario, export, train, export_policy, tune, bench, demo, studio, dataset)


class Parser(argparse.ArgumentParser):
    """argparse that reports a bad flag as one line (exit 2), like every other bad input, and
    refuses a flag given twice."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.register("action", None, StoreOnce)
        self.register("action", "store", StoreOnce)
        self.register("action", "store_true", StoreTrueOnce)

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"{self.prog}: error: {message} (see {self.prog} --help)\n")
        sys.exit(2)


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="agrinav", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for module in COMMANDS:
        module.add(sub)
    return parser


def _terminate(signum: int, _frame: FrameType | None) -> None:
    raise SystemExit(128 + signum)


def _notes(command: str, show: Any) -> Any:
    """``warnings.showwarning`` that prints the packages' notices (``Notice``, e.g. agrinav_gym's
    ``FixedFieldWarning``) as one line ``agrinav COMMAND: note: ...`` and leaves every other
    warning to ``show``."""

    said: set[str] = set()

    def showwarning(message: Any, category: Any, *args: Any, **kwargs: Any) -> None:
        if issubclass(category, Notice):
            if str(message) not in said:  # once a command, however many envs it makes
                said.add(str(message))
                print(f"agrinav {command}: note: {message}", file=sys.stderr)
        else:
            show(message, category, *args, **kwargs)

    return showwarning


#: what to do about the machine's errors a user can act on
_OS_ADVICE = {
    errno.ENOSPC: "free space on that disk or write elsewhere (--out)",
    errno.EDQUOT: "your disk quota is used up: free space or write elsewhere (--out)",
    errno.EROFS: "the file system is read-only: write elsewhere (--out)",
    errno.EACCES: "no permission there: write elsewhere (--out) or fix the folder's permissions",
}


def os_error(exc: OSError, out: object = None) -> str:
    """The path (else the command's ``out``) and the machine's reason, and what to do where
    there is something to do (not Python's ``[Errno 28] ...``)."""
    if exc.errno and exc.strerror and exc.strerror != os.strerror(exc.errno):
        return str(exc.strerror)  # written by the command: it already says where and what to do
    if exc.filename:
        where = f"{exc.filename}: "
    else:
        where = f"writing {out}: " if out else ""
    text = f"{where}{exc.strerror or exc}"
    advice = _OS_ADVICE.get(exc.errno or 0)
    return f"{text}; {advice}" if advice else text


def main(argv: Sequence[str] | None = None) -> int:
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help, or a bad flag already reported in one line
        return int(exc.code or 0)
    except KeyboardInterrupt:
        print("agrinav: interrupted", file=sys.stderr)
        return 130
    out = getattr(args, "out", None)
    if isinstance(out, str) and not out.strip():  # Path("") would be the current folder
        print(
            f"agrinav {args.command}: error: --out: got {out!r}; allowed: a folder path",
            file=sys.stderr,
        )
        return 2
    args.argv = ["agrinav", *(argv if argv is not None else sys.argv[1:])]  # for "reproduce"
    previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        with warnings.catch_warnings():  # restores showwarning
            warnings.showwarning = _notes(args.command, warnings.showwarning)
            return int(args.func(args))
    except InputError as exc:
        print(f"agrinav {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError as exc:
        if exc.filename is not None:  # a pipe the command wrote to as a file
            print(f"agrinav {args.command}: error: {os_error(exc)}", file=sys.stderr)
            return 1
        # the reader of stdout went away (``| head``): what was written stays; exit as a
        # command killed by SIGPIPE does, without a word (nothing more can be printed there)
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 128 + signal.SIGPIPE
    except OSError as exc:  # full disk, permissions: the machine's problem, said in one line
        text = os_error(exc, getattr(args, "out", None))
        print(f"agrinav {args.command}: error: {text}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("agrinav: interrupted", file=sys.stderr)
        return 130
    finally:
        signal.signal(signal.SIGTERM, previous)


__all__ = ["InputError", "build_parser", "main"]
