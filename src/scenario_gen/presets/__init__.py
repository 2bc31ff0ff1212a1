"""Shipped presets: named YAML files of spec overrides, with ``extends:`` chains."""

from __future__ import annotations

from importlib import resources
from typing import Any

from ..errors import InputError
from ..schema import merge, parse_yaml
from ..spec import ScenarioSpec

PRESET_PACKAGE = "scenario_gen.presets"


def preset_names() -> list[str]:
    files = resources.files(PRESET_PACKAGE).iterdir()
    return sorted(p.name[:-5] for p in files if p.name.endswith(".yaml"))


def preset(name: str, **overrides: Any) -> ScenarioSpec:
    """A shipped preset, with overrides as nested dicts or dotted keys.

    >>> preset("paper-p2", layout={"jitter_lateral": 0.0}).layout.row_spacing
    2.0
    """
    names = preset_names()
    if name not in names:
        raise InputError("preset", name, f"allowed: one of {', '.join(names)}")
    data = _preset_data(name)
    data["name"] = name
    # Python keyword arguments cannot hold dots; accept "layout__row_spacing" as well.
    flat = {k.replace("__", "."): v for k, v in overrides.items()}
    return ScenarioSpec.from_dict(merge(data, flat))


def _preset_data(name: str, depth: int = 0) -> dict[str, Any]:
    """A preset file's mapping, with ``extends: other`` resolved (other first, then this)."""
    if depth > 8:
        raise InputError("preset.extends", name, "allowed: a chain of at most 8 presets")
    text = resources.files(PRESET_PACKAGE).joinpath(f"{name}.yaml").read_text()
    data = parse_yaml(text, f"preset {name}") or {}
    parent = data.pop("extends", None)
    if parent is None:
        return dict(data)
    if parent not in preset_names():
        raise InputError(f"preset {name}: extends", parent, "allowed: another preset name")
    return merge(_preset_data(parent, depth + 1), data)
