"""``agrinav scenario``: generate a scenario folder, or a bank of them."""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path
from typing import Any

from scenario_gen.errors import InputError

from .args import MAX_SEED, int_at_least, parse_set, seed_type


def add(sub: Any) -> None:
    from scenario_gen import preset_names

    sc = sub.add_parser(
        "scenario",
        help="generate a crop-field scenario on real terrain",
        description="Generate a scenario directory (scenario.json, terrain.npz, "
        "plants.csv, route.csv, field.geojson, preview.png), or a bank with --count.",
    )
    sc.add_argument("--preset", default="default", choices=preset_names())
    sc.add_argument("--seed", type=seed_type, default=0)
    sc.add_argument("--out", required=True, help="output directory (must not exist, or --force)")
    sc.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a spec field, e.g. --set layout.row_spacing=0.76 (repeatable)",
    )
    sc.add_argument("--config", help="YAML file of spec overrides")
    sc.add_argument("--dem", help="GeoTIFF DEM (any CRS)")
    sc.add_argument("--mesh", help="terrain mesh (glTF/GLB, OBJ, PLY, DAE, STL)")
    sc.add_argument(
        "--datum",
        help="LAT,LON,ALT of the mesh or plane origin (a DEM sets its own: refused with one)",
    )
    sc.add_argument("--field", help="GeoJSON polygon of the field (WGS84 lon/lat)")
    sc.add_argument(
        "--waypoints",
        help="Nav2 GPS waypoint YAML (as `agrinav export --to nav2` writes): the route is the "
        "plan through them instead of the zigzag",
    )
    sc.add_argument("--lod", type=int, help="level of detail (Web-Mercator zoom 0-22)")
    sc.add_argument(
        "--count",
        type=int_at_least(1, 100_000),
        default=1,
        help="generate a bank of COUNT scenarios, seeds SEED..SEED+COUNT-1",
    )
    sc.add_argument("--force", action="store_true", help="replace an existing output directory")
    sc.add_argument("--no-preview", action="store_true", help="skip preview.png")
    sc.set_defaults(func=run)


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
    from scenario_gen import preset
    from scenario_gen.generate import check_spec, resolve_paths
    from scenario_gen.presets import source_name
    from scenario_gen.schema import load_yaml, merge
    from scenario_gen.spec import ScenarioSpec

    base = preset(args.preset).to_dict()
    config: dict[str, Any] = load_yaml(args.config) if args.config else {}
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
    return resolve_paths(spec)  # absolute input paths in scenario.json and bank.yaml


def run(args: argparse.Namespace) -> int:
    import yaml
    from tqdm import tqdm

    from scenario_gen import generate, save
    from scenario_gen.atomic import check_output_dir, output_dir

    spec = spec_from_args(args)
    if args.seed + args.count - 1 > MAX_SEED:
        raise InputError(
            "--seed/--count",
            (args.seed, args.count),
            f"allowed: seeds up to {MAX_SEED} (seed + count - 1)",
        )
    out = Path(args.out)
    check_output_dir(out, args.force)
    if args.count == 1:
        t0 = time.perf_counter()
        scn = generate(spec, args.seed)
        t_gen = time.perf_counter() - t0
        save(scn, out, overwrite=args.force, preview=not args.no_preview)
        rows = {
            **scn.summary(),
            "generate_s": round(t_gen, 3),
            "total_s": round(time.perf_counter() - t0, 3),
            "out": str(out),
        }
        width = max(map(len, rows))
        for k, v in rows.items():
            print(f"{k:<{width}}  {v}")
        return 0
    # A bank: one scenario per seed, written as one folder that appears only when complete;
    # bank.yaml lists its members, and only those are ever sampled.
    seeds = range(args.seed, args.seed + args.count)
    names = [f"seed-{seed:06d}" for seed in seeds]
    first = generate(spec, seeds.start)  # bad input is reported before the bank folder exists
    with output_dir(out, args.force) as tmp:
        for seed, name in tqdm(
            zip(seeds, names, strict=True), total=len(names), desc="scenarios", unit="scn"
        ):
            scn = first if seed == seeds.start else generate(spec, seed)
            save(scn, tmp / name, preview=not args.no_preview)
        (tmp / "bank.yaml").write_text(
            yaml.safe_dump(
                {"spec": spec.to_dict(), "seeds": list(seeds), "scenarios": names},
                sort_keys=False,
            )
        )
    print(f"{args.count} scenarios ({spec.name}, seeds {seeds.start}..{seeds.stop - 1}) in {out}")
    return 0
