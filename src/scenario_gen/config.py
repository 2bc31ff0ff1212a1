"""Declarative scenario specification: frozen, typed, validated; YAML in, YAML/JSON out.

Every field carries its unit and allowed range in its metadata, and ``from_dict`` rejects unknown
keys and bad values with a message that names the dotted field, the value and what is allowed.
"""

from __future__ import annotations

import dataclasses
import math
import types
from dataclasses import dataclass
from dataclasses import field as dc_field
from importlib import resources
from pathlib import Path
from typing import Any, Union, get_args, get_origin, get_type_hints

import yaml

from .errors import ScenarioError


def _f(
    default: Any,
    doc: str,
    lo: float | None = None,
    hi: float | None = None,
    choices: tuple[Any, ...] | None = None,
) -> Any:
    return dc_field(default=default, metadata={"doc": doc, "lo": lo, "hi": hi, "choices": choices})


@dataclass(frozen=True)
class TerrainSpec:
    source: str = _f("embedded", "terrain source", choices=("embedded", "dem", "mesh", "plane"))
    path: str | None = _f(None, "GeoTIFF DEM (source=dem) or terrain mesh (source=mesh)")
    site: str = _f(
        "flattest",
        "how the field centre is chosen on a DEM",
        choices=("flattest", "steepest", "latlon"),
    )
    lat: float | None = _f(None, "site latitude, degrees (site=latlon)", -90, 90)
    lon: float | None = _f(None, "site longitude, degrees (site=latlon)", -180, 180)
    max_slope_deg: float = _f(
        90.0, "site=steepest picks the steepest window at most this steep", 0, 90
    )
    datum: tuple[float, float, float] | None = _f(
        None, "lat, lon, alt of the mesh origin (source=mesh) or of the plane (source=plane)"
    )
    lod: int = _f(20, "level of detail: Web-Mercator zoom; sets the grid spacing", 0, 22)
    margin: float = _f(8.0, "terrain kept around the field, metres", 0, 1000)
    slope_deg: float = _f(0.0, "plane: slope, degrees", 0, 60)
    aspect_deg: float = _f(
        0.0, "plane: downhill direction, degrees clockwise from north", -360, 360
    )
    fill_max_pixels: int = _f(64, "DEM nodata holes up to this many pixels are filled", 0, 10**7)
    up_axis: str = _f(
        "auto", "mesh up axis (auto: y for glTF/GLB, z otherwise)", choices=("auto", "y", "z")
    )


@dataclass(frozen=True)
class FieldSpec:
    geojson: str | None = _f(None, "GeoJSON file with a Polygon/MultiPolygon in lon/lat")
    width: float = _f(30.0, "rectangle size across the rows, metres", 0, 5000)
    length: float = _f(40.0, "rectangle size along the rows, metres", 0, 5000)
    angle_deg: float = _f(
        0.0, "rectangle long-side direction, degrees counter-clockwise from east", -360, 360
    )


@dataclass(frozen=True)
class LayoutSpec:
    row_spacing: float = _f(0.75, "distance between crop rows, metres", 0.05, 50)
    plant_spacing: float = _f(0.18, "distance between plants in a row, metres", 0.02, 50)
    row_angle_deg: float | None = _f(
        None,
        "row direction, degrees counter-clockwise from east (null: along the field)",
        -360,
        360,
    )
    # Planters place seed within ≈1 cm across the row; a 0.616 m robot in 0.75 m rows has
    # 5 cm of clearance per side, so more lateral scatter means crops hit even on the line.
    jitter_lateral: float = _f(0.01, "std of plant offset across the row, metres", 0, 1)
    jitter_longitudinal: float = _f(0.02, "std of plant offset along the row, metres", 0, 1)
    gap_prob: float = _f(0.02, "probability that a single plant is missing", 0, 1)
    gap_run_prob: float = _f(0.0, "probability per plant that a run of missing plants starts", 0, 1)
    gap_run_mean: float = _f(4.0, "mean length of a run of missing plants, plants", 1, 10**4)
    weed_density: float = _f(0.0, "weeds per square metre of planted area", 0, 100)
    headland: float = _f(4.0, "unplanted strip at both row ends, metres", 0, 500)
    edge_margin: float = _f(0.3, "unplanted margin along the field edge, metres", 0, 500)


