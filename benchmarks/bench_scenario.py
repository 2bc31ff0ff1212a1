"""Scenario-generator benchmarks (the scenario generator's performance targets).

Measures, as the median of several runs in one process:

1. laying out ≈2,200 plants (paper-p1 field) with heights and orientation on a terrain of at
   least 500k samples — layout + k-NN IDW heights + slope orientation; the terrain and its
   KD-tree exist already (their build is reported on its own line);
2. the same for ≈100,000 plants;
3. ``generate`` end to end for the ``default`` preset (DEM load, site search, resampling,
   furrows, KD-tree, layout, route);
4. ``generate`` end to end for ≈100,000 plants in straight and in curved rows (radius 30-80 m),
   the two runs interleaved so that both see the same machine load; target: curved within
   twice the straight grid's time.

Run: ``make bench`` or ``python benchmarks/bench_scenario.py [--repeat N]``.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import time
from collections.abc import Callable

import numpy as np

import scenario_gen as sg
from scenario_gen.generate import place_plants
from scenario_gen.layout import layout


def median_ms(fn: Callable[[], object], repeat: int) -> tuple[float, float]:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times), min(times)


def placement_case(spec: sg.ScenarioSpec, repeat: int) -> dict[str, float]:
    scn = sg.generate(spec, seed=0)
    terrain = scn.terrain.with_heights(scn.terrain.heights)  # a fresh object: no cached tree
    t0 = time.perf_counter()
    _ = terrain.tree
    tree_ms = (time.perf_counter() - t0) * 1e3
    angle = scn.rows.angle

    def run() -> int:
        rngs = [np.random.default_rng(i) for i in range(4)]
        lay = layout(scn.field, spec.layout, angle, rngs[0], rngs[1], rngs[2])
        plants = place_plants(lay, terrain, spec.crop, 0.5, rngs[3])
        return len(plants)

    n = run()
    med, best = median_ms(run, repeat)
    return {
        "plants": n,
        "samples": terrain.size,
        "median_ms": med,
        "min_ms": best,
        "tree_ms": tree_ms,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}, numpy {np.__version__}"
    )
    print(f"median of {args.repeat} runs\n")

    # 1. paper-p1 (≈2,200 plants) with a margin wide enough for a ≥ 500k-sample terrain
    p1 = sg.preset("paper-p1", terrain={"margin": 20.0})
    a = placement_case(p1, args.repeat)
    print(
        f"{a['plants']:>7} plants on {a['samples']:>9,} samples: {a['median_ms']:8.2f} ms "
        f"(min {a['min_ms']:.2f}; {a['median_ms'] * 1e3 / a['plants']:.2f} µs/plant; "
        f"target ≤ 20 ms; paper < 0.2 ms/plant)   [KD-tree build {a['tree_ms']:.0f} ms]"
    )

    # 2. ≈100,000 plants: 316 x 316 m at 1 x 1 m; LoD 19 (0.24 m) is the coarsest grid that keeps
    #    the furrow ridges of 1 m rows (scenario_gen.bounds.check_lod)
    side = math.sqrt(100_000) + 2 * 3.5
    big = sg.preset(
        "paper-p1", field={"width": side, "length": side + 6.0}, terrain={"lod": 19, "margin": 4.0}
    )
    b = placement_case(big, max(3, args.repeat // 2))
    print(
        f"{b['plants']:>7} plants on {b['samples']:>9,} samples: {b['median_ms']:8.2f} ms "
        f"(min {b['min_ms']:.2f}; target ≤ 500 ms)   [KD-tree build {b['tree_ms']:.0f} ms]"
    )

    # 3. generate(default) end to end
    spec = sg.preset("default")
    med, best = median_ms(lambda: sg.generate(spec, seed=0), args.repeat)
    print(f"generate('default') end to end: {med:8.1f} ms (min {best:.1f}; target ≤ 2000 ms)")

    # 4. ≈100,000 plants end to end, straight vs curved rows, interleaved
    times: dict[str, list[float]] = {"straight": [], "curved": []}
    plants: dict[str, int] = {}
    for _ in range(max(3, args.repeat // 2)):
        for geometry in times:
            spec = big.replace({"layout.row_geometry": geometry})
            t0 = time.perf_counter()
            scn = sg.generate(spec, seed=0)
            times[geometry].append((time.perf_counter() - t0) * 1e3)
            plants[geometry] = len(scn.plants)
    med_s, med_c = statistics.median(times["straight"]), statistics.median(times["curved"])
    print(
        f"generate ≈100k plants, {len(times['curved'])} runs each: straight "
        f"{med_s:8.1f} ms ({plants['straight']} plants), curved {med_c:8.1f} ms "
        f"({plants['curved']} plants): {med_c / med_s:.2f}x (target ≤ 2x)"
    )


if __name__ == "__main__":
    main()
