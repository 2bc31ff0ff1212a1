"""Rewards as a table of named terms, each with its weight and parameters in config.

A term is a frozen dataclass of parameters (declared with ``param``, so the config reference
and validation come from one place) whose ``__call__`` maps a ``StepContext`` to an
unweighted value; the env reports ``weight × value`` per term in ``info["rewards"]`` and
their sum as the reward. A new term is a new class decorated with ``@reward_term``: no shared
code changes. ``config={"reward": {"cte": {"weight": 2.0}}}`` reweights one term; unknown
terms and parameters are errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, TypeVar

from scenario_gen.errors import InputError
from scenario_gen.schema import from_mapping, param, to_mapping


@dataclass(frozen=True)
class StepContext:
    """What rewards and termination checks read about one control step (ground truth)."""

    dt: float
    v_max: float
    cte: float  # signed cross-track error of the true pose, m
    ds: float  # route arc length gained this step, m
    furrow: bool  # the nearest route segment is a furrow (not headland)
    corridor: float  # allowed |cte| here, m
    heading_error: float  # rad, wrapped
    tilt: float  # max(|roll|, |pitch|), rad
    new_crops: int  # crops first touched this step
    crops_hit: int  # distinct crops touched so far
    action: tuple[float, float]  # the clipped action
    prev_action: tuple[float, float]
    off_terrain: bool
    route_left: float  # route arc length still to go, m
    stalled: float = 0.0  # s since the robot last moved progress_radius from where it was
    termination: str | None = None  # name of the check that ended the episode, if any

    @property
    def success(self) -> bool:
        return self.termination == "success"


@dataclass(frozen=True)
class RewardTerm:
    name: ClassVar[str]
    weight: float = 1.0

    def __call__(self, c: StepContext) -> float:
        raise NotImplementedError


REWARD_TERMS: dict[str, type[RewardTerm]] = {}
T = TypeVar("T", bound=type[RewardTerm])


def reward_term(cls: T) -> T:
    """Register a term under ``cls.name`` (the key of its config section)."""
    REWARD_TERMS[cls.name] = cls
    return cls


@reward_term
@dataclass(frozen=True)
class Progress(RewardTerm):
    """Route progress per step, 1 at full speed. A quadratic cross-track penalty scaled by the
    corridor is flat near the line (5 cm off a 0.5 m corridor costs 1 % of this reward), so a
    learner has no reason to be precise; with ``cte_scale`` = k furrow progress is weighted by
    exp(−|cte| / (k · corridor)): distance only pays when driven on the line, and standing
    still never pays. Furrows only: weighted on the headland too, PPO never learned the U-turn
    (47 % completion after 800k steps)."""

    name: ClassVar[str] = "progress"
    weight: float = param(1.0, "× route progress per step at full speed", -100, 100)
    cte_scale: float | None = param(
        None,
        "in furrows, progress × exp(−|cte| / (cte_scale × corridor)) (null: unweighted)",
        0.001,
        10,
    )

    def __call__(self, c: StepContext) -> float:
        value = c.ds / (c.v_max * c.dt)
        if self.cte_scale is not None and c.furrow:
            value *= math.exp(-abs(c.cte) / (self.cte_scale * c.corridor))
        return value


@reward_term
@dataclass(frozen=True)
class CrossTrack(RewardTerm):
    name: ClassVar[str] = "cte"
    weight: float = param(1.0, "× −(cross-track error / corridor)²", -100, 100)

    def __call__(self, c: StepContext) -> float:
        return -((c.cte / c.corridor) ** 2)


@reward_term
@dataclass(frozen=True)
class Heading(RewardTerm):
    name: ClassVar[str] = "heading"
    weight: float = param(0.2, "× −|heading error| / π", -100, 100)

    def __call__(self, c: StepContext) -> float:
        return -abs(c.heading_error) / math.pi


@reward_term
@dataclass(frozen=True)
class CropContact(RewardTerm):
    name: ClassVar[str] = "crop_contact"
    weight: float = param(5.0, "× −(crops newly touched this step)", -1000, 1000)

    def __call__(self, c: StepContext) -> float:
        return -float(c.new_crops)


@reward_term
@dataclass(frozen=True)
class ActionRate(RewardTerm):
    name: ClassVar[str] = "action_rate"
    weight: float = param(0.05, "× −‖a_t − a_t−1‖²", -100, 100)

    def __call__(self, c: StepContext) -> float:
        (a0, a1), (b0, b1) = c.action, c.prev_action
        return -((a0 - b0) ** 2 + (a1 - b1) ** 2)


@reward_term
@dataclass(frozen=True)
class Terminal(RewardTerm):
    name: ClassVar[str] = "terminal"
    weight: float = param(10.0, "× +1 on success, −1 on any other termination", -1e4, 1e4)

    def __call__(self, c: StepContext) -> float:
        if c.termination is None:
            return 0.0
        return 1.0 if c.success else -1.0


def build_reward_terms(data: Any) -> dict[str, RewardTerm]:
    """Every registered term, with the overrides in ``data`` (``{term: {param: value}}``)."""
    data = {} if data is None else data
    if not isinstance(data, dict):
        raise InputError("config.reward", data, "allowed: a mapping {term: {weight: ...}}")
    unknown = sorted(set(data) - set(REWARD_TERMS))
    if unknown:
        raise InputError(
            f"config.reward.{unknown[0]}",
            data[unknown[0]],
            f"unknown reward term; allowed: {', '.join(REWARD_TERMS)}",
        )
    # only an absent or null term takes the defaults: 0, False or [] is a mistake to name (a
    # term is switched off by {weight: 0}), not a silent weight of 1
    return {
        name: from_mapping(
            cls, {} if data.get(name) is None else data[name], f"config.reward.{name}."
        )
        for name, cls in REWARD_TERMS.items()
    }


def reward_terms_to_dict(terms: dict[str, RewardTerm]) -> dict[str, Any]:
    return {name: to_mapping(t) for name, t in terms.items()}


def evaluate(terms: dict[str, RewardTerm], c: StepContext) -> dict[str, float]:
    """Weighted value of every term (zero-weight terms are skipped but still reported)."""
    return {name: (t.weight * t(c) if t.weight else 0.0) for name, t in terms.items()}
