"""Exports of a saved scenario for Gazebo, ROS 2 / Nav2, GIS tools and 3-D software.

>>> from scenario_gen.export import export, ExportOptions
>>> export("runs/default", "gazebo", "runs/default-gazebo", ExportOptions())  # doctest: +SKIP

Every target writes one folder atomically (``atomic.output_dir``): inputs are checked first,
and a failure leaves nothing behind. See docs/exports.md.
"""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

from ..atomic import check_output_dir, output_dir
from ..errors import InputError
from ..model import Scenario
from ..reading import load
from .options import MESH_FORMATS, TARGETS, ExportOptions
from .plantmodels import user_model_path

__all__ = ["MESH_FORMATS", "TARGETS", "ExportOptions", "export", "export_scenario"]


def export(
    directory: str | Path,
    to: str,
    out: str | Path,
    opts: ExportOptions | None = None,
    overwrite: bool = False,
    what: str = "--out",
) -> dict[str, Any]:
    """Export the scenario folder ``directory`` as ``to`` into the new folder ``out`` (named
    ``what`` in errors: the CLI's flag by default)."""
    if to not in TARGETS:
        raise InputError("--to", to, f"allowed: one of {', '.join(TARGETS)}")
    src = Path(directory)
    if not src.is_dir():
        raise InputError("scenario", str(src), "allowed: a scenario folder (agrinav scenario)")
    # with --force, the plainer reason before the marker's kind; without, "already exists"
    if overwrite and Path(out).resolve() == src.resolve():
        raise InputError(what, str(out), "is the scenario folder itself; choose another")
    check_output_dir(out, overwrite, what, kind="export", inputs=[src])
    try:
        scn = load(src)
    except InputError:
        raise
    except (OSError, ValueError, KeyError, TypeError, zipfile.BadZipFile) as exc:
        raise InputError(
            "scenario",
            str(src),
            f"cannot be read as a scenario folder ({type(exc).__name__}: {exc})",
        ) from None
    return export_scenario(scn, to, out, opts or ExportOptions(), overwrite, what)


def export_scenario(
    scn: Scenario,
    to: str,
    out: str | Path,
    opts: ExportOptions,
    overwrite: bool = False,
    what: str = "--out",
) -> dict[str, Any]:
    """Export an in-memory scenario; every input is checked before ``out`` (named ``what``
    in errors) is created."""
    if to not in TARGETS:
        raise InputError("--to", to, f"allowed: one of {', '.join(TARGETS)}")
    check_output_dir(out, overwrite, what, kind="export")
    if to in ("gazebo", "nav2") or (to == "mesh" and opts.mesh_plants):
        user_model_path(scn)
    if to == "nav2":
        _check_robot(opts.robot_urdf)
        _check_nav2_robot(opts.nav2_robot)
    with output_dir(out, overwrite, what, kind="export") as tmp:
        if to == "gazebo":
            from .gazebo import export_gazebo
            from .readme import gazebo_readme

            g = export_gazebo(scn, tmp, opts)
            (tmp / "README.md").write_text(gazebo_readme(scn, g))
            from .preview import render_export_preview

            render_export_preview(scn, tmp / "preview.png", gazebo=g, opts=opts)
            return {"target": to, "out": str(out), **g.__dict__}
        if to == "nav2":
            from .nav2 import export_nav2

            return {"target": to, "out": str(out), **export_nav2(scn, tmp, opts)}
        if to == "gis":
            from .gis import export_gis

            return {"target": to, "out": str(out), **export_gis(scn, tmp)}
        from .mesh import export_mesh

        return {"target": to, "out": str(out), **export_mesh(scn, tmp, opts)}


def _check_nav2_robot(data: dict[str, Any] | None) -> None:
    from .ros_robot import Nav2Robot

    if data is None:
        raise InputError(
            "nav2_robot",
            None,
            "the nav2 export needs the simulated robot's sensors and DWB configuration "
            "(the CLI passes baselines.nav2_robot.nav2_robot())",
        )
    Nav2Robot.from_dict(data)


def _check_robot(path: str | None) -> None:
    if path is None:
        raise InputError(
            "robot_urdf", None, "the nav2 export needs the robot URDF to spawn (the CLI passes it)"
        )
    p = Path(path)
    if not p.is_file() or p.suffix.lower() != ".urdf":
        raise InputError("robot_urdf", path, "allowed: an existing .urdf file")
