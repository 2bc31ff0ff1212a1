"""pybullet's C code prints where the commands write: its build time to stderr on import, a
line per link to stdout when a URDF is merged. Those lines are sent nowhere."""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
from collections.abc import Iterator
from typing import TextIO


def _flush_c_stdio() -> None:
    # C's stdout is block-buffered on a pipe: what pybullet printed would otherwise reach the
    # real stream at its next flush, after the descriptor is restored
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None).fflush(None)


@contextlib.contextmanager
def quiet(stream: TextIO | None = None) -> Iterator[None]:
    """The stream's file descriptor (default stdout) points at /dev/null inside the block,
    for Python's and C's writes alike."""
    stream = sys.stdout if stream is None else stream
    try:
        fd = stream.fileno()
    except (AttributeError, OSError, ValueError):  # captured or replaced stream
        yield
        return
    stream.flush()
    _flush_c_stdio()
    saved = os.dup(fd)
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), fd)
        try:
            yield
        finally:
            stream.flush()
            _flush_c_stdio()
            os.dup2(saved, fd)
            os.close(saved)
