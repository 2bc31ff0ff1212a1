"""Intel RealSense D455: the facts the mesh camera is built from, and its stereo error model.

* Depth is measured from the **left imager** (the depth origin); the right imager sits
  B = 95 mm to its right along the optical x axis. Depth FOV 87° × 58° (datasheet). The
  848 × 480 mode's focal length follows from the horizontal FOV: fx = 424 / tan(43.5°)
  = 446.8 px (fy = 240 / tan(29°) = 433.0 px from the vertical one; calibrated units report
  fx = fy ≈ 427 px with a slightly wider FOV, so the nominal FOVs are good to a few %). A
  smaller image for RL (64 × 48 by default) is the same FOV with the focal length scaled per
  axis (fx = 446.8 · 64/848 = 33.7 px).
* Noise: σ_z = z² · s / (f · B), s ≈ 0.08 px subpixel, with **f the focal length of the
  sensor mode** (``camera.native_width``: 1280 × 720 by default, fx 674 px) — the disparity
  is measured in that mode's pixels; a smaller image for RL is resampled from that mode's
  depth and keeps its noise (at 64 × 48, fx 33.7 px, it would be 20 × larger).
* Pixels read 0 (invalid) where the stereo pair cannot match: nearer than ≈ 0.4 m, beyond 6 m,
  outside the right imager's field of view (the band on the image's left side at close range),
  and in the **occlusion shadow**: surface the left imager sees but the right one does not,
  which appears to the left of a foreground object.
* The colour camera (OV9782, 90° × 65° at 16:10, so 90° × 59.0° at 16:9) sits 59 mm from the
  depth origin towards the right imager: librealsense's "Extrinsic from Color to Depth" is
  (0.0592, 0.0000, −0.0003) m on a D455-family unit (the D555, same 95 mm module), the rotation
  within 0.1°. RGB is rendered from that pose.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from scenario_gen.arrays import FloatArray

from ..interface import CameraModel

BASELINE = 0.095  # m
DEPTH_HFOV_DEG, DEPTH_VFOV_DEG = 87.0, 58.0
REFERENCE_MODE = (848, 480)
COLOR_OFFSET = 0.059  # m along the baseline, towards the right imager
COLOR_HFOV_DEG = 90.0
COLOR_VFOV_DEG = math.degrees(2 * math.atan(math.tan(math.radians(45.0)) * 480 / 848))  # 59.0°
#: occluders outside the left image (which could hide a point from the right imager alone) are
#: taken to be no nearer than the camera's near limit
NEAREST_OCCLUDER = 0.4


def focal_848() -> float:
    """Horizontal focal length of the 848 × 480 depth mode from the 87° HFOV, pixels."""
    return 0.5 * REFERENCE_MODE[0] / math.tan(math.radians(DEPTH_HFOV_DEG) / 2)


def noise_focal(native_width: int, hfov_deg: float = DEPTH_HFOV_DEG) -> float:
    """The focal length (pixels) the stereo noise is measured in: the sensor mode's,
    ``native_width`` wide. An output image smaller than that mode is resampled from its
    depth, so its pixels do not make the disparity coarser."""
    return 0.5 * native_width / math.tan(math.radians(hfov_deg) / 2)


def noise_sigma(
    z: FloatArray, fx: float, subpixel: float, baseline: float = BASELINE
) -> FloatArray:
    """Depth RMS error σ_z = z² · s / (fx · B) of a stereo pair at range z (m)."""
    out: FloatArray = np.asarray(z, np.float64) ** 2 * subpixel / (fx * baseline)
    return out


def offset_model(model: CameraModel, lateral: float) -> CameraModel:
    """The same camera moved ``lateral`` m to the right along its optical x axis."""
    right = model.rotation @ np.array([0.0, -lateral, 0.0])  # body frame: y is left
    pos = tuple(float(a + b) for a, b in zip(model.position, right, strict=True))
    return CameraModel(
        model.width,
        model.height,
        model.fx,
        model.fy,
        model.cx,
        model.cy,
        (pos[0], pos[1], pos[2]),
        model.pitch,
        model.min_range,
        model.max_range,
    )


def color_model(depth: CameraModel) -> CameraModel:
    """The colour camera for a depth camera: 59 mm to the right, 90° × 59° FOV, same size."""
    moved = offset_model(depth, COLOR_OFFSET)
    return CameraModel.from_fov(
        depth.width,
        depth.height,
        math.radians(COLOR_HFOV_DEG),
        math.radians(COLOR_VFOV_DEG),
        moved.position,
        depth.pitch,
        depth.min_range,
        depth.max_range,
    )


def outside_right_imager(
    u: FloatArray, z: FloatArray, fx: float, baseline: float
) -> NDArray[np.bool_]:
    """Pixels (column u, depth z) whose point falls left of the right imager's image."""
    with np.errstate(divide="ignore"):
        out: NDArray[np.bool_] = u - fx * baseline / z < -0.5
    return out


def shadow_candidates(z: FloatArray, fx: float, baseline: float) -> NDArray[np.bool_]:
    """Pixels of an (H, W) true-depth image that *may* be hidden from the right imager.

    The segment from a point P (column u, depth z) to the right imager projects into the left
    image on P's row, to its right, at columns u_s with 1/z_s = 1/z + (u_s − u)/(f·B). An
    occluder must be nearer than that segment somewhere, so P is a candidate only if a pixel
    u' > u (on its row or the rows beside it, half a pixel of slack) has
    1/z(u') ≥ 1/z + (u' − u − ½)/(f·B) — or if the segment leaves the image to the right before
    it comes nearer than ``NEAREST_OCCLUDER``. Candidates are then tested exactly by a ray.
    """
    w = z.shape[1]
    fb = fx * baseline
    col = np.arange(w, dtype=np.float64)
    with np.errstate(divide="ignore"):
        inv = np.where(np.isfinite(z) & (z > 0), 1.0 / z, 0.0)
    g = inv - col / fb
    suffix = np.maximum.accumulate(g[:, ::-1], axis=1)[:, ::-1]  # max over u' >= u
    after = np.full_like(g, -np.inf)
    after[:, :-1] = suffix[:, 1:]  # max over u' > u
    near = after.copy()
    near[1:] = np.maximum(near[1:], after[:-1])
    near[:-1] = np.maximum(near[:-1], after[1:])
    occluder = near >= inv - (col + 0.5) / fb
    leaves = inv + (w - 1 - col) / fb < 1.0 / NEAREST_OCCLUDER
    out: NDArray[np.bool_] = (occluder | leaves) & (inv > 0)
    return out
