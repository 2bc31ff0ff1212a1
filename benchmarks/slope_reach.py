"""How steep the ground under a `steepest` field can be, over every site a draw can reach.

``terrain.site: steepest`` with ``max_slope_deg`` c picks the pixel whose window (at least 3
DEM pixels across) has the largest mean slope ≤ c, and the field is laid out centred on it. A
draw of c over [lo, hi] therefore reaches every candidate pixel whose window mean lies between
the one chosen at lo and hi. For each reachable pixel this samples the DEM's bicubic surface
(the one the scenario's heights come from) on a 1 m grid over the disc a field of up to
``--length`` × ``--width`` metres can cover, whatever its row direction, and reports the
steepest ground any such field can stand on and the distribution of the discs' median slopes.

With the defaults it answers: can the `ood` slope case (caps 9–12°) be disjoint from the
FieldRoute training split (caps 1–8°, rows 20–40 m, 12.5 m wide) in the slope the robot
drives? It maps metres to pixels with the DEM's pixel size at its centre (a 20 m disc: the
difference from the exact geodesy is below a centimetre of position).

``python benchmarks/slope_reach.py`` (≈ 2 min on the embedded DEM).
"""

from __future__ import annotations

import argparse
import math

import numpy as np
from scipy import ndimage

from scenario_gen.dem import Dem, load_embedded

STEP_M = 1.0  # disc sampling grid
DIFF_M = 0.5  # central-difference half step for the surface slope


def reachable(dem: Dem, extent_m: float, lo: float, hi: float) -> np.ndarray:
    """Pixels (row, col) a `steepest` draw with max_slope_deg in [lo, hi] can pick."""
    mean, bad = dem.window_slopes(extent_m)
    m = np.where(bad, np.nan, mean)
    below = m[m <= lo]
    start = float(below.max()) if below.size else float(np.nanmin(m))
    return np.argwhere(~bad & (m >= start) & (m <= hi))


def disc_slopes(dem: Dem, coeffs: np.ndarray, sites: np.ndarray, radius: float) -> np.ndarray:
    """(sites, points) slope in degrees of the bicubic surface over a disc round each site."""
    dx, dy = dem.pixel_size_m()
    g = np.arange(-radius, radius + 1e-9, STEP_M)
    ex, ny = np.meshgrid(g, g)
    inside = np.hypot(ex, ny) <= radius
    ex, ny = ex[inside], ny[inside]
    out = np.empty((len(sites), len(ex)))

    def z(r: np.ndarray, c: np.ndarray) -> np.ndarray:
        return ndimage.map_coordinates(coeffs, [r, c], order=3, mode="nearest", prefilter=False)

    for k, (i, j) in enumerate(sites):
        # a north-up raster: rows grow southward; pixel centres at integer indices
        col, row = j + ex / dx, i - ny / dy
        zx = (z(row, col + DIFF_M / dx) - z(row, col - DIFF_M / dx)) / (2 * DIFF_M)
        zy = (z(row - DIFF_M / dy, col) - z(row + DIFF_M / dy, col)) / (2 * DIFF_M)
        out[k] = np.degrees(np.arctan(np.hypot(zx, zy)))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--train", type=float, nargs=2, default=(1.0, 8.0), metavar=("LO", "HI"))
    ap.add_argument("--test", type=float, nargs=2, default=(9.0, 12.0), metavar=("LO", "HI"))
    ap.add_argument("--length", type=float, default=40.0, help="longest field, m")
    ap.add_argument("--width", type=float, default=12.5, help="field width, m")
    args = ap.parse_args(argv)
    dem = load_embedded()
    radius = math.hypot(args.length / 2, args.width / 2)
    extent = 2 * radius
    coeffs = ndimage.spline_filter(dem.surface_grid(), order=3, mode="nearest")
    print(f"{dem.source}; fields up to {args.length:g} x {args.width:g} m: a {radius:.1f} m disc")
    results = {}
    for name, (lo, hi) in (("train", args.train), ("test", args.test)):
        sites = reachable(dem, extent, lo, hi)
        s = disc_slopes(dem, coeffs, sites, radius)
        med = np.median(s, axis=1)
        results[name] = (s.max(axis=1), s.min(axis=1), med)
        print(
            f"{name} caps {lo:g}-{hi:g} deg: {len(sites)} reachable sites; steepest ground a "
            f"field can stand on {s.max():.1f} deg; disc median slope p10/p50/p90/max "
            + "/".join(f"{v:.1f}" for v in np.percentile(med, [10, 50, 90, 100]))
        )
    top = float(results["train"][0].max())
    tmin = results["test"][1]
    print(
        f"test sites whose whole disc is steeper than any ground a training field can stand on "
        f"({top:.1f} deg): {int((tmin > top).sum())} of {len(tmin)}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
