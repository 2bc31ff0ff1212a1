"""Output folders that appear whole or not at all.

``output_dir(out, overwrite)`` yields a hidden temporary sibling to write into; on success it
takes the place of ``out`` in one atomic step, on any failure (exception, SIGTERM turned into
``SystemExit`` by the CLI) it is removed, with any parent folder it had to make. A ``kill -9``
leaves only the hidden temporary folder (and the empty lock file), which the next run writing
the same ``out`` removes. Two runs writing the same ``out`` at once cannot both succeed: the
second is refused while the first holds the lock (``flock`` on ``.<out>.lock``). New folders
get the mode ``mkdir`` would give them (0777 less the umask).

Replacing an existing folder uses Linux's ``renameat2(RENAME_EXCHANGE)``: the old and new
contents swap in one system call, so no kill can leave ``out`` missing. Where the call is
unavailable the old folder is renamed aside first and put back by the next run if a kill came
between the two renames.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import errno
import fcntl
import os
import re
import shutil
import tempfile
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TypeVar

from .errors import InputError

TMP_TAG = ".tmp-"
OLD_TAG = ".old-"
LOCK_TAG = ".lock"
#: bytes a temporary sibling's name adds to the output's: ".", TMP_TAG, a pid (≤ 7 digits on
#: Linux: pid_max ≤ 2^22), "-" and mkdtemp's 8 characters
TMP_RESERVE = 1 + len(TMP_TAG) + 7 + 1 + 8
#: Linux's limit on a path's bytes, its final NUL included (limits.h)
PATH_MAX = 4096
#: The file that marks a folder as agrinav's output, the only kind ``--force`` replaces.
MARKER = ".agrinav-output"
_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def check_output_dir(
    directory: str | Path,
    overwrite: bool,
    what: str = "out",
    kind: str | None = None,
    inputs: Sequence[str | Path | None] = (),
) -> Path:
    """Refuse an unusable output path before any work is done (and before anything is made).

    Overwriting replaces only a folder agrinav wrote (it holds ``MARKER``) — with ``kind``,
    only one of that kind (a policy export must not replace a scenario) — and never the
    current folder, one above it, the home folder or ``/``: ``--out . --force`` must not
    delete a user's files. Nor one that holds any of the command's ``inputs`` (files or
    folders it reads): replacing it would delete them."""
    if not str(directory).strip():  # Path("") is the current folder
        raise InputError(what, str(directory), "allowed: a folder path (it is empty)")
    out = Path(os.path.abspath(directory))  # "." and ".." resolved: out.name is a real name
    check_name_lengths(out, what)  # first: a stat of a name too long is errno 36
    check_name_characters(out, what)
    if out.is_symlink():  # replacing it would swap the link itself for a folder
        raise InputError(
            what,
            str(out),
            f"is a symbolic link (to {os.readlink(out)}); allowed: a real folder path, e.g. "
            "the folder it points to",
        )
    if out.exists() and not out.is_dir():
        raise InputError(what, str(out), "exists and is not a directory")
    # an empty folder (made ahead with mkdir) holds nothing to lose: it is taken as a new one
    empty = out.exists() and _is_empty(out)
    if out.exists() and not overwrite and not empty:
        raise InputError(
            what,
            str(out),
            "already exists; choose another directory or allow overwriting (--force)",
        )
    if out.exists():
        real = out.resolve()
        for given in inputs:
            if given is None:
                continue
            source = Path(given).expanduser().resolve()
            if source == real or real in source.parents:
                raise InputError(
                    what,
                    str(out),
                    f"holds this command's input {given}, which replacing it would delete; "
                    "choose another folder",
                )
        if empty:
            _check_protected(out, what)
        else:
            check_replaceable(out, what, kind)
    _check_parent(out, what)  # the names were checked above
    return out


def _is_empty(folder: Path) -> bool:
    try:
        with os.scandir(folder) as entries:
            return next(entries, None) is None
    except OSError:  # unreadable: not known to be empty
        return False


def check_creatable(out: Path, what: str = "out") -> None:
    """Refuse a folder that cannot be made: a file where a parent folder should be, a parent
    that is not writable, or a name the file system cannot hold (not errno's "File exists" or
    "File name too long" from deep inside a mkdir)."""
    check_name_lengths(out, what)  # first: a stat of a name too long is errno 36
    check_name_characters(out, what)
    _check_parent(out, what)


def _check_parent(out: Path, what: str) -> None:
    parent = _existing_parent(out)
    if not parent.is_dir():
        raise InputError(what, str(out), f"its parent {parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(what, str(out), f"cannot be created: {parent} is not writable")


def check_name_characters(out: Path, what: str = "out") -> None:
    """Refuse control characters (a newline, a tab, an escape) in the names still to be made:
    the file system takes them, but every listing, shell and log line that shows the folder
    breaks on them (a pasted path with a trailing newline made ``results\n``)."""
    new = out.absolute()
    while True:
        bad = [c for c in new.name if ord(c) < 32 or ord(c) == 127]
        if bad:
            raise InputError(
                what,
                str(out),
                f"the name {new.name!r} holds the control character {bad[0]!r}; allowed: "
                "names without control characters",
            )
        if new.parent == new or new.parent.exists():
            return
        new = new.parent


def check_name_lengths(out: Path, what: str = "out") -> None:
    """Refuse names longer than the file system holds (before any ``stat``, which would raise
    errno's "File name too long"): each folder still to be made, and ``out``'s own with room
    for its temporary sibling's tags (``.NAME.tmp-PID-XXXXXXXX``)."""
    parts = out.absolute().parts
    size = len(os.fsencode(str(out.absolute()))) + TMP_RESERVE
    if size >= PATH_MAX:
        raise InputError(
            what, str(out), f"the path is {size} bytes long with its temporary tags; "
            f"at most {PATH_MAX - 1} are allowed (the file system's limit)"
        )  # fmt: skip
    known = Path(parts[0])
    for i, name in enumerate(parts[1:], 1):
        try:
            name_max = os.pathconf(known, "PC_NAME_MAX")
        except (OSError, ValueError):
            name_max = 255
        last = i == len(parts) - 1
        allowed = name_max - TMP_RESERVE if last else name_max
        size = len(os.fsencode(name))
        if size > allowed:
            reason = (
                f"the file system takes {name_max}; the temporary folder the output is "
                f"written in adds {TMP_RESERVE}"
                if last
                else "the file system's limit for a folder's name"
            )
            raise InputError(
                what,
                str(out),
                f"the name {name[:24]}… is {size} bytes long; at most {allowed} are allowed "
                f"here ({reason})",
            )
        with contextlib.suppress(OSError):
            if known.is_dir():
                known = known / name


def check_replaceable(out: Path, what: str = "out", kind: str | None = None) -> None:
    """Refuse to replace ``out`` unless agrinav wrote it, as output of ``kind`` where that is
    given and the marker names one (see ``check_output_dir``)."""
    _check_protected(out, what)
    if not (out / MARKER).is_file():
        raise InputError(
            what,
            str(out),
            f"was not written by agrinav (no {MARKER} in it), so it is never replaced; "
            "choose another folder or remove it yourself",
        )
    found = marked_kind(out)
    if kind is not None and found is not None and found != kind:
        raise InputError(
            what,
            str(out),
            f"holds agrinav's {found} output; this command replaces only {kind} output "
            "(choose another folder)",
        )


def _check_protected(out: Path, what: str) -> None:
    real = out.resolve()
    cwd = Path.cwd().resolve()
    protected = {Path("/"), Path.home().resolve()}
    if real in protected or real == cwd or real in cwd.parents:
        raise InputError(
            what, str(out), "is the current, home or root folder (or above it); never replaced"
        )


def marked_kind(folder: Path) -> str | None:
    """The kind of output ``folder``'s marker names (None: none named, an older marker)."""
    try:
        text = (folder / MARKER).read_text(errors="replace")
    except OSError:
        return None
    for line in text.splitlines():
        if line.startswith("kind: "):
            return line.removeprefix("kind: ").strip()
    return None


def mark_output(folder: Path, kind: str | None = None) -> None:
    """Mark ``folder`` as agrinav's output (of ``kind``): ``--force`` may replace it later."""
    (folder / MARKER).write_text(
        "Written by agrinav; a later run with --force may replace this folder.\n"
        + (f"kind: {kind}\n" if kind else "")
    )


def _existing_parent(p: Path) -> Path:
    q = p.absolute().parent
    while not q.exists() and q != q.parent:
        q = q.parent
    return q


def _stale_names(out: Path) -> tuple[re.Pattern[str], re.Pattern[str]]:
    """Exact names of ``out``'s temporaries: ``.<name>.tmp-<pid>-<8 random>`` and
    ``.<name>.old-<pid>`` (so another folder's temporaries never match, whatever its name)."""
    name = re.escape(out.name)
    return (
        re.compile(rf"\.{name}{re.escape(TMP_TAG)}\d+-[a-z0-9_]{{8}}"),
        re.compile(rf"\.{name}{re.escape(OLD_TAG)}\d+"),
    )


def clean_stale(out: Path) -> None:
    """Remove temporaries of ``out`` left by killed runs; restore an old copy a kill orphaned.

    Called with ``out``'s lock held: every writer of ``out`` holds that lock for as long as its
    temporaries exist, so any that are found now belong to a run that died."""
    parent = out.parent
    if not parent.is_dir():
        return
    tmp_re, old_re = _stale_names(out)
    for entry in sorted(parent.iterdir()):
        if old_re.fullmatch(entry.name):
            if not out.exists():
                entry.rename(out)  # a kill came between the two renames of a replace
            else:
                shutil.rmtree(entry, ignore_errors=True)
        elif tmp_re.fullmatch(entry.name):
            shutil.rmtree(entry, ignore_errors=True)


def _exchange(a: Path, b: Path) -> bool:
    """Atomically swap two paths (Linux renameat2); False where unsupported."""
    libc_name = ctypes.util.find_library("c")
    if libc_name is None:
        return False
    libc = ctypes.CDLL(libc_name, use_errno=True)
    fn = getattr(libc, "renameat2", None)
    if fn is None:
        return False
    rc = fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    if rc == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.EXDEV, errno.ENOTSUP):
        return False
    raise OSError(err, os.strerror(err), str(b))


