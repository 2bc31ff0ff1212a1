"""The compiled sensor kernels (``src/agrinav_gym/render/csrc``) through ctypes.

The kernels are plain C functions in the optional extension ``agrinav_gym.render._native`` (built by
``pip install``/``make`` where a C compiler exists). ctypes releases the GIL during each call,
so two threads can render two views at once. Where the extension is missing, or the
environment sets ``AGRINAV_NATIVE=0``, ``lib()`` returns None and the sensors use their numpy
and Embree paths, which give the same images more slowly (tests compare the two).
"""

from __future__ import annotations

import ctypes
import hashlib
import importlib.util
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

_vp, _i, _d, _u64 = ctypes.c_void_p, ctypes.c_int, ctypes.c_double, ctypes.c_uint64
_SIGNATURES: dict[str, tuple[Any, list[Any]]] = {
    "proxy_cast": (
        None,
        [_i, _vp, _vp, _vp, _vp, _d, _vp, _i, _i, _d, _d, _d, _vp, _i, _i, _i, _i, _i, _d, _d, _d]
        + [_vp] * 5,
    ),
    "raster_view": (_i, [_vp, _i, _i, _vp, _vp, _i, _i, _vp, _vp, _vp, _i, _i]),
    "resolve_view": (
        _i,
        [_vp, _i, _i, _vp, _vp, _vp, _vp, _vp, _vp, _vp, _vp, _i] + [_vp] * 7 + [_i, _i],
    ),
    "stereo_prepare": (None, [_i, _d, _d, _vp, _vp, _vp, _i, _i, _i]),
    "stereo_invalid": (_i, [_vp, _i, _i, _d, _d] + [_vp] * 11 + [_i, _i]),
    "finish_depth": (None, [_i, _i, _vp, _vp, _vp, _u64, _d, _d, _d, _vp, _vp, _vp, _vp]),
    "pixel_normals": (None, [_vp, _u64, _i, _i, _vp]),
    "refine_rays": (None, [_i, _vp, _vp, _vp, _vp, _vp, _vp]),
    "embree_packets": (None, [_vp, _vp, _vp, _vp, ctypes.c_int64, ctypes.c_int64]),
    "shade_view": (None, [_vp, _i, _i] + [_vp] * 14 + [_i] + [_vp] * 5 + [_i, _i]),
}

_LIB: Any = None
_TRIED = False
_STALE: str | None = None  # why a build was refused


class NativeUnavailable(RuntimeError):
    """The compiled kernels were asked for but are not built (or disabled)."""


def source_hash(csrc: Path) -> str:
    """setup.py's hash of the kernels' sources in ``csrc``."""
    h = hashlib.sha256()
    for f in sorted(csrc.glob("*.[ch]")):
        h.update(f.name.encode() + b"\0" + f.read_bytes())
    return h.hexdigest()[:16]


def stale(handle: Any) -> str | None:
    """Why a loaded build does not match the sources beside it (None: it does, or there are
    none to compare, as in an installed wheel). A build left from other sources would be called
    with the wrong arguments: wrong images, not an error."""
    try:
        fn = handle.agrinav_source_hash
    except AttributeError:
        return "it predates the source check"
    fn.restype = ctypes.c_char_p
    built = fn().decode()
    csrc = Path(__file__).resolve().parent / "csrc"
    if not any(csrc.glob("*.c")):
        return None
    here = source_hash(csrc)
    return None if built == here else f"built from sources {built}, these are {here}"


def disabled() -> bool:
    return os.environ.get("AGRINAV_NATIVE", "1").strip().lower() in ("0", "false", "no", "off")


def lib() -> Any:
    """The loaded kernels, or None where the extension is not built or is disabled."""
    global _LIB, _TRIED
    if disabled():
        return None
    if not _TRIED:
        _TRIED = True
        spec = importlib.util.find_spec("agrinav_gym.render._native")
        if spec is not None and spec.origin is not None:
            try:
                handle = ctypes.CDLL(spec.origin)
            except OSError:
                handle = None
            why = stale(handle) if handle is not None else None
            if why is not None:
                global _STALE
                _STALE = why
                warnings.warn(
                    f"agrinav_gym.render._native is stale ({why}); the sensors use their numpy and "
                    "Embree paths until it is rebuilt (pip install -e . or make test)",
                    RuntimeWarning,
                    stacklevel=2,
                )
            elif handle is not None:
                for name, (res, args) in _SIGNATURES.items():
                    f = getattr(handle, name)
                    f.restype, f.argtypes = res, args
                _LIB = handle
    return _LIB


def available() -> bool:
    return lib() is not None


def require(what: str) -> Any:
    """The kernels, or an error saying how to get them."""
    handle = lib()
    if handle is None:
        if disabled():
            why = "disabled by AGRINAV_NATIVE=0"
        elif _STALE is not None:
            why = f"stale, {_STALE} (rebuild: pip install -e . or make test)"
        else:
            why = "not built (reinstall with a C compiler: pip install -e . or make test)"
        raise NativeUnavailable(
            f"{what} needs the compiled kernels agrinav_gym.render._native: {why}"
        )
    return handle


def ptr(a: np.ndarray | None) -> int | None:
    """The address of a C-contiguous array (None stays None: a NULL pointer)."""
    if a is None:
        return None
    assert a.flags.c_contiguous, "kernels take C-contiguous arrays"
    return int(a.ctypes.data)


def geometry_block(
    heights: np.ndarray, x0: float, y0: float, spacing: float
) -> tuple[np.ndarray, np.ndarray]:
    """The kernels' geometry block (csrc/native.h ``geom_from``) for a height grid alone: ten
    pointers (slot prototypes, transforms, prototype vertices, faces, vertex and face counts,
    bounding spheres, heights, face adjacency, face clusters) and eight values (slots,
    prototypes, nx, ny, x0, y0, spacing, faces per cluster). ``heights`` must stay alive and
    C-contiguous float64; a caller with plants fills in their pointers and counts."""
    ny, nx = heights.shape
    ptrs = np.zeros(10, np.int64)
    ptrs[7] = heights.ctypes.data
    return ptrs, np.array([0, 0, nx, ny, x0, y0, spacing, 0], np.float64)
