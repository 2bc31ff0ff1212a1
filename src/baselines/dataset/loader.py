"""Reading a perception dataset: a map-style PyTorch ``Dataset`` over its tar shards.

>>> ds = PerceptionDataset("runs/ds", split="train")  # one split's frames (None: all)
>>> sample = ds[0]                 # arrays, the lane offsets, the labels as JSON text
>>> loader = torch.utils.data.DataLoader(ds, batch_size=8)   # PyTorch's default collation
>>> ds.labels(0)                   # one frame's labels, parsed
"""

from __future__ import annotations

import io
import json
import tarfile
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from scenario_gen.errors import InputError, Notice

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
    """Frames of ``root``'s shards (of one ``split``, or all): ``rgb`` (H, W, 3) uint8,
    ``depth`` (H, W) float32 m, ``semantic`` (H, W) uint8, ``instance`` (H, W) int32, the lane
    label's ``lateral_offset`` (m) and ``heading_offset`` (rad) as floats (NaN where the frame
    has none), ``split``, ``key`` and ``labels``: the frame's JSON text, so every value has a
    fixed shape and PyTorch's default collation batches them (``parse_labels=True`` gives the
    parsed dict instead, for a loop over single frames)."""

    def __init__(
        self, root: str | Path, split: str | None = None, parse_labels: bool = False
    ) -> None:
        self.root = Path(root)
        self.parse_labels = parse_labels
        if not (self.root / MANIFEST).is_file():
            raise InputError("root", str(root), f"allowed: a dataset folder holding {MANIFEST}")
        manifest = json.loads((self.root / MANIFEST).read_text())
        splits = manifest.get("splits", {})
        if split is not None and split not in splits:
            allowed = ", ".join(splits) or "none (a dataset from before splits)"
            raise InputError("split", split, f"allowed: {allowed}")
        wanted = set(splits[split]["shards"]) if split is not None else None
        self.index: list[tuple[Path, str, dict[str, tarfile.TarInfo]]] = []
        for shard in sorted(self.root.glob("shard-*.tar")):
            if wanted is not None and shard.name not in wanted:
                continue
            with tarfile.open(shard) as tar:
                members: dict[str, dict[str, tarfile.TarInfo]] = {}
                for m in tar.getmembers():
                    key, _, part = m.name.partition(".")
                    members.setdefault(key, {})[part] = m
            self.index += [(shard, k, v) for k, v in members.items() if set(PARTS) <= set(v)]
        expected = splits[split]["shards"] if split is not None else None
        total = len(expected) if expected is not None else manifest.get("shards")
        found = len({shard for shard, _, _ in self.index})
        if isinstance(total, int) and found < total:
            # a run stopped mid-way keeps its whole shards: training on them is the user's call
            warnings.warn(
                Notice(
                    f"{self.root}: {found} of the {total} shards {MANIFEST} lists"
                    + (f" for split {split!r}" if split is not None else "")
                    + " are here (an unfinished run: rerun its command to complete it)"
                ),
                stacklevel=2,
            )

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, i: int) -> dict[str, Any]:
        shard, key, parts = self.index[i]
        out: dict[str, Any] = {"key": key}
        with tarfile.open(shard) as tar:
            for part, m in parts.items():
                f = tar.extractfile(m)
                assert f is not None
                data = f.read()
                if part == "json":
                    labels = json.loads(data)
                    lane = labels.get("lane") or {}
                    for name in ("lateral_offset", "heading_offset"):
                        v = lane.get(name)
                        out[name] = float("nan") if v is None else float(v)
                    out["split"] = str(labels.get("split", ""))
                    out["labels"] = labels if self.parse_labels else data.decode()
                else:
                    out[part.split(".")[0]] = _decode(m.name, data)
        return out

    def labels(self, i: int) -> dict[str, Any]:
        """Frame ``i``'s labels alone, without decoding its images."""
        shard, _, parts = self.index[i]
        with tarfile.open(shard) as tar:
            f = tar.extractfile(parts["json"])
            assert f is not None
            out: dict[str, Any] = json.loads(f.read())
        return out