@dataclass(frozen=True)
class CropSpec:
    species: str = _f("corn", "crop species", choices=("corn", "tomato", "cabbage", "sunflower"))
    stage: int = _f(3, "growth stage, 1 (early) .. the species' last stage", 1, 10)
    growth: float | None = _f(None, "continuous growth 0..1 (overrides stage)", 0, 1)
    height_std: float = _f(0.08, "relative std of plant height between plants", 0, 0.5)
    model: str | None = _f(None, "user mesh file or .zip (mesh + textures) scaled to the height")


@dataclass(frozen=True)
class FurrowSpec:
    enabled: bool = _f(True, "add ridge/furrow micro-relief along the rows")
    depth: float = _f(0.12, "ridge height above the furrow bottom, metres", 0, 1)
    profile: str = _f("sine", "cross-section of the ridges", choices=("sine", "trapezoid"))
    taper: float = _f(
        1.0, "distance over which relief fades out at the planted edge, metres", 0.01, 100
    )
    roughness: float = _f(0.005, "std of random soil roughness, metres", 0, 0.5)
    roughness_length: float = _f(0.3, "correlation length of the roughness, metres", 0.01, 100)


@dataclass(frozen=True)
class RouteSpec:
    lanes: int = _f(2, "lanes (furrows between adjacent rows) the zigzag route drives", 1, 10**4)
    first_lane: int | None = _f(
        None, "index of the first lane (null: centred in the field)", 0, 10**6
    )
    spacing: float = _f(0.05, "waypoint spacing, metres (at most 0.1)", 0.005, 0.1)
    lead_in: float = _f(
        2.0, "headland run before the first lane and after the last, metres", 0, 100
    )
    turn_offset: float = _f(1.0, "how far past the crop the U-turn starts, metres", 0, 100)


@dataclass(frozen=True)
class ScenarioSpec:
    name: str = _f("custom", "scenario name")
    terrain: TerrainSpec = dc_field(default_factory=TerrainSpec)
    field: FieldSpec = dc_field(default_factory=FieldSpec)
    layout: LayoutSpec = dc_field(default_factory=LayoutSpec)
    crop: CropSpec = dc_field(default_factory=CropSpec)
    furrows: FurrowSpec = dc_field(default_factory=FurrowSpec)
    route: RouteSpec = dc_field(default_factory=RouteSpec)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ScenarioSpec:
        return _build(cls, data, "")

    def to_dict(self) -> dict[str, Any]:
        return _plain(dataclasses.asdict(self))

    def replace(self, overrides: dict[str, Any]) -> ScenarioSpec:
        """A copy with nested or dotted overrides applied (``{"layout.row_spacing": 0.76}``)."""
        return ScenarioSpec.from_dict(merge(self.to_dict(), overrides))

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False)


