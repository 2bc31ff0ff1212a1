"""Per-pixel standard normal draws from a counter: the stereo depth noise.

A frame takes one 64-bit key from the episode's ``rng``; pixel ``i``'s draw is a function of
(key, i) alone. So the draws need no buffer and no order: each band of rows, each thread and
each kernel computes the pixels it needs (only the valid hits), and the rng advances by one
draw per frame whatever the scene — the property the old whole-image ``standard_normal`` call
paid 9 ns a pixel for. The proxy and mesh cameras use the same key for the same rng state, so
paired frames carry the same noise pixel by pixel.

The bits are SplitMix64's (Steele, Lea & Flood 2014; passes BigCrush): output ``c`` of the
stream whose state is ``key`` is ``mix(key + (c + 1)·γ)``, counter-based by construction. A
pixel's first 64 bits come from the key's stream at ``c = i``; the few draws that need more
(≈ 1.5 %) continue in a second stream (key ``mix(key ^ KEY2)``) at ``c = i·2¹² + k``.

The normal is Marsaglia & Tsang's ziggurat with 256 layers (J. Stat. Softw. 5(8), 2000): the
low 8 bits pick a layer, bit 8 the sign, the top 53 bits the abscissa; a draw inside the
layer's rectangle under the curve (≈ 98.5 %) is returned at once, the wedges are tested against
exp(−x²/2) and the tail beyond r is Marsaglia's exponential method (1964).

The kernels (``csrc/pixel_noise.h``) compute the same function; this module's numpy twin gives
the same bits where they are missing (the tables are built here, once, and handed to both;
the rare wedge and tail draws call the C library's ``exp``/``log`` through ``math`` as the
kernels do).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from . import native

LAYERS = 256
#: the base layer's right edge for 256 layers (Marsaglia & Tsang 2000)
R = 3.6541528853610088
GAMMA = 0x9E3779B97F4A7C15
KEY2 = 0xD1B54A32D192ED03
SLOW_STRIDE = 1 << 12
_M64 = (1 << 64) - 1


def _tables() -> NDArray[np.float64]:
    """x (257: layer edges, x[1] = R, x[256] = 0), w (256: x·2⁻⁵³) and f (257: exp(−x²/2)),
    concatenated as the kernels read them."""

    def f(v: float) -> float:
        return math.exp(-0.5 * v * v)

    area = R * f(R) + math.sqrt(math.pi / 2) * math.erfc(R / math.sqrt(2))  # one layer's area
    x = [0.0] * (LAYERS + 1)
    x[0], x[1] = area / f(R), R
    for i in range(1, LAYERS - 1):
        x[i + 1] = math.sqrt(-2.0 * math.log(area / x[i] + f(x[i])))
    fx = [f(v) for v in x]
    fx[LAYERS] = 1.0
    w = [v * 2.0**-53 for v in x[:LAYERS]]
    return np.array(x + w + fx, np.float64)


TABLES = _tables()
_X, _W, _F = TABLES[: LAYERS + 1], TABLES[LAYERS + 1 : 2 * LAYERS + 1], TABLES[2 * LAYERS + 1 :]


def frame_key(rng: np.random.Generator) -> int:
    """A frame's key: one draw from ``rng``, whatever the scene."""
    return int(rng.integers(0, _M64, dtype=np.uint64, endpoint=True))


def _mix(z: int) -> int:
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _M64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _M64
    return z ^ (z >> 31)


def _bits(key: int, c: int) -> int:
    return _mix((key + (c + 1) * GAMMA) & _M64)


def _bits_array(key: int, c: NDArray[np.uint64]) -> NDArray[np.uint64]:
    z = np.uint64(key) + (c + np.uint64(1)) * np.uint64(GAMMA)  # wraps modulo 2⁶⁴, as in C
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    out: NDArray[np.uint64] = z ^ (z >> np.uint64(31))
    return out


def _unit_open(b: int) -> float:
    """(0, 1]: a logarithm's argument."""
    return float((b >> 11) + 1) * 2.0**-53


def _slow(key2: int, i: int, u: int) -> float:
    """The draw of pixel ``i`` whose first bits ``u`` fell outside their layer's rectangle
    (``key2``: the second stream's key)."""
    c = i * SLOW_STRIDE
    while True:
        layer = u & 0xFF
        x = float(u >> 11) * float(_W[layer])
        sign = -1.0 if u & 0x100 else 1.0
        if x < _X[layer + 1]:
            return sign * x
        if layer == 0:  # the tail beyond R: loop here (restarting would bias its mass)
            while True:
                a = -math.log(_unit_open(_bits(key2, c))) / R
                b = -math.log(_unit_open(_bits(key2, c + 1)))
                c += 2
                if b + b > a * a:
                    return sign * (R + a)
        y = float(_F[layer]) + float(_bits(key2, c) >> 11) * 2.0**-53 * float(
            _F[layer + 1] - _F[layer]
        )
        c += 1
        if y < math.exp(-0.5 * x * x):
            return sign * x
        u = _bits(key2, c)
        c += 1


def normals_numpy(key: int, n: int) -> NDArray[np.float64]:
    """Pixels 0..n-1's draws without the kernels."""
    u = _bits_array(key, np.arange(n, dtype=np.uint64))
    layer = (u & np.uint64(0xFF)).astype(np.intp)
    x = (u >> np.uint64(11)).astype(np.float64) * _W[layer]
    out: NDArray[np.float64] = np.where((u & np.uint64(0x100)) != 0, -x, x)
    key2 = _mix(key ^ KEY2)
    for i in np.flatnonzero(~(x < _X[layer + 1])):
        out[i] = _slow(key2, int(i), int(u[i]))
    return out


def kernel_args(key: int | None) -> dict[str, Any]:
    """``finish_depth``'s noise fields for a frame's ``key`` (None: no noise): the tables (NULL:
    none) and the key."""
    return {"noise_tables": None if key is None else TABLES, "noise_key": key or 0}


def normals(key: int, n: int) -> NDArray[np.float64]:
    """Pixels 0..n-1's draws (the kernels where built, else the numpy twin: the same bits)."""
    kernels = native.lib()
    if kernels is None:
        return normals_numpy(key, n)
    out = np.empty(n, np.float64)
    native.call(native.PixelNormalsArgs(tables=TABLES, key=key, i0=0, i1=n, out=out))
    return out
