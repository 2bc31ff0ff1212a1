"""``agrinav export``: a saved scenario for Gazebo, ROS 2 / Nav2, GIS tools or 3-D software."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from scenario_gen.errors import InputError

from .args import separated


def add(sub: Any) -> None:
    from scenario_gen.export import MESH_FORMATS, TARGETS, ExportOptions

    ex = sub.add_parser(
        "export",
        help="export a scenario folder for Gazebo, Nav2, GIS or as meshes",
        description="Export a saved scenario folder: --to gazebo (SDF worlds and models), "
        "nav2 (the world, the Summit-XL with its Gazebo sensors and drive, a ros_gz_bridge, "
        "robot_localization and Nav2 configuration, a behaviour tree, a launch file, GPS "
        "waypoints and the reference path), "
        "gis (GeoTIFF, GeoPackage, GeoJSON) or mesh (GLB/OBJ/PLY/DAE). See docs/exports.md.",
    )
    ex.add_argument("dir", metavar="DIR", help="a scenario folder written by agrinav scenario")
    ex.add_argument("--to", required=True, choices=TARGETS, help="what to export for")
    ex.add_argument("--out", required=True, help="output folder (must not exist, or --force)")
    ex.add_argument("--force", action="store_true", help="replace an existing output folder")
    ex.add_argument(
        "--plants",
        choices=("auto", "include", "tiles"),
        help="gazebo/nav2: one <include> per plant, or merged static tiles "
        "(auto, the default: tiles above --include-limit plants); obstacles alike: a model "
        "each, or tiles",
    )
    defaults = ExportOptions()
    ex.add_argument(
        "--include-limit",
        type=int,
        help=f"gazebo/nav2: auto's limit (default {defaults.include_limit:,} plants), "
        "the same for obstacles, counted separately",
    )
    ex.add_argument(
        "--tile-plants",
        type=int,
        help=f"gazebo/nav2: plants per merged tile (default {defaults.tile_plants:,}); "
        "obstacles per obstacle tile",
    )
    ex.add_argument(
        "--heightmap",
        action="store_true",
        help="gazebo/nav2: also a 16-bit heightmap terrain and a Gazebo Sim world using it",
    )
    ex.add_argument(
        "--formats",
        type=separated(",", "formats"),
        help=f"mesh: comma-separated formats from {','.join(MESH_FORMATS)} (default glb)",
    )
    ex.add_argument(
        "--with-plants", action="store_true", help="mesh: also the merged plants and the obstacles"
    )
    ex.add_argument(
        "--dwb",
        help="nav2: the DWB configuration the bundle's controller runs: furrow (default), nav2, "
        "tuned, or a YAML file of changes (e.g. benchmarks/dwb_tuned_shim.yaml: the rotation "
        "shim in front)",
    )
    ex.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from scenario_gen.export import ExportOptions, export

    # --plants and --formats default to None, not their values: given for another target,
    # even as the default value, they are refused like every other flag
    plants = args.plants or "auto"
    data: dict[str, Any] = {
        "plants": plants,
        "heightmap": args.heightmap,
        "formats": args.formats or ["glb"],
        "mesh_plants": args.with_plants,
    }
    if args.include_limit is not None:
        data["include_limit"] = args.include_limit
    if args.tile_plants is not None:
        data["tile_plants"] = args.tile_plants
    if args.to == "nav2":
        from policies.dwb.params import SHIPPED

        from ..nav2_robot import nav2_options

        # an empty one is not silently the default
        if args.dwb is not None and args.dwb not in SHIPPED and not Path(args.dwb).is_file():
            allowed = f"allowed: {', '.join(SHIPPED)} or an existing YAML file"
            raise InputError("--dwb", args.dwb, allowed)
        data = nav2_options(dwb=args.dwb or "furrow", **data)
    elif args.dwb is not None:
        raise InputError("--to", args.to, "--dwb is for --to nav2 only")
    mesh_only = {"--formats": args.formats is not None, "--with-plants": args.with_plants}
    _only_with(args.to, ("mesh",), mesh_only, "mesh")
    world_only = {
        "--plants": args.plants is not None,
        "--include-limit": args.include_limit is not None,
        "--tile-plants": args.tile_plants is not None,
        "--heightmap": args.heightmap,
    }
    _only_with(args.to, ("gazebo", "nav2"), world_only, "gazebo or nav2 (a Gazebo world)")
    # each tile flag shapes one kind of world: given for the other, it changed nothing
    if plants == "include" and args.tile_plants is not None:
        raise InputError(
            "--tile-plants",
            args.tile_plants,
            "--plants include merges no tiles; allowed with --plants auto or tiles",
        )
    if plants != "auto" and args.include_limit is not None:
        raise InputError(
            "--include-limit",
            args.include_limit,
            f"is auto's limit, and --plants is {plants}; allowed with --plants auto",
        )
    opts = ExportOptions.from_dict(data)
    t0 = time.perf_counter()
    info = export(args.dir, args.to, args.out, opts, overwrite=args.force)
    info["seconds"] = round(time.perf_counter() - t0, 2)
    width = max(map(len, info))
    for k, v in info.items():
        print(f"{k:<{width}}  {v}")
    return 0


def _only_with(to: str, targets: tuple[str, ...], flags: dict[str, bool], names: str) -> None:
    given = [flag for flag, used in flags.items() if used]
    if to not in targets and given:
        raise InputError(
            "--to",
            to,
            f"{' and '.join(given)} are for --to {names} only"
            if len(given) > 1
            else f"{given[0]} is for --to {names} only",
        )
