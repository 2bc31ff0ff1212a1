"""Helpers shared by the classical controllers: the local plan from the route observation."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def local_plan(
    route_obs: NDArray[np.float32], step: float = 0.05
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """The route observation as a dense polyline in the robot frame, starting beside the robot.

    The observation holds points 0.4, 0.8, ... m ahead of the robot's projection on the route;
    one point is extrapolated back so the plan also covers the robot's own position.
    """
    r = np.asarray(route_obs, np.float64).reshape(-1, 3)
    pts, tags = r[:, :2], r[:, 2] > 0.5
    if len(pts) >= 2:
        pts = np.vstack([2 * pts[0] - pts[1], pts])
        tags = np.concatenate([tags[:1], tags])
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-6])  # the route's end repeats its last point
    pts, tags = pts[keep], tags[keep]
    if len(pts) < 2:
        return pts, tags
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    s = np.arange(0.0, arc[-1] + 1e-9, step)
    dense = np.column_stack([np.interp(s, arc, pts[:, 0]), np.interp(s, arc, pts[:, 1])])
    dense_tags = tags[np.minimum(np.searchsorted(arc, s, side="right") - 1, len(tags) - 1)]
    return dense, dense_tags
