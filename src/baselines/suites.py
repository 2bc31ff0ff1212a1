"""Benchmark suites: the same held-out scenarios and seeds for every policy.

Evaluation seeds start at 10⁹ and scenario seeds are drawn from the hyperparameters' eval range,
disjoint from every training range (MetaDrive-style splits).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from scenario_gen import ScenarioError

EVAL_SEED = 1_000_000_000
ALL_OBS = ["gps", "imu", "odom", "route", "depth"]  # every policy finds its inputs


@dataclass(frozen=True)
class Case:
    group: str  # the scenario group a results row belongs to
    env_id: str
    scenario: str
    overrides: dict[str, Any] = field(default_factory=dict)
    config: dict[str, Any] = field(default_factory=dict)
    max_steps: int | None = None

    def env_kwargs(self) -> dict[str, Any]:
        kw: dict[str, Any] = {
            "scenario": self.scenario,
            "observations": ALL_OBS,
            "scenario_seed": EVAL_SEED,
        }
        if self.overrides:
            kw["scenario_overrides"] = self.overrides
        if self.config:
            kw["config"] = self.config
        return kw


PAPER_FIELD = {"field": {"width": 12.5, "length": 30.0}, "route": {"lanes": 2}}


def suite(name: str) -> list[Case]:
    """The cases of a suite, in a fixed order."""
    if name == "smoke":
        # A 14 m lane: long enough that the 0.3 m start offset and the 0.3 m success tolerance
        # leave a finished lane above 95 % completion; the slowest shipped controller (DWB,
        # ≈ 0.45 m/s) drives it in ≈ 650 steps.
        tiny = {
            "field": {"width": 6.0, "length": 18.0},
            "layout": {"headland": 1.5},
            "terrain": {"margin": 4.0},
        }
        return [Case("tiny", "AgriNav/FurrowFollow-v0", "default", tiny, max_steps=800)]
    if name == "paper":
        # The source paper's run: two lanes with a headland U-turn, RTK GNSS, depth camera,
        # early and intermediate corn, on the paper's P1 density (1 m rows).
        return [
            Case(
                f"corn-{label}",
                "AgriNav/FieldRoute-v0",
                "paper-p1",
                {**PAPER_FIELD, "crop": {"stage": stage}},
                {"gnss": {"mode": "rtk_fixed"}},
            )
            for label, stage in (("early", 1), ("intermediate", 3))
        ]
    if name == "growth":
        # Dense maize (0.18 m in the row) on the paper's 1 m rows: in 0.75 m rows a 0.62 m
        # Summit-XL touches stalks at 2 cm of error, and crop contact, not perception, would end
        # every episode. 1,500 steps leave the slowest controller time to finish a lane.
        return [
            Case(
                f"{h} m",
                "AgriNav/FurrowFollow-v0",
                "default",
                {"crop": {"stage": s}, "layout": {"row_spacing": 1.0}},
                max_steps=1500,
            )
            for s, h in ((1, 0.3), (2, 0.6), (3, 1.2), (4, 1.8), (5, 2.5))
        ]
    if name == "density":
        return [
            Case(
                p.upper(),
                "AgriNav/FurrowFollow-v0",
                f"paper-{p}",
                {"field": {"width": 20.0, "length": 30.0}},
            )
            for p in ("p1", "p2", "p3", "p4")
        ]
    if name == "terrain":
        return [
            Case("flat", "AgriNav/FurrowFollow-v0", "default"),
            Case("hillside", "AgriNav/FurrowFollow-v0", "hillside"),
        ]
    raise ScenarioError("--suite", name, f"allowed: one of {', '.join(SUITES)}")


SUITES = ("smoke", "paper", "growth", "density", "terrain")