def _plain(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    return obj


def merge(base: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    """Deep-merge ``overrides`` (nested dicts and/or dotted keys) into a copy of ``base``."""
    out = _plain(base)
    for key, value in overrides.items():
        parts = key.split(".")
        node = out
        for i, part in enumerate(parts[:-1]):
            nxt = node.get(part)
            if not isinstance(nxt, dict):
                if part in node or not isinstance(node, dict):
                    raise ScenarioError(".".join(parts[: i + 1]), nxt, "is not a section")
                nxt = node[part] = {}
            node = nxt
        last = parts[-1]
        if isinstance(value, dict) and isinstance(node.get(last), dict):
            node[last] = merge(node[last], value)
        else:
            node[last] = value
    return out


def from_mapping(cls: type, data: Any, prefix: str = "") -> Any:
    """Build any frozen config dataclass of this style from a mapping, with the same checks."""
    return _build(cls, data, prefix)


def to_mapping(obj: Any) -> dict[str, Any]:
    return _plain(dataclasses.asdict(obj))


def _build(cls: type, data: Any, prefix: str) -> Any:
    where = prefix.rstrip(".") or "spec"
    if not isinstance(data, dict):
        raise ScenarioError(where, data, "allowed: a mapping of keys to values")
    hints = get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - set(fields))
    if unknown:
        raise ScenarioError(
            f"{prefix}{unknown[0]}",
            data[unknown[0]],
            f"unknown key; allowed keys here: {', '.join(fields)}",
        )
    kwargs: dict[str, Any] = {}
    for name, value in data.items():
        f, tp, path = fields[name], hints[name], f"{prefix}{name}"
        if dataclasses.is_dataclass(tp):
            kwargs[name] = _build(tp, value, path + ".")  # type: ignore[arg-type]
        else:
            kwargs[name] = _coerce(value, tp, f.metadata, path)
    return cls(**kwargs)


def _coerce(value: Any, tp: Any, meta: Any, path: str) -> Any:
    args = get_args(tp)
    if get_origin(tp) in (Union, types.UnionType) and type(None) in args:
        if value is None:
            return None
        tp = next(a for a in args if a is not type(None))
    elif value is None:
        raise ScenarioError(path, value, f"allowed: {_describe(tp, meta)} (not null)")
    if get_origin(tp) is tuple:
        inner = get_args(tp)
        if not isinstance(value, (list, tuple)) or len(value) != len(inner):
            raise ScenarioError(path, value, f"allowed: a list of {len(inner)} numbers")
        return tuple(
            _scalar(v, t, {}, f"{path}[{i}]")
            for i, (v, t) in enumerate(zip(value, inner, strict=True))
        )
    return _scalar(value, tp, meta, path)


def _scalar(value: Any, tp: Any, meta: Any, path: str) -> Any:
    if tp is bool:
        if not isinstance(value, bool):
            raise ScenarioError(path, value, "allowed: true or false")
        return value
    if tp is int:
        if isinstance(value, bool) or not (
            isinstance(value, int) or (isinstance(value, float) and value.is_integer())
        ):
            raise ScenarioError(path, value, f"allowed: {_describe(tp, meta)}")
        value = int(value)
    elif tp is float:
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
        ):
            raise ScenarioError(path, value, f"allowed: {_describe(tp, meta)}")
        value = float(value)
    elif tp is str:
        if not isinstance(value, str):
            raise ScenarioError(path, value, f"allowed: {_describe(tp, meta)}")
    lo, hi, choices = meta.get("lo"), meta.get("hi"), meta.get("choices")
    if choices is not None and value not in choices:
        raise ScenarioError(path, value, f"allowed: {_describe(tp, meta)}")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise ScenarioError(path, value, f"allowed: {_describe(tp, meta)}")
    return value


def _describe(tp: Any, meta: Any) -> str:
    choices = meta.get("choices")
    if choices:
        return "one of " + ", ".join(map(str, choices))
    name = {float: "a number", int: "an integer", str: "a string", bool: "true/false"}.get(
        tp, str(tp)
    )
    lo, hi = meta.get("lo"), meta.get("hi")
    if lo is not None and hi is not None:
        return f"{name} in [{lo}, {hi}]"
    return name


# --------------------------------------------------------------------------- presets

PRESET_PACKAGE = "scenario_gen.presets"


def preset_names() -> list[str]:
    files = resources.files(PRESET_PACKAGE).iterdir()
    return sorted(p.name[:-5] for p in files if p.name.endswith(".yaml"))


def load_yaml(path: str | Path, what: str = "--config") -> dict[str, Any]:
    p = Path(path)
    if not p.is_file():
        raise ScenarioError(what, str(path), "allowed: an existing YAML file")
    try:
        data = yaml.safe_load(p.read_text())
    except yaml.YAMLError as exc:
        raise ScenarioError(
            what, str(path), f"is not valid YAML ({exc.__class__.__name__})"
        ) from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ScenarioError(what, str(path), "allowed: a YAML mapping at the top level")
    return data


def preset(name: str, **overrides: Any) -> ScenarioSpec:
    """A shipped preset, with overrides as nested dicts or dotted keys.

    >>> preset("paper-p2", layout={"jitter_lateral": 0.0}).layout.row_spacing
    2.0
    """
    names = preset_names()
    if name not in names:
        raise ScenarioError("preset", name, f"allowed: one of {', '.join(names)}")
    data = _preset_data(name)
    data["name"] = name
    # Python keyword arguments cannot hold dots; accept "layout__row_spacing" as well.
    flat = {k.replace("__", "."): v for k, v in overrides.items()}
    return ScenarioSpec.from_dict(merge(data, flat))


def _preset_data(name: str, depth: int = 0) -> dict[str, Any]:
    """A preset file's mapping, with ``extends: other`` resolved (other first, then this)."""
    if depth > 8:
        raise ScenarioError("preset.extends", name, "allowed: a chain of at most 8 presets")
    text = resources.files(PRESET_PACKAGE).joinpath(f"{name}.yaml").read_text()
    data = yaml.safe_load(text) or {}
    parent = data.pop("extends", None)
    if parent is None:
        return dict(data)
    if parent not in preset_names():
        raise ScenarioError(f"preset {name}: extends", parent, "allowed: another preset name")
    return merge(_preset_data(parent, depth + 1), data)
