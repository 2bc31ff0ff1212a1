"""Cross-track metrics exactly as the source paper defines them (DESIGN §6).

Cross-track error = perpendicular distance from each recorded pose (the ground projection of
base_link) to the nearest segment of the reference path. Reported: global RMSE, MAE, max,
in-furrow RMSE and headland RMSE (by the tag of each pose's nearest segment), completion
(% of the route's length reached) and crops hit. A category without poses (no headland in a
single-lane run) reports ``None``, not NaN, so results compare and serialize cleanly.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def project_to_polyline(
    points: ArrayLike, path: ArrayLike, chunk: int = 2048
) -> tuple[FloatArray, NDArray[np.int64], FloatArray, FloatArray]:
    """For each point: distance to the nearest segment, its index, arc length and signed CTE.

    Signed CTE is positive to the left of the path direction. Vectorized over points × segments
    in chunks so memory stays bounded for long logs.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    xy = np.asarray(path, dtype=np.float64).reshape(-1, 2)
    if len(xy) < 2:
        raise ValueError(f"path needs at least 2 points, got {len(xy)}")
    a, b = xy[:-1], xy[1:]
    ab = b - a
    L2 = np.maximum((ab * ab).sum(axis=1), 1e-18)
    seg_len = np.sqrt((ab * ab).sum(axis=1))
    s0 = np.concatenate([[0.0], np.cumsum(seg_len)])[:-1]
    dist = np.empty(len(pts))
    seg = np.empty(len(pts), np.int64)
    arc = np.empty(len(pts))
    signed = np.empty(len(pts))
    for i in range(0, len(pts), chunk):
        p = pts[i : i + chunk, None, :]
        u = np.clip(((p - a) * ab).sum(axis=2) / L2, 0.0, 1.0)
        q = a + u[..., None] * ab
        d2 = ((p[..., 0] - q[..., 0]) ** 2) + ((p[..., 1] - q[..., 1]) ** 2)
        k = np.argmin(d2, axis=1)
        rows = np.arange(len(k))
        dist[i : i + chunk] = np.sqrt(d2[rows, k])
        seg[i : i + chunk] = k
        arc[i : i + chunk] = s0[k] + u[rows, k] * seg_len[k]
        rel = pts[i : i + chunk] - a[k]
        cross = ab[k, 0] * rel[:, 1] - ab[k, 1] * rel[:, 0]
        signed[i : i + chunk] = np.sign(cross) * dist[i : i + chunk]
    return dist, seg, arc, signed


def segment_tags(labels: ArrayLike) -> NDArray[np.str_]:
    """Tag of each segment: ``furrow`` when both its waypoints are, else ``headland``."""
    lab = np.asarray(labels).astype(str)
    both = (lab[:-1] == "furrow") & (lab[1:] == "furrow")
    return np.where(both, "furrow", "headland")


def _rmse(x: FloatArray) -> float | None:
    return float(np.sqrt(np.mean(x * x))) if len(x) else None


def cross_track_metrics(
    poses: ArrayLike, path: ArrayLike, labels: ArrayLike | None = None, crops_hit: int = 0
) -> dict[str, Any]:
    """The paper's metrics for a pose log (N, 2+) against a reference path (M, 2+)."""
    pts = np.asarray(poses, dtype=np.float64)[:, :2]
    xy = np.asarray(path, dtype=np.float64)[:, :2]
    dist, seg, arc, _ = project_to_polyline(pts, xy)
    tags = segment_tags(labels if labels is not None else np.full(len(xy), "furrow"))[seg]
    length = float(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum())
    return {
        "rmse": _rmse(dist),
        "mae": float(np.mean(dist)) if len(dist) else None,
        "max": float(np.max(dist)) if len(dist) else None,
        "in_furrow_rmse": _rmse(dist[tags == "furrow"]),
        "headland_rmse": _rmse(dist[tags == "headland"]),
        "completion": 100.0 * float(arc.max()) / length if len(arc) and length > 0 else 0.0,
        "crops_hit": int(crops_hit),
        "poses": len(pts),
    }
