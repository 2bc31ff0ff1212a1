"""The perception dataset spec: what is randomized, how frames are taken, how they are stored.

Every field is declared with ``scenario_gen.schema.param`` (unknown keys and out-of-range
values are ``InputError``s naming the field); ``randomize`` is checked by the env's own
``Randomization`` when the spec is loaded, before anything is written.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from scenario_gen.crops import CROP_SPECIES
from scenario_gen.errors import InputError
from scenario_gen.schema import from_mapping, load_yaml, param, to_mapping

#: Bumped when a frame's files or label fields change meaning (docs/datasets.md).
#: 2: splits (train/validation/test fields by scenario seed range); 3: obstacles (semantic
#: class 5, their instance ids, the labels' ``obstacles``); 4: a plant's top keypoint on its
#: axis (leaning with the ground, as drawn; it was straight above the base), labels as far as
#: a camera sees by default (``label_range`` null)
SCHEMA_VERSION = 4

#: The default domain randomization: scenario and env keys, over ranges the generator accepts.
DEFAULT_RANDOMIZE: dict[str, Any] = {
    "crop.species": {"choices": list(CROP_SPECIES)},
    "crop.stage": [1, 3],
    "layout.row_spacing": [0.9, 1.2],
    "layout.plant_spacing": [0.15, 0.35],
    "layout.jitter_lateral": [0.0, 0.03],
    "layout.gap_prob": [0.0, 0.1],
    "layout.weed_density": [0.0, 2.0],
    "layout.row_angle_deg": [-180.0, 180.0],
    "terrain.site": {"choices": ["flattest", "steepest"]},
    "terrain.max_slope_deg": [2.0, 10.0],
    "furrows.enabled": {"choices": [False, True]},
    "furrows.depth": [0.0, 0.15],
    "lighting.soil_rgb": [[0.25, 0.18, 0.1], [0.6, 0.48, 0.35]],
    "lighting.sun_azimuth_deg": [0.0, 360.0],
    "lighting.sun_elevation_deg": [20.0, 80.0],
}


@dataclass(frozen=True)
class PerceptionSpec:
    """One perception dataset: frames from randomized fields, seen by a robot that errs."""

    env: str = param("AgriNav/FurrowFollow-v3", "env id the frames come from")
    preset: str = param("default", "scenario preset the randomization starts from")
    field_length: float = param(
        14.0, "rows length of each field, m (short fields: many fields)", 4, 200
    )
    randomize: dict[str, Any] = param(
        DEFAULT_RANDOMIZE, "env randomize mapping (scenario keys and env keys), re-drawn per field"
    )
    width: int = param(848, "image width, pixels (D455 depth mode 848×480)", 16, 1280)
    height: int = param(480, "image height, pixels", 12, 800)
    frames_per_shard: int = param(32, "frames per tar shard (one field per shard)", 1, 10_000)
    frame_every: int = param(5, "control steps between frames (20 Hz control: 4 frames/s)", 1, 100)
    policy: str = param("rpp", "controller driving the robot (dwb, rpp, depth, ppo:PATH)")
    steer_noise: float = param(
        0.35, "std of the yaw-rate perturbation added to the policy, rad/s", 0, 3
    )
    steer_noise_tau: float = param(1.5, "correlation time of the perturbation, s", 0.05, 60)
    camera_height: tuple[float, float] = param(
        (0.45, 0.65), "range of the camera's height above base_link per field, m", 0.1, 3
    )
    camera_pitch_deg: tuple[float, float] = param(
        (15.0, 35.0), "range of the camera's pitch below the horizon per field", -30, 90
    )
    label_range: float | None = param(
        None,
        "plants, obstacles and row points farther than this from base_link (horizontally) are "
        "not labelled, m; null: as far as a camera's image reaches within its range (the "
        "D455's corner rays: about 9.4 m)",
        1,
        50,
    )

    def digest(self) -> str:
        """A fingerprint of the spec: a folder holds one spec's shards."""
        text = json.dumps(to_mapping(self), sort_keys=True, default=list)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def load_spec(path: str | Path | None, overrides: dict[str, Any] | None = None) -> PerceptionSpec:
    """The spec in ``path`` (YAML; None: the defaults) with ``overrides``, fully checked."""
    data: dict[str, Any] = {}
    if path is not None:
        loaded = load_yaml(path, "--spec")
        if not isinstance(loaded, dict):
            raise InputError("--spec", str(path), "allowed: a YAML mapping of spec fields")
        data.update(loaded)
    data.update(overrides or {})
    spec: PerceptionSpec = from_mapping(PerceptionSpec, data, "spec.")
    from agrinav_gym import check_env_id

    check_env_id(spec.env, "spec.env")  # gym.make would import a ``module:`` named here
    if isinstance(spec.randomize, dict) and "field.length" in spec.randomize:
        # the env's draw would override spec.field_length, which the card and manifest state
        raise InputError(
            "spec.randomize",
            "field.length",
            "is set by spec.field_length (one length for every field, as the card states); "
            "allowed: spec.field_length",
        )
    for name in ("camera_height", "camera_pitch_deg"):
        lo, hi = getattr(spec, name)
        if lo > hi:
            raise InputError(f"spec.{name}", [lo, hi], "allowed: [low, high] with low <= high")
    return spec
