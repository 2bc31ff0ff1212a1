"""Where the ground under a tyre gives way: measured soils and their bearing capacity.

The tyre model's ground is rigid unless ``soil.cohesion_kpa`` is set. Then each disc of the
tread (``soil.contact_width``) bears at most what the soil under it can: the ultimate bearing
capacity of a shallow footing — the disc's share of a contact patch ``contact_length`` long and
``contact_width`` wide — on ground sloping as the surface under the disc does:

    q_u = c·N_c·s_c·g_c + ½·γ·B·N_γ·s_γ·g_γ        (surface footing: no overburden term)

with the bearing-capacity factors of Prandtl (N_c, N_q) and Vesić (N_γ), De Beer's shape
factors and Vesić's ground-inclination factors (Vesić 1975, "Bearing capacity of shallow
foundations", in Winterkorn & Fang, *Foundation Engineering Handbook*, ch. 3):

    N_q = e^(π tan φ) tan²(45° + φ/2),  N_c = (N_q − 1) cot φ,  N_γ = 2 (N_q + 1) tan φ
    s_c = 1 + (B/L)(N_q/N_c),  s_γ = 1 − 0.4 B/L       (B ≤ L the patch's sides)
    g_q = g_γ = (1 − tan β)²,  g_c = g_q − (1 − g_q)/(N_c tan φ)

A disc pressed harder than that sinks into the ridge instead of being pushed back by it: the
soil flows, and the tyre model cuts its own copy of the height grid down under the disc (a
rigid–plastic ground with memory: the next wheel meets the rut; ``sim.tyres``). The slope a
capacity reads is the field's, or a cut bench's where flatter, so a rut's wall stands. The
cohesion and friction angle of real soils are in ``WONG_SOILS``; docs/physics.md, "Ridges that
yield", has what they do to the ridges' guidance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ..config import SoilConfig

G = 9.81


@dataclass(frozen=True)
class MeasuredSoil:
    """Bekker's pressure–sinkage and Mohr–Coulomb's strength parameters of one soil."""

    n: float  # sinkage exponent
    k_c: float  # cohesive modulus, kN/m^(n+1)
    k_phi: float  # frictional modulus, kN/m^(n+2)
    cohesion_kpa: float
    friction_angle_deg: float


#: Measured terrain values (Wong, J. Y., *Theory of Ground Vehicles*, 4th ed., Wiley 2008,
#: Table 2.3; moisture content in the name). Agricultural soils only (the table's snows left out).
WONG_SOILS: dict[str, MeasuredSoil] = {
    "dry sand (LLL)": MeasuredSoil(1.1, 0.99, 1528.43, 1.04, 28.0),
    "sandy loam 15 % (LLL)": MeasuredSoil(0.7, 5.27, 1515.04, 1.72, 29.0),
    "sandy loam 22 % (LLL)": MeasuredSoil(0.2, 2.56, 43.12, 1.38, 38.0),
    "sandy loam 11 % (Michigan)": MeasuredSoil(0.9, 52.53, 1127.97, 4.83, 20.0),
    "sandy loam 23 % (Michigan)": MeasuredSoil(0.4, 11.42, 808.96, 9.65, 35.0),
    "sandy loam 26 % (Hanamoto)": MeasuredSoil(0.3, 2.79, 141.11, 13.79, 22.0),
    "sandy loam 32 % (Hanamoto)": MeasuredSoil(0.5, 0.77, 51.91, 5.17, 11.0),
    "clayey soil 38 % (Thailand)": MeasuredSoil(0.5, 13.19, 692.15, 4.14, 13.0),
    "clayey soil 55 % (Thailand)": MeasuredSoil(0.7, 16.03, 1262.53, 2.07, 10.0),
    "heavy clay 25 % (WES)": MeasuredSoil(0.13, 12.70, 1555.95, 68.95, 34.0),
    "heavy clay 40 % (WES)": MeasuredSoil(0.11, 1.84, 103.27, 20.69, 6.0),
    "lean clay 22 % (WES)": MeasuredSoil(0.2, 16.43, 1724.69, 68.95, 20.0),
    "lean clay 32 % (WES)": MeasuredSoil(0.15, 1.52, 119.61, 13.79, 11.0),
    "LETE sand": MeasuredSoil(0.79, 102.0, 5301.0, 1.3, 31.1),
    "upland sandy loam 51 %": MeasuredSoil(1.10, 74.6, 2080.0, 3.3, 33.7),
    "Rubicon sandy loam 43 %": MeasuredSoil(0.66, 6.9, 752.0, 3.7, 29.8),
    "North Gower clayey loam 46 %": MeasuredSoil(0.73, 41.6, 2471.0, 6.1, 26.6),
    "Grenville loam 24 %": MeasuredSoil(1.01, 0.06, 5880.0, 3.1, 29.8),
}


def bearing_factors(friction_angle_deg: float) -> tuple[float, float, float]:
    """(N_c, N_q, N_γ) of a friction angle φ > 0 (Prandtl–Reissner; Vesić's N_γ)."""
    t = math.tan(math.radians(friction_angle_deg))
    nq = math.exp(math.pi * t) * math.tan(math.radians(45.0 + 0.5 * friction_angle_deg)) ** 2
    return (nq - 1.0) / t, nq, 2.0 * (nq + 1.0) * t


@dataclass(frozen=True)
class DiscBearing:
    """One tread disc's force limit on a surface of slope tan β (``limit``): the same three
    numbers the compiled kernel reads, so both compute the same bits."""

    cohesive: float  # c·N_c·s_c·A, N
    weight: float  # ½·γ·B·N_γ·s_γ·A, N
    k3: float  # 1/(N_c tan φ)

    def limit(self, tan_beta: float) -> float:
        gq = (1.0 - tan_beta) * (1.0 - tan_beta) if tan_beta < 1.0 else 0.0
        return max(self.cohesive * (gq - (1.0 - gq) * self.k3) + self.weight * gq, 0.0)


def disc_bearing(soil: SoilConfig, slices: int) -> DiscBearing | None:
    """The bearing limit of each of ``slices`` discs across a ``soil.contact_width`` tread on a
    ``soil.contact_length`` patch (None: a rigid ground)."""
    if soil.cohesion_kpa is None or slices <= 0:
        return None
    nc, nq, ng = bearing_factors(soil.friction_angle_deg)
    side_b = min(soil.contact_length, soil.contact_width)
    side_l = max(soil.contact_length, soil.contact_width)
    ratio = side_b / side_l
    area = soil.contact_length * soil.contact_width / slices
    gamma = soil.bulk_density * 1000.0 * G  # N/m³
    return DiscBearing(
        cohesive=soil.cohesion_kpa * 1000.0 * nc * (1.0 + ratio * nq / nc) * area,
        weight=0.5 * gamma * side_b * ng * (1.0 - 0.4 * ratio) * area,
        k3=1.0 / (nc * math.tan(math.radians(soil.friction_angle_deg))),
    )


def bearing_capacity(soil: SoilConfig, slope_deg: float = 0.0) -> float:
    """Ultimate bearing pressure (kPa) of the whole contact patch on ground sloping at
    ``slope_deg`` (the same formula the discs use)."""
    b = disc_bearing(soil, 1)
    if b is None:
        raise ValueError("bearing_capacity needs soil.cohesion_kpa and soil.contact_width > 0")
    area = soil.contact_length * soil.contact_width
    return b.limit(math.tan(math.radians(slope_deg))) / area / 1000.0


def measured_strength(name: str) -> dict[str, float]:
    """One of Wong's soils as ``soil`` config values: its cohesion and friction angle."""
    s = WONG_SOILS[name]
    return {"cohesion_kpa": s.cohesion_kpa, "friction_angle_deg": s.friction_angle_deg}


def with_measured_soil(base: SoilConfig, name: str) -> SoilConfig:
    """``base`` on one of Wong's soils."""
    return replace(base, **measured_strength(name))


def bekker_sinkage(soil: MeasuredSoil, load: float, radius: float, width: float) -> float:
    """Static sinkage (m) of a rigid wheel under ``load`` N on a level soil (Bekker's
    pressure–sinkage p = (k_c/b + k_φ) zⁿ over the wheel's front arc, the arc's integral exact:
    W = b k √(2r) z^(n+½) ∫₀¹ (1 − u²)ⁿ du)."""
    k = (soil.k_c / width + soil.k_phi) * 1000.0
    arc = 0.5 * math.sqrt(math.pi) * math.gamma(soil.n + 1.0) / math.gamma(soil.n + 1.5)
    return (load / (width * k * math.sqrt(2.0 * radius) * arc)) ** (1.0 / (soil.n + 0.5))
