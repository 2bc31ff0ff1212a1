"""Shipped presets: named YAML files of spec overrides, with ``extends:`` chains."""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..schema import merge, parse_yaml
from ..spec import ScenarioSpec

PRESET_PACKAGE = "scenario_gen.presets"


def preset_names() -> list[str]:
    files = resources.files(PRESET_PACKAGE).iterdir()
    return sorted(p.name[:-5] for p in files if p.name.endswith(".yaml"))


def preset(name: str, /, **overrides: Any) -> ScenarioSpec:
    """A shipped preset, with overrides as nested dicts or dotted keys; named after the preset
    and the files the overrides bring in (``source_name``) unless they set ``name``.

    >>> preset("paper-p2", layout={"jitter_lateral": 0.0}).layout.row_spacing
    2.0
    >>> preset("default", field={"geojson": "fields/north.geojson"}).name
    'default+north'
    """
    names = preset_names()
    if name not in names:
        raise InputError("preset", name, f"allowed: one of {', '.join(names)}")
    data = _preset_data(name)
    data["name"] = name
    # Python keyword arguments cannot hold dots; accept "layout__row_spacing" as well.
    flat = {k.replace("__", "."): v for k, v in overrides.items()}
    spec = ScenarioSpec.from_dict(merge(data, flat))
    if "name" in flat:
        return spec
    return dataclasses.replace(spec, name=source_name(name, spec))


MAX_NAME = 100  # generate's limit on scenario names


def source_name(preset_name: str, spec: ScenarioSpec, files: Sequence[str] = ()) -> str:
    """A scenario's name after what it was made from: the preset, then the stem of each file
    ``files`` (e.g. a config file) and the spec read — the terrain (a DEM or mesh), the field
    polygon, the waypoints, the crop model — joined by ``+``: ``default`` for the preset alone,
    ``default+farm+north`` on ``farm.tif`` with the field ``north.geojson``. Kept one printable
    line without ``--``, at most 100 characters, as ``generate`` requires of a name."""
    t = spec.terrain
    paths = [*files, t.path if t.source in ("dem", "mesh") else None]
    paths += [spec.field.geojson, spec.route.waypoints, spec.crop.model]
    parts = [preset_name]
    for path in paths:
        stem = Path(str(path)).name.split(".", 1)[0] if path else ""
        if stem and stem not in parts:
            parts.append(stem)
    name = "".join(c if c.isprintable() else "_" for c in "+".join(parts))
    name = re.sub("-{2,}", "-", name)[:MAX_NAME].strip() or "custom"
    return name


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
