"""Where an env's scenarios come from: a Scenario, a saved directory, a preset, or a bank."""

from __future__ import annotations

from collections import OrderedDict
from pathlib import Path
from typing import Any

import numpy as np

import scenario_gen as sg
from scenario_gen import Scenario, ScenarioError

#: Keys of ``randomize`` handled by the env rather than the scenario spec.
ENV_RANDOMIZE_KEYS = ("gnss_mode", "soil_colour", "light_azimuth_deg", "light_elevation_deg")


def resolve(source: Any, overrides: dict[str, Any] | None, seed: int) -> Scenario:
    """A Scenario from a Scenario, a scenario directory or a preset name."""
    if isinstance(source, Scenario):
        if overrides:
            raise ScenarioError(
                "scenario_overrides",
                overrides,
                "apply only to presets; pass a new Scenario instead",
            )
        return source
    if source is None:
        source = "default"
    if isinstance(source, (str, Path)):
        path = Path(source)
        if (path / "scenario.json").is_file():
            if overrides:
                raise ScenarioError(
                    "scenario_overrides",
                    overrides,
                    "apply only to presets, not to a saved scenario directory",
                )
            return sg.load(path)
        if str(source) in sg.preset_names():
            return sg.generate(sg.preset(str(source), **(overrides or {})), seed)
        raise ScenarioError(
            "scenario",
            str(source),
            "allowed: a Scenario, a scenario directory "
            f"or a preset ({', '.join(sg.preset_names())})",
        )
    raise ScenarioError(
        "scenario",
        type(source).__name__,
        "allowed: a Scenario, a scenario directory or a preset name",
    )


def sample_randomization(ranges: dict[str, Any], rng: np.random.Generator) -> dict[str, Any]:
    """Draw one value per key: [lo, hi] is uniform (integers if both ends are), a dict
    {"choices": [...]} picks one."""
    out: dict[str, Any] = {}
    for key in sorted(ranges):
        spec = ranges[key]
        if isinstance(spec, dict) and set(spec) == {"choices"} and len(spec["choices"]) > 0:
            out[key] = spec["choices"][int(rng.integers(len(spec["choices"])))]
        elif (
            isinstance(spec, (list, tuple))
            and len(spec) == 2
            and all(
                isinstance(v, (int, float, list, tuple)) and not isinstance(v, bool) for v in spec
            )
        ):
            lo, hi = spec
            if isinstance(lo, (list, tuple)):  # e.g. soil colour: two RGB triplets
                out[key] = list(rng.uniform(np.asarray(lo, float), np.asarray(hi, float)))
            elif isinstance(lo, int) and isinstance(hi, int):
                out[key] = int(rng.integers(lo, hi + 1))
            else:
                out[key] = float(rng.uniform(lo, hi))
        else:
            raise ScenarioError(
                f"randomize.{key}", spec, "allowed: [low, high] or {choices: [...]}"
            )
    return out


def split_randomization(values: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    env = {k: v for k, v in values.items() if k in ENV_RANDOMIZE_KEYS}
    scn = {k: v for k, v in values.items() if k not in ENV_RANDOMIZE_KEYS}
    return scn, env


class Bank:
    """Scenarios saved under one directory (e.g. by ``agrinav scenario --count N``)."""

    def __init__(self, directory: str | Path, cache: int = 8) -> None:
        root = Path(directory)
        self.dirs = (
            sorted(d for d in root.iterdir() if (d / "scenario.json").is_file())
            if root.is_dir()
            else []
        )
        if not self.dirs:
            raise ScenarioError(
                "bank", str(directory), "holds no scenario directories (with scenario.json)"
            )
        self._cache: OrderedDict[Path, Scenario] = OrderedDict()
        self._size = cache

    def __len__(self) -> int:
        return len(self.dirs)

    def sample(self, rng: np.random.Generator) -> Scenario:
        d = self.dirs[int(rng.integers(len(self.dirs)))]
        if d in self._cache:
            self._cache.move_to_end(d)
            return self._cache[d]
        scn = sg.load(d)
        self._cache[d] = scn
        while len(self._cache) > self._size:
            self._cache.popitem(last=False)
        return scn
