"""Fit the analytic proxy's parameters to the crop meshes and draw the figure.

For every species and catalog stage, ``agrinav_gym.tools.proxy_fit.fit_stage`` renders lanes with
the mesh camera and searches (fill, base, reach) minimising the proxy's per-pixel depth
difference. This script runs all fits on one planting's lanes, rewrites that planting's table
(``src/agrinav_gym/render/proxy_fit.json`` for ridged lanes, ``proxy_fit_flat.json`` for flat
ones) and draws ``docs/img/proxy_fit.png`` (``proxy_fit_flat.png``):

* fitted parameters against growth, per species;
* per-pixel depth difference, fitted against the former hand-tuned constants (0.2, 0.2, 0.9);
* maize leaf reach by height, measured on the meshes, with the fitted leaf band.

Run: ``python benchmarks/fit_proxy.py --planting flat`` (about a minute on 2 cores; ``ridged``
the default). Each stage's line prints, beside the fit, the other planting's table's objective
on the same lanes (where that table is there).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from tqdm import tqdm

from agrinav_gym.config import PROXY_PLANTINGS
from agrinav_gym.render.proxy_params import PLANTINGS, ProxyParams, fitted, proxy_params
from agrinav_gym.tools.proxy_fit import FitResult, fit_stage, write_table
from scenario_gen import CATALOG
from scenario_gen.crops import crop_mesh

ROOT = Path(__file__).resolve().parents[1]
SPECIES = ("corn", "tomato", "cabbage", "sunflower", "weed")


def reach_by_height(growth: float, bins: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """Maize leaf reach along the leaf plane (max |x| of the surface) per height band, as
    fractions of half the canopy width and of the height."""
    import trimesh

    mesh = crop_mesh("corn", growth)
    pts, _ = trimesh.sample.sample_surface(mesh, 20000, seed=0)
    h = float(CATALOG["corn"].height(growth))
    half = 0.5 * float(CATALOG["corn"].canopy_width(growth))
    band = np.clip((pts[:, 2] / h * bins).astype(int), 0, bins - 1)
    reach = np.zeros(bins)
    np.maximum.at(reach, band, np.abs(pts[:, 0]) / half)
    return (np.arange(bins) + 0.5) / bins, reach


def figure(results: dict[str, list[tuple[float, FitResult]]], out: Path, planting: str) -> None:
    fig = Figure(figsize=(13, 8.5))
    FigureCanvasAgg(fig)
    ax = fig.subplots(2, 2)
    for name in SPECIES:
        g = [x for x, _ in results[name]]
        ax[0, 0].plot(g, [r.params.fill for _, r in results[name]], "o-", label=name)
        fitted = [r.depth[0] + r.lane[0] for _, r in results[name]]
        ax[1, 0].plot(g, fitted, "o-", label=f"{name} fitted")
        ax[1, 0].plot(g, [r.start for _, r in results[name]], "x:", color="grey")
    corn = results["corn"]
    g = [x for x, _ in corn]
    ax[0, 1].plot(g, [r.params.base for _, r in corn], "s-", label="maize leaf band base / height")
    ax[0, 1].plot(
        g, [r.params.reach for _, r in corn], "^-", label="maize leaf reach / half canopy"
    )
    ax[0, 0].set(xlabel="growth", ylabel="core radius / canopy width", title="core fill")
    ax[0, 1].set(xlabel="growth", ylabel="fraction", title="maize leaf band")
    ax[1, 0].set(
        xlabel="growth",
        ylabel="mean |Δz| per pixel + mean |Δ lane width|, m",
        title="proxy vs mesh (grey ×: the former constants 0.2, 0.2, 0.9)",
    )
    for a in (ax[0, 0], ax[0, 1], ax[1, 0]):
        a.legend(fontsize=7)
        a.grid(alpha=0.3)
    b = ax[1, 1]
    for growth, r in corn:
        z, reach = reach_by_height(growth)
        (line,) = b.plot(reach, z, label=f"growth {growth:g}")
        p = r.params
        band = p.reach if p.reach * 0.5 > p.fill else 0.0
        b.plot([band, band], [p.base, 1.0], "--", color=line.get_color())
        b.plot([2 * p.fill] * 2, [0, 1.0], ":", color=line.get_color())
    b.set(
        xlabel="leaf reach along the leaf plane / half canopy width",
        ylabel="height / plant height",
        title="maize: mesh reach by height (lines), fitted band (dashed), core (dotted)",
    )
    b.legend(fontsize=7)
    b.grid(alpha=0.3)
    fig.suptitle(f"proxy camera parameters fitted to the crop meshes on {planting} lanes")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--species", nargs="*", default=list(SPECIES))
    ap.add_argument("--no-write", action="store_true", help="print only; leave the table")
    ap.add_argument(
        "--planting",
        default="ridged",
        choices=PROXY_PLANTINGS,
        help="the lanes' planting, and the table written",
    )
    args = ap.parse_args()
    other = next(p for p in PROXY_PLANTINGS if p != args.planting)
    try:
        fitted(other)
        compare = True
    except FileNotFoundError:
        compare = False
    jobs = [
        (name, float(CATALOG[name].growth_of_stage(s)))
        for name in args.species
        for s in range(1, CATALOG[name].stages + 1)
    ]
    results: dict[str, list[tuple[float, FitResult]]] = {n: [] for n in args.species}
    t0 = time.perf_counter()
    for name, growth in tqdm(jobs, desc="fitting proxy stages"):
        shipped = ProxyParams(*map(float, proxy_params(name, growth, other))) if compare else None
        r = fit_stage(name, growth, planting=args.planting, reference=shipped)
        results[name].append((growth, r))
        tqdm.write(
            f"{name:9s} growth {growth:.3f}: fill {r.params.fill:.2f} base {r.params.base:.2f} "
            f"reach {r.params.reach:.2f} | mean |dz| {r.depth[0]:.3f} m + lane width error "
            f"{r.lane[0]:.3f} m (hand-tuned constants: {r.start:.3f} m)"
            + (
                f" | {other} table {shipped.fill:.2f} {shipped.base:.2f} {shipped.reach:.2f}: "
                f"{r.reference:.3f} m"
                if shipped is not None and r.reference is not None
                else ""
            )
        )
    print(f"fits took {time.perf_counter() - t0:.0f} s")
    if not args.no_write and set(args.species) == set(SPECIES):
        table = write_table(results, planting=args.planting)
        img = "docs/img/" + PLANTINGS[args.planting].replace(".json", ".png")
        figure(results, ROOT / img, args.planting)
        print(f"wrote {table} and {img}")


if __name__ == "__main__":
    main()
