"""Reference geometry in plain numpy, slow and obvious: the oracles the proxy camera's fast paths
(the compiled cast, Embree) are tested against. Test code only."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from agrinav_gym.render.proxy_plants import PlantField
from scenario_gen import Terrain

FloatArray = NDArray[np.float64]
MARCH_STEP = 0.15  # m between terrain samples along a ray before the secant refinement
MAX_MARCH = 24


def ground_hits(o: FloatArray, rays: FloatArray, terrain: Terrain, t_lim: FloatArray) -> FloatArray:
    """Ray length to the first terrain crossing (inf where none within ``t_lim``): a bracketed
    march with secant refinement, the reference ``DepthCamera.ground`` is tested against."""
    reach = float(t_lim.max())
    s = terrain.spacing
    ny, nx = terrain.shape
    j0 = max(int((o[0] - reach - terrain.x0) / s), 0)
    j1 = min(int((o[0] + reach - terrain.x0) / s) + 2, nx)
    i0 = max(int((o[1] - reach - terrain.y0) / s), 0)
    i1 = min(int((o[1] + reach - terrain.y0) / s) + 2, ny)
    window = terrain.heights[i0:i1, j0:j1] if (i1 > i0 and j1 > j0) else terrain.heights
    # a slab a little thicker than the local relief, so a flat field still brackets the crossing
    zlo, zhi = float(window.min()) - 1e-3, float(window.max()) + 1e-3
    dz = rays[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (zlo - o[2]) / dz
        b = (zhi - o[2]) / dz
    t_in = np.where(dz != 0, np.minimum(a, b), np.where(zlo <= o[2] <= zhi, 0.0, np.inf))
    t_out = np.where(dz != 0, np.maximum(a, b), np.where(zlo <= o[2] <= zhi, np.inf, -np.inf))
    t_in = np.maximum(t_in, 0.0)
    t_out = np.minimum(t_out, t_lim)
    live = t_in < t_out
    out = np.full(len(rays), np.inf)
    if not live.any():
        return out
    r = rays[live]
    ta, tb = t_in[live], t_out[live]
    # The ray can only cross the terrain inside the slab [zlo, zhi] of the local window, so the
    # march covers that stretch only: a few samples on a furrowed field, more on a hillside.
    span = float(np.percentile(tb - ta, 90))
    samples = int(np.clip(math.ceil(span / MARCH_STEP) + 1, 4, MAX_MARCH))
    ts = ta[:, None] + (tb - ta)[:, None] * np.linspace(0.0, 1.0, samples)[None, :]

    def f(t: FloatArray, rr: FloatArray) -> FloatArray:
        return (
            o[2] + t * rr[..., 2] - terrain.height_at(o[0] + t * rr[..., 0], o[1] + t * rr[..., 1])
        )

    fs = f(ts, r[:, None, :])
    below = fs <= 0.0
    hit = below.any(axis=1)
    if not hit.any():
        return out
    k = np.argmax(below, axis=1)[hit]
    rows = np.flatnonzero(hit)
    r = r[hit]
    km = np.maximum(k - 1, 0)
    t0, t1 = ts[rows, km], ts[rows, k]
    f0, f1 = fs[rows, km], fs[rows, k]
    for _ in range(2):  # secant / regula falsi refinement of the bracket
        tm = np.where(f0 != f1, t0 + f0 * (t1 - t0) / np.where(f0 != f1, f0 - f1, 1.0), t1)
        fm = f(tm, r)
        above = fm > 0
        t0, f0 = np.where(above, tm, t0), np.where(above, fm, f0)
        t1, f1 = np.where(above, t1, tm), np.where(above, f1, fm)
    tm = np.where(f0 != f1, t0 + f0 * (t1 - t0) / np.where(f0 != f1, f0 - f1, 1.0), t1)
    idx = np.flatnonzero(live)[rows]
    out[idx] = tm
    return out


def plant_hits(
    o: FloatArray, rays: FloatArray, plants: PlantField, t_lim: FloatArray
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Ray length to the nearest plant cylinder (side, top or bottom) and whether it is a weed."""
    n = len(rays)
    t_best = np.full(n, np.inf)
    weed = np.zeros(n, bool)
    if len(plants) == 0:
        return t_best, weed
    reach = float(t_lim.max()) + plants.max_radius
    cand = np.asarray(plants.tree.query_ball_point(o[:2], reach), dtype=np.int64)
    if len(cand) == 0:
        return t_best, weed
    rel = plants.xy[cand] - o[:2]
    dist = np.hypot(rel[:, 0], rel[:, 1])
    rad = plants.radius[cand]
    # a cylinder whose disc holds the camera, seen by rays of any azimuth: from below or above
    # it, its cap; from inside it, the wall or cap the ray leaves through (as Embree's cones)
    for k in cand[dist <= rad]:
        z0, z1, r2 = plants.z[k], plants.top[k], plants.radius[k] ** 2
        cx, cy = o[0] - plants.xy[k, 0], o[1] - plants.xy[k, 1]
        dz = rays[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            if z0 <= o[2] <= z1:
                a = rays[:, 0] ** 2 + rays[:, 1] ** 2
                b = cx * rays[:, 0] + cy * rays[:, 1]
                side = (-b + np.sqrt(b * b - a * (cx * cx + cy * cy - r2))) / a
                cap = np.where(dz > 0, (z1 - o[2]) / dz, np.where(dz < 0, (z0 - o[2]) / dz, np.inf))
                tc = np.fmin(np.where(a > 0, side, np.inf), cap)
                ok = tc > 0
            else:
                tc = ((z0 if o[2] < z0 else z1) - o[2]) / dz
                px, py = cx + tc * rays[:, 0], cy + tc * rays[:, 1]
                ok = (tc > 0) & (px * px + py * py <= r2)
        ok &= tc < t_best
        t_best[ok] = tc[ok]
        weed[ok] = plants.is_weed[k]
    heading = math.atan2(float(rays[:, 1].mean()), float(rays[:, 0].mean()))
    az_p = np.angle(np.exp(1j * (np.arctan2(rel[:, 1], rel[:, 0]) - heading)))
    keep = (dist > rad) & (np.abs(az_p) < math.radians(100))
    cand, rel, dist, rad, az_p = cand[keep], rel[keep], dist[keep], rad[keep], az_p[keep]
    if len(cand) == 0:
        return t_best, weed
    half = np.arcsin(np.clip(rad / dist, 0.0, 1.0))
    az_r = np.angle(np.exp(1j * (np.arctan2(rays[:, 1], rays[:, 0]) - heading)))
    order = np.argsort(az_r, kind="stable")
    az_sorted = az_r[order]
    lo = np.searchsorted(az_sorted, az_p - half, side="left")
    hi = np.searchsorted(az_sorted, az_p + half, side="right")
    counts = hi - lo
    total = int(counts.sum())
    if total == 0:
        return t_best, weed
    pl = np.repeat(np.arange(len(cand)), counts)
    offset = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
    ray = order[np.repeat(lo, counts) + offset]
    # Elevation cull: a ray can only meet a cylinder if its slope dz/dh lies between the
    # lowest and highest slopes of the cylinder's points as seen from the camera. Most pairs
    # of the azimuth test fail it (a short plant 5 m away spans a few pixel rows).
    zb_c, zt_c = plants.z[cand] - o[2], plants.top[cand] - o[2]
    near, far = dist - rad, dist + rad
    s_lo = zb_c / np.where(zb_c < 0, near, far)
    s_hi = zt_c / np.where(zt_c >= 0, near, far)
    slope = rays[:, 2] / np.hypot(rays[:, 0], rays[:, 1])
    s_ray = slope[ray]
    sel = (s_ray >= s_lo[pl] - 1e-9) & (s_ray <= s_hi[pl] + 1e-9)
    ray, pl = ray[sel], pl[sel]
    if len(ray) == 0:
        return t_best, weed
    d = rays[ray]
    ox, oy = -rel[pl, 0], -rel[pl, 1]
    r2 = rad[pl] ** 2
    a = d[:, 0] ** 2 + d[:, 1] ** 2
    b = 2 * (ox * d[:, 0] + oy * d[:, 1])
    c = ox * ox + oy * oy - r2
    disc = b * b - 4 * a * c
    with np.errstate(invalid="ignore", divide="ignore"):
        t_side = (-b - np.sqrt(disc)) / (2 * a)
    zb, zt = zb_c[pl] + o[2], zt_c[pl] + o[2]
    z_side = o[2] + t_side * d[:, 2]
    side_ok = (disc >= 0) & (t_side > 0) & (z_side >= zb) & (z_side <= zt)
    with np.errstate(invalid="ignore", divide="ignore"):
        t_cap = (zt - o[2]) / d[:, 2]
        cx, cy = ox + t_cap * d[:, 0], oy + t_cap * d[:, 1]
    cap_ok = (d[:, 2] < 0) & (t_cap > 0) & (cx * cx + cy * cy <= r2)
    t_pair = np.where(side_ok, t_side, np.inf)
    t_pair = np.where(cap_ok, np.minimum(t_pair, t_cap), t_pair)
    # a leaf band above the camera is seen from below
    with np.errstate(invalid="ignore", divide="ignore"):
        t_bot = (zb - o[2]) / d[:, 2]
        bx, by = ox + t_bot * d[:, 0], oy + t_bot * d[:, 1]
    bot_ok = (d[:, 2] > 0) & (t_bot > 0) & (bx * bx + by * by <= r2)
    t_pair = np.where(bot_ok, np.minimum(t_pair, t_bot), t_pair)
    ok = np.isfinite(t_pair)
    if not ok.any():
        return t_best, weed
    ray, t_pair, pl = ray[ok], t_pair[ok], pl[ok]
    np.minimum.at(t_best, ray, t_pair)
    winner = t_pair == t_best[ray]
    weed[ray[winner]] = plants.is_weed[cand[pl[winner]]]
    return t_best, weed
