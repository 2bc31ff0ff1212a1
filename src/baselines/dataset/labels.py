"""Labels of one frame from the ground truth: crop rows, the lane, stems and weeds, obstacles,
projected through the camera's public calibration (``CameraModel``) at the robot's true pose.

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
from agrinav_gym.render.classes import CROP, OBSTACLE, WEED
from agrinav_gym.render.plant_meshes import rotation_rpy
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


def _pixel_counts(
    instance: NDArray[np.int32] | None,
    semantic: NDArray[np.uint8] | None,
    classes: tuple[int, ...],
    n: int,
) -> NDArray[np.int64]:
    """Pixels of each instance id 0..n-1 among the pixels of ``classes`` (an instance id is a
    row of plants.csv on crop and weed pixels, of obstacles.csv on obstacle pixels; without a
    ``semantic`` image every id counts)."""
    if instance is None:
        return np.zeros(n, np.int64)
    sel = instance >= 0
    if semantic is not None:
        sel &= np.isin(semantic, classes)
    return np.bincount(instance[sel].ravel(), minlength=n)[:n]


def plants(
    scn: Scenario,
    pos: FloatArray,
    rot: FloatArray,
    cams: dict[str, CameraModel],
    instance: NDArray[np.int32] | None,
    reach: float,
    semantic: NDArray[np.uint8] | None = None,
) -> list[dict[str, Any]]:
    """Stems (crops) and weeds near the camera: base and top keypoints (the top on the plant's
    axis, which leans with the ground) in 3-D (depth camera frame) and 2-D, instance id (= row
    of plants.csv), species, stage, height, and how many pixels of the instance image show the
    plant (its crop and weed pixels where ``semantic`` is given: an obstacle's pixels carry an
    obstacle's id)."""
    p = scn.plants
    near = np.flatnonzero(np.hypot(p.x - pos[0], p.y - pos[1]) < reach)
    if len(near) == 0:
        return []
    counts = _pixel_counts(instance, semantic, (CROP, WEED), len(p))
    base = np.column_stack([p.x[near], p.y[near], p.z[near]])
    # along the plant's own axis: it stands on the ground's normal (plants.csv roll, pitch),
    # as the cameras draw it, not straight up (21 cm apart at the top on a 10° slope)
    axis = rotation_rpy(p.roll[near], p.pitch[near], p.yaw[near])[:, :, 2]
    top = base + axis * p.height[near][:, None]
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


#: the 8 corners of a unit box about its centre (x fastest), as ``box_3d``'s corners list them
_UNIT_BOX = np.array([[sx, sy, sz] for sz in (-1, 1) for sy in (-1, 1) for sx in (-1, 1)], float)
#: m: mesh points nearer to the camera plane than this are clipped off before projecting
_NEAR = 1e-3


def bbox_2d(q: FloatArray, faces: NDArray[np.int64], cam: CameraModel) -> list[float] | None:
    """[u0, v0, u1, v1]: the pixel rectangle a closed mesh (vertices ``q`` in the camera body
    frame) projects to, clipped to the image (pixel centres at integers, edges at ±0.5), None
    where none of it is in front of the camera or the rectangle misses the image. Parts behind
    the camera are cut off at its plane (the edges crossing it give the extra points)."""
    front = q[:, 0] > _NEAR
    if not front.any():
        return None
    pts = [q[front]]
    if not front.all():  # where the mesh's edges cross the clipping plane
        a = q[faces.ravel()]
        b = q[np.roll(faces, -1, axis=1).ravel()]
        cross = (a[:, 0] > _NEAR) != (b[:, 0] > _NEAR)
        a, b = a[cross], b[cross]
        s = (_NEAR - a[:, 0]) / (b[:, 0] - a[:, 0])
        pts.append(a + s[:, None] * (b - a))
    p = np.concatenate(pts)
    u = cam.cx - cam.fx * p[:, 1] / p[:, 0]
    v = cam.cy - cam.fy * p[:, 2] / p[:, 0]
    u0, u1 = max(float(u.min()), -0.5), min(float(u.max()), cam.width - 0.5)
    v0, v1 = max(float(v.min()), -0.5), min(float(v.max()), cam.height - 0.5)
    if u0 >= u1 or v0 >= v1:
        return None
    return [round(u0, 2), round(v0, 2), round(u1, 2), round(v1, 2)]


def obstacles(
    scn: Scenario,
    pos: FloatArray,
    rot: FloatArray,
    cams: dict[str, CameraModel],
    semantic: NDArray[np.uint8] | None,
    instance: NDArray[np.int32] | None,
    reach: float,
) -> list[dict[str, Any]]:
    """The obstacles (stones, litter, fallen stalks) near the camera that are in view — their
    mesh projects into a camera's image within its range — or show in the instance image:
    id (= row of obstacles.csv), kind, the 3-D box in the depth camera's body frame
    (``centre``; ``size`` = length, width, height; ``yaw``: the box's heading about the
    vertical relative to the camera's, both taken in the horizontal plane — the box is the
    obstacle's own, tilted with the ground it lies on, so these three make an upright box on
    level ground only; and its 8 ``corners``, exact whatever the ground's slope and the
    camera's pitch), the 2-D bounding box of its mesh in each camera
    (``bbox_2d_<camera>``: [u0, v0, u1, v1] pixels, None outside the image) and
    ``visible_pixels``: its obstacle pixels in the depth camera's semantic and instance
    images."""
    obs = scn.obstacles
    if len(obs) == 0:
        return []
    half = 0.5 * np.hypot(obs.length, obs.width)
    near = np.flatnonzero(np.hypot(obs.x - pos[0], obs.y - pos[1]) < reach + half)
    if len(near) == 0:
        return []
    counts = _pixel_counts(instance, semantic, (OBSTACLE,), len(obs))
    depth_cam = cams["depth"]
    ax = rot @ depth_cam.rotation[:, 0]  # the camera's optical axis in ENU
    heading = math.atan2(float(ax[1]), float(ax[0]))
    out = []
    for i in near.tolist():
        v, f = obs.mesh(i)
        boxes: dict[str, list[float] | None] = {}
        in_view = False
        for name, cam in cams.items():
            q = to_camera(v, pos, rot, cam)
            box = bbox_2d(q, f, cam)
            boxes[name] = box
            ahead = q[:, 0]
            in_range = ahead.max() >= cam.min_range and ahead.min() <= cam.max_range
            in_view |= box is not None and bool(in_range)
        if not in_view and counts[i] == 0:
            continue
        r = obs.rotation(i)
        size = np.array([obs.length[i], obs.width[i], obs.height[i]])
        centre = np.array([obs.x[i], obs.y[i], obs.z[i]]) + r @ np.array([0, 0, 0.5 * size[2]])
        corners = centre + (_UNIT_BOX * (0.5 * size)) @ r.T
        yaw = math.atan2(float(r[1, 0]), float(r[0, 0])) - heading
        rec: dict[str, Any] = {
            "id": i,
            "kind": str(obs.kind[i]),
            "box_3d": {
                "centre": _r(to_camera(centre[None, :], pos, rot, depth_cam)[0]),
                "size": _r(size),
                "yaw": round((yaw + math.pi) % (2 * math.pi) - math.pi, 5),
                "corners": _r(to_camera(corners, pos, rot, depth_cam)),
            },
            "visible_pixels": int(counts[i]),
        }
        for name in cams:
            rec[f"bbox_2d_{name}"] = boxes[name]
        out.append(rec)
    return out


def camera_reach(cams: dict[str, CameraModel]) -> float:
    """How far from base_link, horizontally, any camera's image reaches within its range: its
    corner rays out to ``max_range`` along the optical axis, plus where it sits (a bound for
    any pitch). Labels within it cover every plant an image can show."""
    out = 0.0
    for cam in cams.values():
        tx, ty = (cam.width / 2) / cam.fx, (cam.height / 2) / cam.fy
        offset = float(np.hypot(*np.asarray(cam.T_base_optical)[:2, 3]))
        out = max(out, cam.max_range * math.sqrt(1.0 + tx * tx + ty * ty) + offset)
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