@contextlib.contextmanager
def lock_output(out: Path, what: str) -> Iterator[None]:
    """An exclusive, non-blocking lock on ``out`` (refused while another run holds it).

    The lock file is removed by its holder while still locked; a run that opened the old file
    just before finds, once it holds its lock, that the path no longer names that file, and
    retries with the new one — so two runs can never both hold ``out``."""
    lock_path = out.parent / f".{out.name}{LOCK_TAG}"
    while True:
        try:
            fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:  # a folder that refuses files though it looks writable (/proc)
            raise InputError(
                what, str(out), f"cannot be created: {out.parent} takes no files ({exc.strerror})"
            ) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise InputError(
                what, str(out), "is being written by another run; wait for it or pick another"
            ) from None
        try:
            same = os.stat(lock_path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        yield
    finally:
        with contextlib.suppress(OSError):
            lock_path.unlink()
        os.close(fd)


def make_parents(out: Path) -> list[Path]:
    """Create ``out``'s missing parent folders; the ones created, outermost first."""
    made: list[Path] = []
    q = out.absolute().parent
    while not q.exists():
        made.append(q)
        q = q.parent
    made.reverse()
    for p in made:
        p.mkdir(exist_ok=True)
    return made


def remove_empty(folders: list[Path]) -> None:
    for p in reversed(folders):
        with contextlib.suppress(OSError):
            p.rmdir()


@contextlib.contextmanager
def output_dir(
    directory: str | Path,
    overwrite: bool = False,
    what: str = "out",
    kind: str | None = None,
    inputs: Sequence[str | Path | None] = (),
) -> Iterator[Path]:
    """Yield a temporary folder that becomes ``directory`` when the block succeeds (marked as
    agrinav's output of ``kind``); ``inputs`` as ``check_output_dir`` takes them.

    On failure nothing is left: not the temporary folder, not a parent folder this call made.
    """
    out = check_output_dir(directory, overwrite, what, kind, inputs)
    made: list[Path] = []
    try:
        made = make_parents(out)
        with lock_output(out, what):
            clean_stale(out)
            check_output_dir(out, overwrite, what, kind, inputs)  # again, under the lock
            try:
                tmp = Path(
                    tempfile.mkdtemp(prefix=f".{out.name}{TMP_TAG}{os.getpid()}-", dir=out.parent)
                )
            except OSError as exc:
                raise InputError(what, str(out), f"cannot be created ({exc.strerror})") from None
            try:
                umask = os.umask(0)
                os.umask(umask)
                os.chmod(tmp, 0o777 & ~umask)  # mkdtemp makes 0700; honour the umask like mkdir
                yield tmp
                mark_output(tmp, kind)
                _publish(tmp, out)
            except BaseException:
                shutil.rmtree(tmp, ignore_errors=True)
                raise
    except BaseException:
        remove_empty(made)
        raise


def _publish(tmp: Path, out: Path) -> None:
    """Put the complete ``tmp`` in ``out``'s place in one step (swapping an old ``out`` out)."""
    if out.exists():
        if _exchange(tmp, out):
            shutil.rmtree(tmp)
        else:
            old = out.with_name(f".{out.name}{OLD_TAG}{os.getpid()}")
            out.rename(old)
            tmp.rename(out)
            shutil.rmtree(old)
    else:
        tmp.rename(out)


T = TypeVar("T")


def atomic_write(path: Path, write: Callable[[Path], T]) -> T:
    """``write`` a hidden file next to ``path`` (``.NAME.tmp-PID``), then rename it into place:
    the file is whole or absent; returns what ``write`` returned."""
    tmp = path.with_name(f".{path.name}{TMP_TAG}{os.getpid()}")
    try:
        out = write(tmp)
        tmp.replace(path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    return out


def atomic_write_text(path: Path, text: str) -> None:
    """Write a file next to its final name, then rename it into place."""
    atomic_write(path, lambda tmp: tmp.write_text(text))
