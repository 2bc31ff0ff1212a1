"""Output folders that appear whole or not at all.

``output_dir(out, overwrite)`` yields a hidden temporary sibling to write into; on success it
takes the place of ``out`` in one atomic step, on any failure (exception, SIGTERM turned into
``SystemExit`` by the CLI) it is removed. A ``kill -9`` leaves only the hidden temporary folder,
which the next run on the same parent removes once its owner is dead. Two runs writing the same
``out`` at once cannot both succeed: the second is refused while the first holds the lock.

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
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

from .errors import InputError

TMP_TAG = ".tmp-"
OLD_TAG = ".old-"
LOCK_TAG = ".lock"
_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def check_output_dir(directory: str | Path, overwrite: bool, what: str = "out") -> Path:
    """Refuse an unusable output path before any work is done (and before anything is made)."""
    out = Path(directory)
    if out.exists() and not out.is_dir():
        raise InputError(what, str(out), "exists and is not a directory")
    if out.exists() and not overwrite:
        raise InputError(
            what,
            str(out),
            "already exists; choose another directory or allow overwriting (--force)",
        )
    parent = _existing_parent(out)
    if not parent.is_dir():
        raise InputError(what, str(out), f"its parent {parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(what, str(out), f"cannot be created: {parent} is not writable")
    return out


def _existing_parent(p: Path) -> Path:
    q = p.absolute().parent
    while not q.exists() and q != q.parent:
        q = q.parent
    return q


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _owner(name: str, tag: str) -> int | None:
    """The pid encoded in a ``.<out>.tmp-<pid>-<rand>`` or ``.<out>.old-<pid>`` name."""
    rest = name.split(tag, 1)[1] if tag in name else ""
    head = rest.split("-", 1)[0]
    return int(head) if head.isdigit() else None


def clean_stale(out: Path) -> None:
    """Remove temporaries of ``out`` left by killed runs; restore an old copy a kill orphaned."""
    parent = out.parent
    if not parent.is_dir():
        return
    prefix = f".{out.name}"
    for entry in parent.iterdir():
        name = entry.name
        if not name.startswith(prefix):
            continue
        for tag in (TMP_TAG, OLD_TAG):
            if not name.startswith(prefix + tag):
                continue
            pid = _owner(name, tag)
            if pid is not None and pid != os.getpid() and _pid_alive(pid):
                continue
            if tag == OLD_TAG and not out.exists():
                entry.rename(out)  # a kill came between the two renames of a replace
            else:
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
def _lock(out: Path) -> Iterator[None]:
    lock_path = out.parent / f".{out.name}{LOCK_TAG}"
    fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InputError(
                "out", str(out), "is being written by another run; wait for it or pick another"
            ) from None
        yield
    finally:
        os.close(fd)
        with contextlib.suppress(OSError):
            lock_path.unlink()


@contextlib.contextmanager
def output_dir(directory: str | Path, overwrite: bool = False, what: str = "out") -> Iterator[Path]:
    """Yield a temporary folder that becomes ``directory`` when the block succeeds."""
    out = check_output_dir(directory, overwrite, what)
    out.parent.mkdir(parents=True, exist_ok=True)
    with _lock(out):
        clean_stale(out)
        check_output_dir(out, overwrite, what)  # again, under the lock
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}{TMP_TAG}{os.getpid()}-", dir=out.parent))
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)  # mkdtemp makes 0700; honour the umask like mkdir
        try:
            yield tmp
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
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise


def atomic_write_text(path: Path, text: str) -> None:
    """Write a file next to its final name, then rename it into place."""
    tmp = path.with_name(f".{path.name}{TMP_TAG}{os.getpid()}")
    try:
        tmp.write_text(text)
        tmp.replace(path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
