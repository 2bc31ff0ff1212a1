"""Labels of one frame from the ground truth: crop rows, the lane, stems and weeds, projected
through the camera's public calibration (``CameraModel``) at the robot's true pose.

Camera body frame: x forward, y left, z up; pixel (u, v) = (cx − fx·y/x, cy − fy·z/x) and the
z-depth is x (interface.CameraModel). World → camera body: the base pose (true ENU position of
base_link and its rotation), then the mount (``position``, pitched by ``rotation``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from agrinav_gym.interface import CameraModel
from scenario_gen import Scenario
from scenario_gen.arrays import FloatArray

ROW_STEP = 0.25  # m between labelled points along a row line


def to_camera(points: FloatArray, pos: FloatArray, rot: FloatArray, cam: CameraModel) -> FloatArray:
    """(n, 3) ENU points in the camera body frame of ``cam`` on a base at ``pos``, ``rot``."""
    base = (np.asarray(points, np.float64) - pos) @ rot  # rot: base -> world
    out: FloatArray = (base - np.asarray(cam.position)) @ cam.rotation
    return out


def project(q: FloatArray, cam: CameraModel) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Pixel coordinates (n, 2) of camera-frame points and whether each lies in the image, in
    front of the camera and within its range."""
    x = np.where(q[:, 0] > 1e-6, q[:, 0], np.nan)
    uv = np.column_stack([cam.cx - cam.fx * q[:, 1] / x, cam.cy - cam.fy * q[:, 2] / x])
    inside = (
        (q[:, 0] >= cam.min_range)
        & (q[:, 0] <= cam.max_range)
        & (uv[:, 0] >= -0.5)
        & (uv[:, 0] <= cam.width - 0.5)
        & (uv[:, 1] >= -0.5)
        & (uv[:, 1] <= cam.height - 0.5)
    )
    return uv, np.asarray(inside & np.isfinite(uv).all(axis=1))


def _r(a: Any, nd: int = 4) -> Any:
    return np.round(np.asarray(a, np.float64), nd).tolist()


def lane_offset(scn: Scenario, xy: FloatArray, yaw: float) -> dict[str, Any]:
    """The lane the robot is in: its index, the signed lateral offset of base_link from the
    lane centre (m, left positive looking along the rows) and the heading offset (rad, to the
    row direction the robot faces)."""
    rows = scn.rows
    if rows.curve is None:
        s = float((xy - np.asarray(rows.origin)) @ rows.n)
        angle = rows.angle
    else:  # curved or contour rows: the offset from their curve, their local direction
        t_arr, s_arr = rows.to_rows(np.array([xy[0]]), np.array([xy[1]]))
        s, angle = float(s_arr[0]), float(rows.heading(t_arr)[0])
    centres = 0.5 * (rows.offsets[1:] + rows.offsets[:-1])
    if len(centres) == 0:
        return {"lane": -1, "lateral_offset": None, "heading_offset": None}
    k = int(np.argmin(np.abs(centres - s)))
    dh = (yaw - angle + math.pi / 2) % math.pi - math.pi / 2  # either direction of travel
    forward = abs((yaw - angle + math.pi) % (2 * math.pi) - math.pi) < math.pi / 2
    lateral = (s - centres[k]) * (1.0 if forward else -1.0)
    return {"lane": k, "lateral_offset": round(lateral, 4), "heading_offset": round(dh, 5)}


