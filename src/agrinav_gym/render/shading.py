"""Colour for ray-cast hits: Lambert shading under a sun, a procedural soil texture, a sky.

Soil albedo is the scenario's soil colour modulated by a periodic 1/f noise texture (clods and
crumbs: 1 cm texels over 5.12 m, a second octave 7.3× coarser and turned by 37° so the period
does not show); its normal is the bilinear terrain's, so ridges and furrows read in the light.
Plant faces take the prototype's face colour, or its texture at the hit's interpolated UV.
Faces are lit from both sides (leaves are thin). Rays that leave the loaded tiles fade into a
haze over the horizon colour.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from scenario_gen.arrays import U8, FloatArray

SOIL_RGB = (0.45, 0.33, 0.22)  # default soil colour of renders and the cameras' RGB
AMBIENT = 0.35
SKY_HORIZON = np.array([0.80, 0.86, 0.93])
SKY_ZENITH = np.array([0.42, 0.62, 0.88])
TEXEL = 0.01  # m
TEX_SIZE = 512


#: The sun before an episode sets its own (azimuth 33.7° from east, elevation 68.8°).
DEFAULT_LIGHT = np.array([0.3, 0.2, 0.93]) / np.linalg.norm([0.3, 0.2, 0.93])


class Lighting:
    """The soil colour and the sun direction a camera shades with (both cameras share it)."""

    soil_rgb: FloatArray
    light: FloatArray

    def _init_lighting(self, soil_rgb: Any) -> None:
        self.soil_rgb = np.array(soil_rgb, np.float64)
        self.light = DEFAULT_LIGHT.copy()

    def set_lighting(self, soil_rgb: Any | None, azimuth_deg: float, elevation_deg: float) -> None:
        """Soil colour (RGB in [0, 1]; None keeps the current one) and the sun direction."""
        if soil_rgb is not None:
            self.soil_rgb = np.clip(np.asarray(soil_rgb, float), 0, 1)
        az, el = math.radians(float(azimuth_deg)), math.radians(float(elevation_deg))
        self.light = np.array(
            [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)]
        )


@lru_cache(maxsize=4)
def soil_texture(seed: int = 0) -> NDArray[np.float32]:
    """A periodic (TEX_SIZE²) noise field with a 1/f spectrum, scaled to mean 1, ±≈25 %."""
    rng = np.random.default_rng(seed)
    white = rng.standard_normal((TEX_SIZE, TEX_SIZE))
    f = np.fft.fftfreq(TEX_SIZE)
    k = np.hypot(f[:, None], f[None, :])
    k[0, 0] = 1.0
    field = np.fft.ifft2(np.fft.fft2(white) / k).real
    field = (field - field.mean()) / field.std()
    return (1.0 + 0.12 * np.clip(field, -2.5, 2.5)).astype(np.float32)


def soil_albedo(x: FloatArray, y: FloatArray, soil_rgb: FloatArray, seed: int = 0) -> FloatArray:
    tex = soil_texture(seed)
    n = TEX_SIZE
    i1 = np.floor(x / TEXEL).astype(np.int64) % n
    j1 = np.floor(y / TEXEL).astype(np.int64) % n
    c, s = math.cos(0.65), math.sin(0.65)
    xr, yr = c * x - s * y, s * x + c * y
    i2 = np.floor(xr / (7.3 * TEXEL)).astype(np.int64) % n
    j2 = np.floor(yr / (7.3 * TEXEL)).astype(np.int64) % n
    m = tex[j1, i1] * tex[j2, i2]
    out: FloatArray = np.asarray(soil_rgb, np.float64)[None, :] * m[:, None]
    return out


def sky(d: FloatArray) -> FloatArray:
    """Sky colour along unit directions d (n, 3): horizon to zenith."""
    a = np.clip(d[:, 2], 0.0, 1.0)[:, None] ** 0.6
    out: FloatArray = SKY_HORIZON * (1 - a) + SKY_ZENITH * a
    return out


def lambert(albedo: FloatArray, normal: FloatArray, d: FloatArray, light: FloatArray) -> FloatArray:
    """Two-sided Lambert: the normal turned towards the viewer, ambient + diffuse sun."""
    n = normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    flip = np.sign(-(n * d).sum(axis=1))
    n = n * np.where(flip == 0, 1.0, flip)[:, None]
    cos = n[:, 0] * light[0] + n[:, 1] * light[1] + n[:, 2] * light[2]  # no BLAS for (n, 3)
    lit = AMBIENT + (1.0 - AMBIENT) * np.clip(cos, 0.0, 1.0)
    out: FloatArray = albedo * lit[:, None]
    return out


def haze(rgb: FloatArray, distance: FloatArray, far: float) -> FloatArray:
    """Aerial perspective: blend towards the horizon colour over ``far`` metres."""
    a = np.clip(distance / (3.0 * far), 0.0, 0.6)[:, None]
    out: FloatArray = rgb * (1 - a) + SKY_HORIZON * a
    return out


def to_u8(rgb: FloatArray) -> U8:
    out: U8 = (np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    return out
