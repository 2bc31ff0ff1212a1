"""How much a ridged seedbed steers the simulated robot: the turn it lets through.

A skid-steer driving along sine ridges (rows on the crests, the robot's wheels on the flanks
of the furrow between them) is commanded a gentle turn at speed; the measure is the yaw rate
it achieves over the one it achieves on level ground under the same command. 1 means the
ground does not steer; 0 means the furrow holds the robot like a rail (a constant command then
follows the lane by itself, and a benchmark on such ground measures the terrain, not the
controller). ``docs/physics.md`` has the curve over ridge height, its sensitivity to the soil
values nobody measured for this robot, and the curve on measured soils whose ridges yield.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from scenario_gen import Terrain

from ..config import RobotConfig, SoilConfig
from .terramechanics import WONG_SOILS, with_measured_soil
from .world import World

#: The gentle turn the ridge test commands: 0.2 rad/s at 1 m/s (a 5 m radius).
TURN = (1.0, 0.2)


def ridged_plane(depth: float, row_spacing: float = 1.0, size: float = 30.0) -> Terrain:
    """Level ground with sine ridges of ``depth`` (crest to trough) along x, rows on the crests
    at y = k·row_spacing, furrow bottoms between them (as ``scenario_gen.furrows`` lays them)."""
    sp = 0.05
    n = round(size / sp) + 1
    y = -0.5 * size + sp * np.arange(n)
    profile = 0.5 * depth * np.cos(2.0 * math.pi * y / row_spacing)
    return Terrain(np.tile(profile[:, None], (1, n)), -0.5 * size, -0.5 * size, sp)


def achieved_yaw_rate(
    terrain: Terrain, soil: SoilConfig, y0: float, seconds: float = 4.0, settle: float = 1.5
) -> float:
    """Mean true yaw rate (rad/s) under ``TURN`` after ``settle`` s, starting at rest at
    (−10, y0) heading along the rows."""
    world = World(RobotConfig(), soil)
    try:
        world.load(terrain)
        world.place_robot(-10.0, y0, 0.0, terrain)
        world.drive(0.0, 0.0)
        world.step(world.cfg.physics_hz // 2)
        sub = world.cfg.physics_hz // world.cfg.control_hz
        rates = []
        for k in range(round(seconds * world.cfg.control_hz)):
            world.drive(*TURN)
            world.step(sub)
            if k >= settle * world.cfg.control_hz:
                rates.append(float(world.state().ang[2]))
        return float(np.mean(rates))
    finally:
        world.close()


def turn_ratios(
    depths: list[float], soil: SoilConfig | None = None, row_spacing: float = 1.0
) -> list[float]:
    """Yaw rate achieved in a furrow of ridges of each of ``depths`` over the rate on level
    ground (driven once for them all)."""
    soil = soil or SoilConfig()
    lane = 0.5 * row_spacing  # a furrow bottom: the lane centre
    level = achieved_yaw_rate(ridged_plane(0.0, row_spacing), soil, lane)
    return [achieved_yaw_rate(ridged_plane(d, row_spacing), soil, lane) / level for d in depths]


def turn_ratio(depth: float, soil: SoilConfig | None = None, row_spacing: float = 1.0) -> float:
    """``turn_ratios`` of one ridge height."""
    return turn_ratios([depth], soil, row_spacing)[0]


def sensitivity(depths: list[float], soils: dict[str, SoilConfig]) -> dict[str, list[float]]:
    """``turn_ratios`` over ``depths`` for each named soil (the curve and its sensitivity)."""
    return {name: turn_ratios(depths, soil) for name, soil in soils.items()}


def soil_variants(base: SoilConfig | None = None) -> dict[str, SoilConfig]:
    """The assumed soil values at both ends of their plausible ranges (SoilConfig's docs),
    and the tyre's contact across its tread (the default is a point)."""
    b = base or SoilConfig()
    return {
        "default": b,
        "μ 0.4": replace(b, friction=0.4),
        "μ 0.8": replace(b, friction=0.8),
        "k_z 2·10⁴ N/m": replace(b, vertical_stiffness=2.0e4),
        "k_z 1.5·10⁵ N/m": replace(b, vertical_stiffness=1.5e5),
        "K 0.01 m": replace(b, shear_modulus=0.01),
        "K 0.05 m": replace(b, shear_modulus=0.05),
        # the tread: the Summit-XL's 0.15 m (its URDF's wheel) and a wider field tyre
        "tread 0.15 m": replace(b, contact_width=0.15),
        "tread 0.25 m": replace(b, contact_width=0.25),
    }


#: the Summit-XL's tread, on which a ground can yield (``soil.cohesion_kpa``)
SUMMIT_TREAD = 0.15
#: the soil the yield model's own assumed values are swept on (a mid-strength sandy loam)
YIELD_REFERENCE = "sandy loam 15 % (LLL)"


def measured_soils(base: SoilConfig | None = None) -> dict[str, SoilConfig]:
    """Every soil of Wong's table under the Summit-XL's tread, its ridges yielding."""
    b = replace(base or SoilConfig(), contact_width=SUMMIT_TREAD)
    return {name: with_measured_soil(b, name) for name in WONG_SOILS}


def yield_variants(base: SoilConfig | None = None) -> dict[str, SoilConfig]:
    """The yield model's assumed values at both ends of their ranges, on ``YIELD_REFERENCE``:
    the contact patch's length (also the shear model's relaxation length) and the tilled
    ground's bulk density."""
    ref = measured_soils(base)[YIELD_REFERENCE]
    return {
        YIELD_REFERENCE: ref,
        "patch 0.05 m": replace(ref, contact_length=0.05),
        "patch 0.2 m": replace(ref, contact_length=0.2),
        "bulk density 1.1 t/m³": replace(ref, bulk_density=1.1),
        "bulk density 1.6 t/m³": replace(ref, bulk_density=1.6),
    }
