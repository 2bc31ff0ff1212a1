"""Array type aliases, named once for every package (SB3's ``type_aliases`` in spirit)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
F32 = NDArray[np.float32]
IntArray = NDArray[np.int64]
U8 = NDArray[np.uint8]
U32 = NDArray[np.uint32]
BoolArray = NDArray[np.bool_]
AnyFloat = NDArray[np.floating[Any]]

__all__ = ["F32", "U8", "U32", "AnyFloat", "BoolArray", "FloatArray", "IntArray"]
