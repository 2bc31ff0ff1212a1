"""Export benchmarks: seconds for the default field, bounded for 100k plants.

Each export runs as ``agrinav export`` in a fresh process (wall time and peak RSS of that
process, median of ``--repeat`` runs):

1. every target (gazebo, nav2, gis, mesh) on the ``default`` preset (≈2,900 plants);
2. gazebo and gis on a ≈100,000-plant field (merged tiles): time per plant and peak memory
   side by side with case 1;
3. what Gazebo's own parser pays per plant: libsdformat 12 (tools/sdf_check, built with
   tools/sdf_check/build.sh) loading worlds of N ``<include>`` plants, against the tiled
   100k-plant world. This is the measurement behind ``ExportOptions.include_limit``.

Run: ``python benchmarks/bench_export.py [--repeat N] [--big-plants N]``; writes
``runs/bench_export.json`` and ``runs/bench_export.png``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tqdm import tqdm

ROOT = Path(__file__).resolve().parents[1]


def measure(cmd: list[str]) -> tuple[float, float]:
    """(wall seconds, peak RSS in MB) of one child process."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode() if proc.stderr else ""
    if proc.returncode != 0:
        raise SystemExit(f"failed: {' '.join(cmd)}\n{err[-2000:]}")
    return wall, usage.ru_maxrss / 1024.0


def agrinav(*args: str) -> list[str]:
    return [sys.executable, "-m", "baselines.cli", *args]


def du_mb(path: Path) -> float:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file()) / 2**20


def export_case(scn: Path, to: str, out: Path, repeat: int, *extra: str) -> dict[str, float]:
    runs = [
        measure(agrinav("export", str(scn), "--to", to, "--out", str(out), "--force", *extra))
        for _ in range(repeat)
    ]
    return {
        "seconds": statistics.median(r[0] for r in runs),
        "peak_mb": max(r[1] for r in runs),
        "size_mb": du_mb(out),
    }


def plant_count(scn: Path) -> int:
    return int(json.loads((scn / "scenario.json").read_text())["counts"]["plants"]) + int(
        json.loads((scn / "scenario.json").read_text())["counts"]["weeds"]
    )


def cut_world(world: Path, n: int, dest: Path) -> None:
    """The world with the terrain and its first ``n`` plant includes."""
    text = world.read_text()
    head = text[: text.index("<include>")]
    incs = re.findall(r"<include>.*?</include>", text)
    dest.write_text(head + "\n".join(incs[: n + 1]) + "\n  </world>\n</sdf>\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--big-plants", type=int, default=100_000)
    ap.add_argument("--out", default=str(ROOT / "runs"))
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench-export-"))
    results: dict[str, object] = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}",
    }
    try:
        steps = tqdm(total=5, desc="bench_export", unit="step")
        default = work / "default"
        measure(agrinav("scenario", "--out", str(default), "--no-preview"))
        # a field of about big-plants plants at the default spacing: 7.4 plants per planted m²,
        # ≈ 6.9 per field m² once headlands and edge margins are left out
        side = math.sqrt(args.big_plants / (6.9 * 1.45))
        big = work / "big"
        gen_big = measure(
            agrinav(
                "scenario",
                "--out",
                str(big),
                "--no-preview",
                "--set",
                f"field.width={side:.1f}",
                "--set",
                f"field.length={side * 1.45:.1f}",
            )
        )
        steps.update()
        n_def, n_big = plant_count(default), plant_count(big)
        table: dict[str, dict[str, float]] = {}
        for to in ("gazebo", "nav2", "gis", "mesh"):
            table[f"default {to}"] = export_case(default, to, work / f"d-{to}", args.repeat)
        steps.update()
        for to in ("gazebo", "gis"):
            table[f"100k {to}"] = export_case(big, to, work / f"b-{to}", args.repeat)
        steps.update()
        results |= {
            "plants_default": n_def,
            "plants_big": n_big,
            "generate_big_s": gen_big[0],
            "exports": table,
        }

        # libsdformat's cost per <include> vs the tiled world
        exe = work / "sdf_check"
        subprocess.run([str(ROOT / "tools/sdf_check/build.sh"), str(exe)], check=True)
        inc = work / "d-inc"
        measure(
            agrinav(
                "export", str(default), "--to", "gazebo", "--plants", "include", "--out", str(inc)
            )
        )
        sizes = [50, 200, 400]
        parse = {}
        for n in sizes:
            w = inc / "worlds" / f"cut{n}.sdf"
            cut_world(inc / "worlds" / "field.sdf", n, w)
            runs = [measure([str(exe), str(w), "-m", str(inc / "models")]) for _ in range(2)]
            parse[n] = (statistics.median(r[0] for r in runs), max(r[1] for r in runs))
        steps.update()
        tiled = [
            measure(
                [
                    str(exe),
                    str(work / "b-gazebo/worlds/field.sdf"),
                    "-m",
                    str(work / "b-gazebo/models"),
                ]
            )
            for _ in range(2)
        ]
        steps.update()
        steps.close()
        slope_s = (parse[sizes[-1]][0] - parse[sizes[0]][0]) / (sizes[-1] - sizes[0])
        slope_mb = (parse[sizes[-1]][1] - parse[sizes[0]][1]) / (sizes[-1] - sizes[0])
        results["sdformat"] = {
            "include_worlds": {str(n): {"seconds": s, "peak_mb": m} for n, (s, m) in parse.items()},
            "per_include_ms": slope_s * 1e3,
            "per_include_mb": slope_mb,
            "tiled_100k": {
                "seconds": statistics.median(t[0] for t in tiled),
                "peak_mb": max(t[1] for t in tiled),
            },
        }
    finally:
        shutil.rmtree(work, ignore_errors=True)
    report(results, Path(args.out))


