"""Is memory bounded over a long perception run? RSS of the run (this process and its worker
processes, summed) sampled every second while ``generate`` writes ``--frames`` frames.

Reports RSS at fractions of the run and the growth from 25 % to 95 % of it: a leak per frame,
per episode or per shard (a worker makes hundreds of fields) shows as a steady climb. Linux
(reads /proc). The RL-size image keeps 20,000 frames to tens of minutes on 2 cores; every
array is made and freed the same way at 848×480, only larger.

    python benchmarks/bench_dataset_memory.py [--frames 20000] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import threading
import time
from pathlib import Path

from baselines.dataset import generate, load_spec

PAGE = os.sysconf("SC_PAGE_SIZE")


def tree_rss(pid: int) -> int:
    """Resident bytes of ``pid`` and every descendant."""
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                ppid = int(f.read().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
        children.setdefault(ppid, []).append(int(entry))
    total, todo = 0, [pid]
    while todo:
        p = todo.pop()
        try:
            with open(f"/proc/{p}/statm") as f:
                total += int(f.read().split()[1]) * PAGE
        except OSError:
            pass
        todo += children.get(p, [])
    return total


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=20_000)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--size", default="64x48", help="WIDTHxHEIGHT")
    a = ap.parse_args()
    w, h = (int(v) for v in a.size.split("x"))
    spec = load_spec(None, {"width": w, "height": h, "frames_per_shard": 64, "frame_every": 4})
    samples: list[tuple[float, int]] = []
    stop = threading.Event()

    def sample() -> None:
        while not stop.is_set():
            samples.append((time.perf_counter(), tree_rss(os.getpid())))
            stop.wait(1.0)

    thread = threading.Thread(target=sample, daemon=True)
    t0 = time.perf_counter()
    thread.start()
    with tempfile.TemporaryDirectory() as d:
        n = generate(spec, Path(d) / "ds", seed=0, frames=a.frames, workers=a.workers)
        size = sum(f.stat().st_size for f in (Path(d) / "ds").iterdir())
    stop.set()
    thread.join()
    wall = time.perf_counter() - t0
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, {platform.python_version()}")
    print(
        f"{n} frames {w}x{h}, {a.workers} workers, {spec.frames_per_shard}-frame shards: "
        f"{wall / 60:.1f} min, {n / wall:.1f} frames/s, {size / 2**30:.2f} GiB written"
    )
    mb = [(t - t0, r / 2**20) for t, r in samples]

    def at(frac: float) -> float:
        k = min(len(mb) - 1, int(frac * (len(mb) - 1)))
        return mb[k][1]

    print(
        "RSS (MiB, run and workers) at "
        + ", ".join(f"{int(f * 100)} %: {at(f):.0f}" for f in (0.05, 0.25, 0.5, 0.75, 0.95))
    )
    print(
        f"peak {max(r for _, r in mb):.0f} MiB; growth 25 % -> 95 %: {at(0.95) - at(0.25):+.0f} MiB"
    )


if __name__ == "__main__":
    main()
