"""The scenario a command line describes: ``agrinav scenario``'s spec flags and the spec they
give, in one place for the CLI and the studio (whose state is such a command line).

Precedence: preset < ``--config`` file < ``--dem/--mesh/--field/--waypoints/--lod`` flags <
``--set`` overrides.
"""

from __future__ import annotations

import argparse
import functools
import shlex
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

import yaml

from scenario_gen.errors import InputError
from scenario_gen.spec import ScenarioSpec

#: flags of ``agrinav scenario`` that say where and how to write, not what to generate
OUTPUT_FLAGS = {"--seed": 1, "--out": 1, "--force": 0, "--no-preview": 0, "--count": 1}


def add_spec_arguments(parser: Any) -> None:
    """The flags that make the spec (on ``agrinav scenario`` and the studio's parser)."""
    from scenario_gen import preset_names

    parser.add_argument("--preset", default="default", choices=preset_names())
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a spec field, e.g. --set layout.row_spacing=0.76 (repeatable)",
    )
    parser.add_argument("--config", help="YAML file of spec overrides")
    parser.add_argument("--dem", help="GeoTIFF DEM (any CRS)")
    parser.add_argument("--mesh", help="terrain mesh (glTF/GLB, OBJ, PLY, DAE, STL)")
    parser.add_argument(
        "--datum",
        help="LAT,LON,ALT of the mesh or plane origin (a DEM sets its own: refused with one)",
    )
    parser.add_argument(
        "--field",
        help="the field's polygons: GeoJSON, GeoPackage, Shapefile or KML in any declared CRS "
        "(a file with several polygon layers: add --set field.layer=NAME)",
    )
    parser.add_argument(
        "--waypoints",
        help="Nav2 GPS waypoint YAML (as `agrinav export --to nav2` writes): the route is the "
        "plan through them instead of the zigzag",
    )
    parser.add_argument("--lod", type=int, help="level of detail (Web-Mercator zoom 0-22)")


def parse_set(
    items: list[str], flag: str = "--set", example: str = "layout.row_spacing=0.76"
) -> dict[str, Any]:
    """``key=value`` pairs (``--set``, ``--hyperparams``, ``--config``), values parsed as YAML."""
    from scenario_gen.schema import parse_yaml

    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise InputError(flag, item, f"allowed: key=value, e.g. {example}")
        if key.strip() in out:  # which of the two values wins would be the order on the line
            raise InputError(f"{flag} {key.strip()}", item, "given twice; allowed: once")
        try:
            out[key.strip()] = parse_yaml(raw, f"{flag} {key}") if raw.strip() else None
        except yaml.YAMLError:  # pragma: no cover  (parse_yaml reports YAML errors itself)
            raise InputError(f"{flag} {key}", raw, "is not a valid YAML value") from None
    return out


def _parse_datum(text: str) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        vals = []
    if len(vals) != 3:
        raise InputError("--datum", text, "allowed: LAT,LON,ALT in degrees and metres")
    return vals


def spec_from_args(args: argparse.Namespace) -> Any:
    """preset < --config file < --dem/--mesh/--field/--lod flags < --set overrides; named after
    the preset and the files it reads (``source_name``) unless the config or --set names it."""
    import dataclasses

    from scenario_gen import preset
    from scenario_gen.generate import PATH_KEYS, check_fields_used, check_spec, resolve_paths
    from scenario_gen.presets import source_name
    from scenario_gen.schema import load_yaml, merge
    from scenario_gen.spec import ScenarioSpec

    for flag in ("config", "dem", "mesh", "field", "waypoints"):
        given = getattr(args, flag)
        if given is not None and not given.strip():  # an unset shell variable: not "absent"
            raise InputError(f"--{flag}", given, "allowed: a file path (it is empty)")
    base = preset(args.preset).to_dict()
    config: dict[str, Any] = load_yaml(args.config) if args.config else {}
    if args.config:  # a file the config names is where the config's folder says it is
        folder = Path(args.config).expanduser().parent
        for key in PATH_KEYS:
            section, name = key.split(".")
            part = config.get(section)
            if isinstance(part, dict) and isinstance(part.get(name), str):
                path = Path(part[name]).expanduser()
                if not path.is_absolute():
                    config = {**config, section: {**part, name: str(folder / path)}}
    base = merge(base, config)
    flags: dict[str, Any] = {}
    if args.dem and args.mesh:
        raise InputError("--dem/--mesh", (args.dem, args.mesh), "allowed: one terrain source")
    if args.dem:
        flags.update({"terrain.source": "dem", "terrain.path": args.dem})
    if args.mesh:
        if not args.datum:
            raise InputError("--datum", None, "--mesh needs --datum LAT,LON,ALT of the mesh origin")
        flags.update({"terrain.source": "mesh", "terrain.path": args.mesh})
    if args.datum is not None:  # '' is a bad datum, not an absent one
        flags["terrain.datum"] = _parse_datum(args.datum)
    if args.field:
        flags["field.geojson"] = args.field
    if args.waypoints:
        flags["route.waypoints"] = args.waypoints
    if args.lod is not None:
        flags["terrain.lod"] = args.lod
    sets = parse_set(args.set)
    spec = ScenarioSpec.from_dict(merge(merge(base, flags), sets))
    if "name" not in config and "name" not in sets:  # named after its preset and files
        files = [args.config] if args.config else []
        spec = dataclasses.replace(spec, name=source_name(args.preset, spec, files))
    check_spec(spec)
    check_fields_used(spec)
    return resolve_paths(spec)  # absolute input paths in scenario.json and bank.yaml


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise InputError("command", message, "see agrinav scenario --help")


def spec_from_argv(argv: Sequence[str]) -> ScenarioSpec:
    """The spec ``agrinav scenario ARGV`` would generate (``--out`` may be omitted)."""
    return _spec_from_argv(tuple(argv))


@functools.lru_cache(maxsize=512)
def _spec_from_argv(argv: tuple[str, ...]) -> ScenarioSpec:
    # Cached: argparse and the preset's YAML cost ≈15 ms a time, a third of a studio redraw.
    # Specs are frozen and these arguments name no file that is read here, so it is exact.
    rest = list(argv)
    spec_argv = []
    while rest:
        arg = rest.pop(0)
        if arg in OUTPUT_FLAGS:
            del rest[: OUTPUT_FLAGS[arg]]
        else:
            spec_argv.append(arg)
    try:
        ns = _parser().parse_args(spec_argv)
    except InputError:
        raise InputError("command", shlex.join(argv), "is not a valid agrinav command") from None
    return spec_from_args(ns)


@functools.lru_cache(maxsize=1)
def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="agrinav scenario", add_help=False)
    add_spec_arguments(parser)
    return parser
