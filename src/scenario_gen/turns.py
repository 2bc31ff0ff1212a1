"""Headland turns between two lanes, sized to the robot (design.md, "The scenario pipeline").

Every turn is built in one canonical frame: it leaves the end of a lane at (0, 0) heading +x
and enters the next lane, ``w`` metres to its left, at (0, w) heading −x. ``routes.zigzag``
lays it on the rows at the turn point (``RowFrame.local_to_enu``: x along the direction of
travel, y along the rows' normal), so the same turn serves straight, curved and contour rows.

The types follow the turn families of Fields2Cover (``f2c::pp::DubinsCurves``,
``ReedsSheppCurves``: src/fields2cover/path_planning/dubins_curves.cpp,
reeds_shepp_curves.cpp, built for a robot's minimum turning radius between a swath's end and
the next swath's start, turning_base.cpp ``createTurn``), which opennav_coverage exposes as its
``DUBIN`` and ``REEDS_SHEPP`` path modes (opennav_coverage/src/path_generator.cpp) with the
robot's ``min_turning_radius`` (include/opennav_coverage/robot_params.hpp); a Fields2Cover path
state carries its direction, FORWARD or BACKWARD, and its section type, SWATH or TURN
(include/fields2cover/types/PathState.h), as the route's ``direction`` and ``turn`` tags do
here. The turns are written out as the closed forms of the curve words, not searched:

- ``semicircle``: half a circle of diameter ``w`` (the lanes' spacing), whatever the robot.
- ``omega`` (Ω, bulb): the Dubins word RLR for ``w < 2R``: a turn away from the next lane, a
  loop of radius R around the far side, a turn away again — the shortest forward turn between
  lanes closer than two turning radii. It bulges ``R − w/2`` beyond each lane.
- ``keyhole``: the Dubins word LRL: toward the next lane, across its extension, a loop of
  ≈ 330° back through the neck and into it; forward only, longer and deeper than the omega.
- ``three_point``: the Reeds–Shepp word L+ R− L+ (C|C|C) with two cusps: forward left through
  α, reverse through π − 2α (still turning the same way), forward left through α, with
  cos α = (2 − w/R)/4; it stays between the two lanes' lines and reaches R·sin α past the turn
  point.

With ``w ≥ 2R`` the last three are the flat turn LSL (quarter circle, straight, quarter
circle). Curvature is 1/R on every arc (0 on straights), so the path never curves tighter than
the turning radius; ``three_point`` is driven backwards between its cusps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from .arrays import FloatArray, IntArray

TURN_TYPES = ("semicircle", "omega", "keyhole", "three_point")


@dataclass(frozen=True)
class TurnPath:
    """A turn in the canonical frame: points, the robot's facing direction at each (rad) and
    the direction the segment leaving each point is driven (+1 forward, −1 backward)."""

    xy: FloatArray
    yaw: FloatArray
    direction: NDArray[np.int8]

    def __len__(self) -> int:
        return len(self.xy)

    @property
    def cusps(self) -> IntArray:
        """Indices where the direction of travel changes."""
        return np.flatnonzero(np.diff(self.direction[:-1]) != 0) + 1


def _arc(
    c: tuple[float, float], r: float, a0: float, sweep: float, forward: bool, step: float
) -> tuple[FloatArray, FloatArray]:
    n = max(2, math.ceil(r * abs(sweep) / step) + 1)
    a = a0 + np.linspace(0.0, sweep, n)
    xy = np.column_stack([c[0] + r * np.cos(a), c[1] + r * np.sin(a)])
    travel = a + math.copysign(0.5 * math.pi, sweep)
    return xy, travel if forward else travel + math.pi


def _line(
    a: tuple[float, float], b: tuple[float, float], step: float
) -> tuple[FloatArray, FloatArray]:
    n = max(2, math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / step) + 1)
    f = np.linspace(0.0, 1.0, n)[:, None]
    xy = np.asarray(a) * (1 - f) + np.asarray(b) * f
    return xy, np.full(n, math.atan2(b[1] - a[1], b[0] - a[0]))


def _join(parts: list[tuple[FloatArray, FloatArray, int]]) -> TurnPath:
    xy, yaw, dirs = [], [], []
    for i, (p, h, d) in enumerate(parts):
        k = 0 if i == 0 else 1  # junctions are shared with the previous part
        xy.append(p[k:])
        yaw.append(h[k:])
        dirs.append(np.full(len(p) - k, d, np.int8))
        if i > 0:
            dirs[-2][-1] = d  # the junction leaves in this part's direction
    return TurnPath(np.concatenate(xy), np.unwrap(np.concatenate(yaw)), np.concatenate(dirs))


def canonical_turn(kind: str, w: float, radius: float, step: float) -> TurnPath:
    """The ``kind`` turn from (0, 0) heading +x to (0, ``w``) heading −x, ``radius`` the
    smallest turning radius (unused by the semicircle), points at most ``step`` apart."""
    if w <= 0:
        raise ValueError(f"lane spacing {w} must be positive")
    R = radius
    if kind == "semicircle":
        return _join([(*_arc((0.0, 0.5 * w), 0.5 * w, -0.5 * math.pi, math.pi, True, step), 1)])
    if kind not in TURN_TYPES:
        raise ValueError(f"unknown turn type {kind!r}")
    if w >= 2 * R:  # flat turn: LSL
        return _join(
            [
                (*_arc((0.0, R), R, -0.5 * math.pi, 0.5 * math.pi, True, step), 1),
                (*_line((R, R), (R, w - R), step), 1),
                (*_arc((0.0, w - R), R, 0.0, 0.5 * math.pi, True, step), 1),
            ]
        )
    if kind == "omega":  # RLR
        xc = math.sqrt(4 * R * R - (0.5 * w + R) ** 2)
        phi = math.atan2(0.5 * w + R, xc)
        return _join(
            [
                (*_arc((0.0, -R), R, 0.5 * math.pi, -(0.5 * math.pi - phi), True, step), 1),
                (*_arc((xc, 0.5 * w), R, phi - math.pi, 2 * math.pi - 2 * phi, True, step), 1),
                (*_arc((0.0, w + R), R, -phi, -(0.5 * math.pi - phi), True, step), 1),
            ]
        )
    if kind == "keyhole":  # LRL
        xc = math.sqrt(4 * R * R - (R - 0.5 * w) ** 2)
        psi = math.atan2(0.5 * w - R, xc)
        a_end = math.atan2(0.5 * w - R, -xc)
        sweep = -((psi + math.pi - a_end) % (2 * math.pi))
        return _join(
            [
                (*_arc((0.0, R), R, -0.5 * math.pi, psi + 0.5 * math.pi, True, step), 1),
                (*_arc((xc, 0.5 * w), R, psi + math.pi, sweep, True, step), 1),
                (*_arc((0.0, w - R), R, -psi, 0.5 * math.pi + psi, True, step), 1),
            ]
        )
    # three_point: L+ R- L+
    alpha = math.acos((2.0 - w / R) / 4.0)
    ca, sa = math.cos(alpha), math.sin(alpha)
    return _join(
        [
            (*_arc((0.0, R), R, -0.5 * math.pi, alpha, True, step), 1),
            (
                *_arc(
                    (2 * R * sa, R * (1 - 2 * ca)),
                    R,
                    0.5 * math.pi + alpha,
                    math.pi - 2 * alpha,
                    False,
                    step,
                ),
                -1,
            ),
            (*_arc((0.0, R * (1 - 4 * ca)), R, 0.5 * math.pi - alpha, alpha, True, step), 1),
        ]
    )


def footprint_corners(
    xy: FloatArray, yaw: FloatArray, length: float, width: float, pad: float = 0.0
) -> FloatArray:
    """(n, 4, 2) corners of the footprint (centred on each pose) grown by ``pad``."""
    hl, hw = 0.5 * length + pad, 0.5 * width + pad
    local = np.array([[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]])
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    x = xy[:, 0:1] + c * local[:, 0] - s * local[:, 1]
    y = xy[:, 1:2] + s * local[:, 0] + c * local[:, 1]
    return np.stack([x, y], axis=-1)


def footprint_hits(
    xy: FloatArray,
    yaw: FloatArray,
    length: float,
    width: float,
    pad: float,
    points: FloatArray,
    tree: cKDTree | None = None,
) -> IntArray:
    """Indices of ``points`` inside the footprint (grown by ``pad``) at any of the poses."""
    if len(points) == 0 or len(xy) == 0:
        return np.empty(0, np.int64)
    tree = tree if tree is not None else cKDTree(points)
    hl, hw = 0.5 * length + pad, 0.5 * width + pad
    near = tree.query_ball_point(xy, math.hypot(hl, hw))
    hit: set[int] = set()
    for k, idx in enumerate(near):
        if not idx:
            continue
        p = points[idx] - xy[k]
        c, s = math.cos(yaw[k]), math.sin(yaw[k])
        lx = p[:, 0] * c + p[:, 1] * s
        ly = -p[:, 0] * s + p[:, 1] * c
        inside = (np.abs(lx) <= hl) & (np.abs(ly) <= hw)
        hit.update(np.asarray(idx)[inside].tolist())
    return np.array(sorted(hit), np.int64)
