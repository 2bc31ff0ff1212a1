"""The studio's state, kept as the ``agrinav scenario`` command line that reproduces it.

The page never builds a spec its own way: its state is a preset, the terrain flags it was
started with, the drawn field, a seed and ``--set`` overrides, and the spec is what
``baselines.scenario_spec`` — the CLI's own spec builder — makes of that command line. The
command the page shows (and copies) is therefore the scenario it generates, by construction.
"""

from __future__ import annotations

import math
import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from shapely.geometry.base import BaseGeometry

from scenario_gen.errors import InputError
from scenario_gen.generate import check_spec
from scenario_gen.schema import coerce, field_info, parse_yaml, plain
from scenario_gen.spec import ScenarioSpec

from ..scenario_spec import spec_from_argv
from . import fields


@dataclass(frozen=True)
class Terrain:
    """The terrain flags the studio was started with (``--dem``, ``--mesh``, ``--datum``)."""

    dem: str | None = None
    mesh: str | None = None
    datum: str | None = None

    def args(self) -> list[str]:
        out: list[str] = []
        for flag, value in (("--dem", self.dem), ("--mesh", self.mesh), ("--datum", self.datum)):
            if value is not None:
                out += [flag, value]
        return out


@dataclass
class Session:
    """What the page shows: preset + terrain flags + drawn field + seed + overrides."""

    preset: str = "default"
    terrain: Terrain = field(default_factory=Terrain)
    seed: int = 0
    overrides: dict[str, Any] = field(default_factory=dict)
    field_geom: BaseGeometry | None = None  # lon/lat, normalised (see fields.normalise)
    field_text: str | None = None

    # ------------------------------------------------------------------ the spec
    def base(self) -> ScenarioSpec:
        """The spec without ``--set`` overrides and without a drawn field."""
        return spec_from_argv(self.args(None, None, with_overrides=False))

    def spec(self, field_path: str | None = None) -> ScenarioSpec:
        """The spec the command line gives (``field_path`` names the drawn field's file)."""
        return spec_from_argv(self.args(None, field_path))

    def set(self, key: str, value: Any) -> None:
        """Set one dotted spec field; bad values raise ``InputError`` naming ``key``."""
        info = field_info(ScenarioSpec, key)
        if info is None or info[0] is None:
            raise InputError(key, value, "is not a spec field")
        tp, meta = info
        checked = coerce(value, tp, meta, key)
        base = _get(self.base().to_dict(), key)
        trial = dict(self.overrides)
        if plain(checked) == base:
            trial.pop(key, None)
        else:
            trial[key] = plain(checked)
        old, self.overrides = self.overrides, trial
        try:
            check_spec(self.spec())  # cross-field checks (crop.stage per species) name a field
        except InputError:
            self.overrides = old
            raise

    def value(self, key: str) -> Any:
        return _get(self.spec().to_dict(), key)

    def set_field(self, geom: BaseGeometry | None) -> None:
        if geom is None:
            self.field_geom = self.field_text = None
            return
        self.field_geom, self.field_text = fields.normalise(geom)

    def set_preset(self, name: str) -> None:
        """Switch preset; overrides are dropped (they were relative to the old one)."""
        spec_from_argv(["--preset", name, *self.terrain.args()])
        self.preset, self.overrides = name, {}

    # ------------------------------------------------------------------ the command line
    def args(
        self,
        out: str | None,
        field_path: str | None,
        force: bool = False,
        with_overrides: bool = True,
    ) -> list[str]:
        """``agrinav scenario`` arguments (without the program and subcommand names)."""
        a = ["--preset", self.preset, *self.terrain.args()]
        if field_path is not None:
            a += ["--field", field_path]
        a += ["--seed", str(self.seed)]
        if with_overrides:
            for key in sorted(self.overrides):
                a += ["--set", f"{key}={yaml_value(self.overrides[key])}"]
        if out is not None:
            a += ["--out", out]
        if force:
            a.append("--force")
        return a

    def command(self, out: str, force: bool = False) -> str:
        """The shell command that generates what ``actions.generate_and_save`` writes."""
        path = str(field_file(out)) if self.field_geom is not None else None
        return shlex.join(["agrinav", "scenario", *self.args(out, path, force)])


def field_file(out: str | Path) -> Path:
    """Where the drawn field is written: next to the scenario folder, not inside it."""
    p = Path(out)
    if not str(out).strip() or p.name in ("", ".", ".."):  # "/", ".": no name to put it beside
        raise InputError("out", str(out), "allowed: a folder path")
    return p.with_name(p.name + ".field.geojson")


def yaml_value(v: Any) -> str:
    """``v`` as the text ``--set key=TEXT`` reads back as exactly ``v``."""
    v = plain(v)
    if v is None:
        text = "null"
    elif isinstance(v, bool):
        text = "true" if v else "false"
    elif isinstance(v, int):
        text = str(v)
    elif isinstance(v, float):
        if not math.isfinite(v):
            raise InputError("value", v, "allowed: a finite number")
        text = repr(v)
        mant, e, exp = text.partition("e")
        if e and "." not in mant:  # YAML 1.1 reads 1e-05 as a string, 1.0e-05 as a float
            text = f"{mant}.0e{exp}"
    elif isinstance(v, str):
        text = v if v.strip() == v and v and parse_yaml(v, "value") == v else _quoted(v)
    elif isinstance(v, list):
        text = "[" + ", ".join(yaml_value(x) for x in v) + "]"
    else:
        raise InputError("value", v, "allowed: a number, string, boolean, list or null")
    if parse_yaml(text, "value") != v:
        raise InputError("value", v, "cannot be written as a --set value")
    return text


def _quoted(s: str) -> str:
    import json

    return json.dumps(s)


def _get(d: dict[str, Any], dotted: str) -> Any:
    node: Any = d
    for part in dotted.split("."):
        node = node[part]
    return node