def row_lines(
    scn: Scenario, pos: FloatArray, rot: FloatArray, cams: dict[str, CameraModel], reach: float
) -> list[dict[str, Any]]:
    """Each crop row near the camera as a 3-D polyline in the depth camera's frame and its 2-D
    projection in every camera (NaN outside the image)."""
    rows = scn.rows
    out = []
    t_robot = (
        float((pos[:2] - np.asarray(rows.origin)) @ rows.u)
        if rows.curve is None
        else float(rows.to_rows(pos[:1], pos[1:2])[0][0])
    )
    for k, off in enumerate(rows.offsets):
        t0 = max(float(rows.starts[k]), t_robot - reach)
        t1 = min(float(rows.ends[k]), t_robot + reach)
        if t1 <= t0:
            continue
        t = np.arange(t0, t1 + 1e-9, ROW_STEP)
        x, y = rows.to_enu(t, np.full_like(t, float(off)))
        z = scn.terrain.height_at(x, y)
        pts = np.column_stack([x, y, z])
        entry: dict[str, Any] = {"row": k}
        any_seen = False
        for name, cam in cams.items():
            q = to_camera(pts, pos, rot, cam)
            uv, ok = project(q, cam)
            if name == "depth":
                entry["points_3d"] = _r(q)
            pts2 = _r(np.where(ok[:, None], uv, 0.0), 2)
            entry[f"points_2d_{name}"] = [p if v else None for p, v in zip(pts2, ok, strict=True)]
            any_seen |= bool(ok.any())
        if any_seen:
            out.append(entry)
    return out


def plants(
    scn: Scenario,
    pos: FloatArray,
    rot: FloatArray,
    cams: dict[str, CameraModel],
    instance: NDArray[np.int32] | None,
    reach: float,
) -> list[dict[str, Any]]:
    """Stems (crops) and weeds near the camera: base and top keypoints in 3-D (depth camera
    frame) and 2-D, instance id (= row of plants.csv), species, stage, height, and how many
    pixels of the instance image show the plant."""
    p = scn.plants
    near = np.flatnonzero(np.hypot(p.x - pos[0], p.y - pos[1]) < reach)
    if len(near) == 0:
        return []
    counts = (
        np.bincount(instance[instance >= 0].ravel(), minlength=len(p))
        if instance is not None
        else np.zeros(len(p), np.int64)
    )
    base = np.column_stack([p.x[near], p.y[near], p.z[near]])
    top = base + np.column_stack([np.zeros((len(near), 2)), p.height[near]])
    out = []
    proj: dict[str, tuple[FloatArray, FloatArray, NDArray[np.bool_], NDArray[np.bool_]]] = {}
    q_base = q_top = np.zeros((0, 3))
    for name, cam in cams.items():
        qb, qt = to_camera(base, pos, rot, cam), to_camera(top, pos, rot, cam)
        ub, okb = project(qb, cam)
        ut, okt = project(qt, cam)
        proj[name] = (ub, ut, okb, okt)
        if name == "depth":
            q_base, q_top = qb, qt
    # whole arrays rounded at once (the same np.round as _r, element by element it dominated)
    seen = counts[near] > 0
    for n in cams:
        seen |= proj[n][2] | proj[n][3]
    keep = np.flatnonzero(seen)
    ids = near[keep]
    b3, t3 = _r(q_base[keep]), _r(q_top[keep])
    two = {
        n: (_r(ub[keep], 2), _r(ut[keep], 2), okb[keep].tolist(), okt[keep].tolist())
        for n, (ub, ut, okb, okt) in proj.items()
    }
    species, stage = p.species[ids].tolist(), p.stage[ids].tolist()
    height, weed, pixels = p.height[ids].tolist(), p.is_weed[ids].tolist(), counts[ids].tolist()
    for j, i in enumerate(ids.tolist()):
        rec: dict[str, Any] = {
            "id": i,
            "species": str(species[j]),
            "stage": int(stage[j]),
            "height": round(float(height[j]), 4),
            "weed": bool(weed[j]),
            "base_3d": b3[j],
            "top_3d": t3[j],
            "visible_pixels": int(pixels[j]),
        }
        for name in cams:
            ub, ut, okb, okt = two[name]
            rec[f"base_2d_{name}"] = ub[j] if okb[j] else None
            rec[f"top_2d_{name}"] = ut[j] if okt[j] else None
        out.append(rec)
    return out


def camera_dict(cam: CameraModel) -> dict[str, Any]:
    """Intrinsics and the extrinsics in base_link (4×4, optical frame x right, y down, z fwd)."""
    return {
        "width": cam.width,
        "height": cam.height,
        "fx": round(cam.fx, 6),
        "fy": round(cam.fy, 6),
        "cx": cam.cx,
        "cy": cam.cy,
        "T_base_optical": _r(cam.T_base_optical, 6),
        "min_range": cam.min_range,
        "max_range": cam.max_range,
    }