def report(r: dict, out: Path) -> None:
    print(f"\nmachine: {r['machine']}")
    print(f"plants: default {r['plants_default']}, big {r['plants_big']}")
    print(f"{'export':<16}{'median s':>10}{'peak MB':>10}{'size MB':>10}{'µs/plant':>10}")
    for name, v in r["exports"].items():
        n = r["plants_big"] if name.startswith("100k") else r["plants_default"]
        print(
            f"{name:<16}{v['seconds']:>10.2f}{v['peak_mb']:>10.0f}{v['size_mb']:>10.1f}"
            f"{v['seconds'] / n * 1e6:>10.0f}"
        )
    for to in ("gazebo", "gis"):
        d, b = r["exports"][f"default {to}"], r["exports"][f"100k {to}"]
        per_plant = (b["seconds"] / r["plants_big"]) / (d["seconds"] / r["plants_default"])
        more = r["plants_big"] / r["plants_default"]
        print(
            f"{to}: 100k vs default, time per plant x{per_plant:.2f}, "
            f"peak memory x{b['peak_mb'] / d['peak_mb']:.2f} for x{more:.1f} plants"
        )
    s = r["sdformat"]
    print("libsdformat 12 loading a world (tools/sdf_check):")
    for n, v in s["include_worlds"].items():
        print(f"  {n:>5} plant includes: {v['seconds']:6.2f} s, {v['peak_mb']:6.0f} MB")
    print(f"  per include: {s['per_include_ms']:.1f} ms, {s['per_include_mb']:.2f} MB")
    t = s["tiled_100k"]
    print(
        f"  tiled {r['plants_big']}-plant world: {t['seconds']:.2f} s, {t['peak_mb']:.0f} MB "
        f"(includes would need ≈{s['per_include_ms'] * r['plants_big'] / 1e3:.0f} s, "
        f"≈{s['per_include_mb'] * r['plants_big'] / 1024:.0f} GB)"
    )
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_export.json").write_text(json.dumps(r, indent=2) + "\n")
    plot(r, out / "bench_export.png")


def plot(r: dict, path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    s = r["sdformat"]
    n = [int(k) for k in s["include_worlds"]]
    secs = [v["seconds"] for v in s["include_worlds"].values()]
    fig = Figure(figsize=(7.5, 4.2), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.plot(n, secs, "o-", label="one <include> per plant (measured)")
    big = r["plants_big"]
    ax.plot(
        [n[-1], big],
        [secs[-1], secs[-1] + s["per_include_ms"] / 1e3 * (big - n[-1])],
        ":",
        color="C0",
        label="… extrapolated at the measured cost per include",
    )
    ax.plot(
        [r["plants_big"]],
        [s["tiled_100k"]["seconds"]],
        "s",
        color="orange",
        label=f"{r['plants_big']} plants in merged tiles",
    )
    ax.axvline(1000, color="gray", ls="--", lw=0.8, label="include_limit (auto)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("plants in the world")
    ax.set_ylabel("libsdformat 12 load time (s)")
    ax.set_title("What Gazebo's parser pays before the first step", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path)


if __name__ == "__main__":
    main()
