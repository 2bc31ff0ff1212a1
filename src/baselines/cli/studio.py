"""``agrinav studio``: the field studio, a local web page (see docs/studio.md)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from scenario_gen.errors import InputError

from .args import int_at_least


def add(sub: Any) -> None:
    from scenario_gen import preset_names

    st = sub.add_parser(
        "studio",
        help="draw a field on the terrain, tune it with a live preview, generate and run it",
        description="Serve the field studio on 127.0.0.1: the terrain as a map, a field drawn "
        "on it, every layout and crop parameter with a live preview, and buttons to generate, "
        "export and run a policy. Works offline.",
    )
    st.add_argument("--preset", default="default", choices=preset_names())
    st.add_argument("--dem", help="GeoTIFF DEM (any CRS)")
    st.add_argument("--mesh", help="terrain mesh (glTF/GLB, OBJ, PLY, DAE, STL)")
    st.add_argument("--datum", help="LAT,LON,ALT of the mesh or plane origin")
    st.add_argument("--port", type=int_at_least(1, 65535), default=8080)
    st.add_argument(
        "--workspace",
        default="runs/studio",
        help="default folder for scenarios and uploaded crop models (default: runs/studio)",
    )
    st.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from baselines.studio.session import Session, Terrain

    if args.dem and args.mesh:
        raise InputError("--dem/--mesh", (args.dem, args.mesh), "allowed: one terrain source")
    workspace = Path(args.workspace)
    if workspace.exists() and not workspace.is_dir():
        raise InputError(
            "--workspace", str(workspace), "is not a folder; allowed: a folder (made if missing)"
        )
    check_port(args.port)
    terrain = Terrain(dem=args.dem, mesh=args.mesh, datum=args.datum)
    session = Session(preset=args.preset, terrain=terrain)
    spec = session.spec()  # the CLI's own checks, before a server starts
    from baselines.studio.layers import elevation_source

    elevation_source(spec.terrain)  # an unreadable DEM or mesh is refused here, in one line
    from baselines.studio.app import serve
    from baselines.studio.shared import Studio

    serve(Studio(args.preset, terrain, workspace), args.port)
    return 0


def check_port(port: int, host: str = "127.0.0.1") -> None:
    """Refuse a port another program listens on before the studio prints its address (the
    server would fail after it, with its own exit status)."""
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as uvicorn binds
        try:
            sock.bind((host, port))
        except OSError as exc:
            raise InputError(
                "--port", port, f"cannot be served on {host} ({exc.strerror}); allowed: a free port"
            ) from None
