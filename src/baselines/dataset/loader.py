"""Reading a perception dataset: a map-style PyTorch ``Dataset`` over its tar shards.

>>> ds = PerceptionDataset("runs/ds")            # every frame of every shard
>>> sample = ds[0]                                # dict of numpy arrays + "labels"
>>> loader = torch.utils.data.DataLoader(ds, batch_size=8, collate_fn=lambda b: b)
"""

from __future__ import annotations

import io
import json
import tarfile
from pathlib import Path
from typing import Any

import numpy as np

from scenario_gen.errors import InputError

from .run import MANIFEST

try:  # the loader is a torch Dataset where torch is installed, a plain sequence otherwise
    from torch.utils.data import Dataset as _Base
except ImportError:  # pragma: no cover
    _Base = object  # type: ignore[assignment,misc]

PARTS = ("rgb.png", "depth.npy", "semantic.png", "instance.npy", "json")


def _decode(name: str, data: bytes) -> Any:
    if name.endswith(".png"):
        import cv2

        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise InputError("dataset", name, "is not a readable PNG")
        return img[..., ::-1].copy() if img.ndim == 3 else img
    if name.endswith(".npy"):
        return np.load(io.BytesIO(data), allow_pickle=False)
    return json.loads(data)


class PerceptionDataset(_Base):
    """Frames of ``root``'s shards: ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float32 m,
    ``semantic`` (H, W) uint8, ``instance`` (H, W) int32 and ``labels`` (the JSON)."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        if not (self.root / MANIFEST).is_file():
            raise InputError("root", str(root), f"allowed: a dataset folder holding {MANIFEST}")
        self.index: list[tuple[Path, str, dict[str, tarfile.TarInfo]]] = []
        for shard in sorted(self.root.glob("shard-*.tar")):
            with tarfile.open(shard) as tar:
                members: dict[str, dict[str, tarfile.TarInfo]] = {}
                for m in tar.getmembers():
                    key, _, part = m.name.partition(".")
                    members.setdefault(key, {})[part] = m
            self.index += [(shard, k, v) for k, v in members.items() if set(PARTS) <= set(v)]

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, i: int) -> dict[str, Any]:
        shard, key, parts = self.index[i]
        out: dict[str, Any] = {"key": key}
        with tarfile.open(shard) as tar:
            for part, m in parts.items():
                f = tar.extractfile(m)
                assert f is not None
                value = _decode(m.name, f.read())
                out["labels" if part == "json" else part.split(".")[0]] = value
        return out

    def labels(self, i: int) -> dict[str, Any]:
        """Frame ``i``'s labels alone, without decoding its images."""
        shard, _, parts = self.index[i]
        with tarfile.open(shard) as tar:
            f = tar.extractfile(parts["json"])
            assert f is not None
            out: dict[str, Any] = json.loads(f.read())
        return out
