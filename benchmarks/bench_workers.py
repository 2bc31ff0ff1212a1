"""``agrinav bench`` on one worker and on two (target: 2 workers ≥ 1.7x one), interleaved.

Each run is the whole command in a fresh process — argument checks, every case's env built once
to check the policies, the workers started (spawned: each imports the package and builds its
env), the episodes, the tables and figures — timed from start to exit. The records of the two
are compared (they must be the same but for each episode's wall time). CPU: what the command's
processes used over its wall time (on a shared machine the workers get what the others leave).

    python benchmarks/bench_workers.py [--repeat 3] [--seeds 8] [--policies rpp,dwb,stanley]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def run(out: Path, workers: int, args: argparse.Namespace) -> tuple[float, float]:
    """(wall seconds, CPU seconds of the command's processes) of one ``agrinav bench``."""
    cmd = [sys.executable, "-m", "baselines.cli", "bench", "--suite", args.suite]
    cmd += ["--policies", args.policies, "--seeds", str(args.seeds), "--out", str(out)]
    cmd += ["--workers", str(workers)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def records(out: Path) -> list[dict[str, object]]:
    rows = json.loads((out / "results.json").read_text())
    for r in rows:
        r.pop("seconds")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--suite", default="smoke")
    ap.add_argument("--policies", default="rpp,dwb,stanley")
    ap.add_argument("--seeds", type=int, default=8)
    args = ap.parse_args()
    episodes = len(args.policies.split(",")) * args.seeds
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}; load average {os.getloadavg()[0]:.1f} at the start"
    )
    print(
        f"agrinav bench --suite {args.suite} --policies {args.policies} --seeds {args.seeds} "
        f"({episodes} episodes), median of {args.repeat} interleaved runs:"
    )
    walls: dict[int, list[float]] = {1: [], 2: []}
    cpus: dict[int, list[float]] = {1: [], 2: []}
    with tempfile.TemporaryDirectory(prefix="bench-workers-") as tmp:
        for r in range(args.repeat):
            for n in (1, 2):
                wall, cpu = run(Path(tmp) / f"w{n}-{r}", n, args)
                walls[n].append(wall)
                cpus[n].append(cpu)
        same = all(
            records(Path(tmp) / f"w2-{r}") == records(Path(tmp) / "w1-0")
            for r in range(args.repeat)
        )
    one, two = statistics.median(walls[1]), statistics.median(walls[2])
    for n in (1, 2):
        w, c = statistics.median(walls[n]), statistics.median(cpus[n])
        print(
            f"   --workers {n}: {w:6.1f} s ({episodes / w:.2f} episodes/s), CPU {c:.1f} s "
            f"({c / w:.2f} cores busy)"
        )
    print(
        f"   2 workers / 1: {one / two:.2f}x (target ≥ 1.7x); records the same: {same}; load "
        f"average {os.getloadavg()[0]:.1f} at the end"
    )


if __name__ == "__main__":
    main()
