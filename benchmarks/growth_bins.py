"""How many growth nodes per species: the geometry change between a model and its node's model.

A plant at growth g is drawn with the prototype of the nearest node k/n (scaled to its height).
For candidate node counts n (multiples of the species' stage intervals, so every catalog stage
is a node), this measures the symmetric mean surface distance between ``crop_mesh(g)`` and the
node's model scaled to the same height, over 97 growths evenly spaced in [0, 1], and picks the
smallest n whose mean over g is at most 6 mm (the D455's depth RMS at 1.8 m in the 848 × 480
mode). The largest single distance is a leaf that appears up to half a step early or late; it
does not shrink with n, so it is reported, not used. Prints a markdown table (docs/camera.md)
and checks it against each catalog entry's ``mesh_intervals``.

Run: ``python benchmarks/growth_bins.py`` (about a minute).
"""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import cKDTree
from tqdm import tqdm

from scenario_gen import CATALOG
from scenario_gen.crops import crop_mesh

TOLERANCE = 0.006  # m
CANDIDATES = (6, 12, 24, 48, 96)
SAMPLES = 4000


def surface_distance(a: trimesh.Trimesh, b: trimesh.Trimesh) -> float:
    pa, _ = trimesh.sample.sample_surface(a, SAMPLES, seed=0)
    pb, _ = trimesh.sample.sample_surface(b, SAMPLES, seed=1)
    da = cKDTree(pb).query(pa)[0]
    db = cKDTree(pa).query(pb)[0]
    return 0.5 * float(da.mean() + db.mean())


def main() -> None:
    growths = np.linspace(0.0, 1.0, 97)
    rows = []
    chosen = {}
    for name in tqdm(list(CATALOG), desc="species"):
        sp = CATALOG[name]
        step = sp.stages - 1
        for n in (c for c in CANDIDATES if c % step == 0):
            d = []
            for g in growths:
                node = round(g * n) / n
                exact = crop_mesh(name, float(g))
                near = crop_mesh(name, float(node))
                near.apply_scale(float(sp.height(g)) / float(sp.height(node)))
                d.append(surface_distance(exact, near))
            mean, worst = float(np.mean(d)), float(np.max(d))
            rows.append((name, n, mean, worst))
            if name not in chosen and mean <= TOLERANCE:
                chosen[name] = n
    print("| species | steps n | mean distance, mm | largest, mm |")
    print("|---|---|---|---|")
    for name, n, mean, worst in rows:
        mark = " ← chosen" if chosen.get(name) == n else ""
        print(f"| {name} | {n}{mark} | {mean * 1e3:.1f} | {worst * 1e3:.0f} |")
    print("chosen:", chosen)
    shipped = {name: sp.mesh_intervals for name, sp in CATALOG.items()}
    if chosen != shipped:
        print("WARNING: the catalog's mesh_intervals differ:", shipped)


if __name__ == "__main__":
    main()
