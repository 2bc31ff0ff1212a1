"""What the studio's buttons do, as plain functions (the page runs them in a worker thread).

Every action checks all of its input before it writes anything, like the CLI: a bad value, a
field off the terrain or an existing output folder raises ``InputError`` and leaves the disk as
it was.
"""

from __future__ import annotations

import dataclasses
import filecmp
import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

from scenario_gen.atomic import atomic_write_text, check_output_dir
from scenario_gen.errors import InputError

from .session import Session, field_file

#: Policies the page offers: names ``policies.make_policy`` takes.
POLICIES = ("dwb", "rpp", "stanley", "blind", "ppo:shipped")
RUN_ENV = "AgriNav/FieldRoute-v3"


#: the workspace's folder of uploaded crop models (``Studio.models_dir``)
MODELS_DIR = "models"


def inside_workspace(out: str, workspace: Path) -> None:
    """Refuse an output folder outside ``workspace`` (the page writes nowhere else), or in its
    folder of uploaded models: a scenario saved there, then overwritten, took the models."""
    target = Path(os.path.abspath(out)).resolve()
    root = workspace.resolve()
    if target == root or not target.is_relative_to(root):
        raise InputError("out", out, f"allowed: a folder inside the studio's workspace {root}")
    models = root / MODELS_DIR
    if target == models or target.is_relative_to(models):
        raise InputError(
            "out",
            out,
            f"is the uploaded crop models' folder {models}; allowed: another folder of the "
            "workspace",
        )


def generate_and_save(
    session: Session, out: str, overwrite: bool = False, workspace: Path | None = None
) -> dict[str, Any]:
    """Generate the session's scenario and save it to ``out`` (and the drawn field beside it).

    The scenario is generated in memory first, from a temporary copy of the field file, so
    nothing is written unless generation succeeds; the field file then goes next to the folder
    (``<out>.field.geojson``), which ``scenario.json`` and the copied command refer to.
    """
    from scenario_gen import generate, save

    if not out or not out.strip():
        raise InputError("out", out, "allowed: a folder path")
    if workspace is not None:
        inside_workspace(out, workspace)
    check_output_dir(out, overwrite)
    path = field_file(out) if session.field_text is not None else None
    spec = session.spec(str(path) if path is not None else None)
    if path is not None:
        assert session.field_text is not None
        if path.exists() and not overwrite and path.read_text() != session.field_text:
            raise InputError("out", str(path), "exists with another field; allowed: overwrite")
        with tempfile.TemporaryDirectory(prefix="agrinav-studio-") as tmp:
            probe = Path(tmp) / "field.geojson"
            probe.write_text(session.field_text)
            scn = generate(session.spec(str(probe)), session.seed)
        scn = dataclasses.replace(scn, spec=spec)  # same bits as read from ``path``
    else:
        scn = generate(spec, session.seed)
    previous = path.read_text() if path is not None and path.exists() else None
    if path is not None:
        assert session.field_text is not None
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(path, session.field_text)
    try:
        save(scn, out, overwrite=overwrite)
    except BaseException:
        if path is not None:  # put the field file back as it was
            if previous is None:
                path.unlink(missing_ok=True)
            else:
                atomic_write_text(path, previous)
        raise
    return {**scn.summary(), "out": out, "field_file": str(path) if path else None}


def run_policy(
    scenario: str, policy: str, out: str, seed: int = 1_000_000_000, overwrite: bool = False
) -> dict[str, Any]:
    """One episode of ``policy`` on the saved scenario: metrics and the trajectory figure."""
    from baselines.bench import run

    if policy not in POLICIES:
        raise InputError("policy", policy, f"allowed: one of {', '.join(POLICIES)}")
    if not (Path(scenario) / "scenario.json").is_file():
        raise InputError("scenario", scenario, "generate and save the scenario first")
    records = run(RUN_ENV, policy, seed, 1, out, scenario=scenario, force=overwrite)
    return {**records[0], "figure": str(Path(out) / "trajectory_000.png")}


def export_formats() -> tuple[str, ...]:
    """The export targets (``gazebo``, ``nav2``, ``gis``, ``mesh``)."""
    from scenario_gen.export import TARGETS

    return TARGETS


def export(scenario: str, fmt: str, out: str, overwrite: bool = False) -> dict[str, Any]:
    """Export a saved scenario through ``scenario_gen.export.export`` with the CLI's defaults
    (``agrinav export DIR --to FMT --out OUT``; the Nav2 bundle spawns the simulated robot's
    URDF); it checks everything before writing."""
    from scenario_gen.export import TARGETS, ExportOptions
    from scenario_gen.export import export as export_to

    from ..nav2_robot import nav2_options

    if fmt not in TARGETS:
        raise InputError("export", fmt, f"allowed: one of {', '.join(TARGETS)}")
    if not (Path(scenario) / "scenario.json").is_file():
        raise InputError("scenario", scenario, "generate and save the scenario first")
    data: dict[str, Any] = nav2_options() if fmt == "nav2" else {}
    info: dict[str, Any] = export_to(
        scenario, fmt, out, ExportOptions.from_dict(data), overwrite=overwrite, what="out"
    )
    return info


def install_model(upload: Path, name: str, models_dir: Path, height: float) -> Path:
    """Check an uploaded crop model (mesh or .zip) like the CLI does, then keep it.

    The archive goes through ``scenario_gen.models.load_model`` (``safe_extract``'s checks and a
    mesh load) from a temporary file; only a model that loads is copied into ``models_dir``.
    """
    from scenario_gen.models import load_model
    from scenario_gen.sources import MESH_SUFFIXES

    safe = Path(name).name
    if (
        not safe
        or safe.startswith(".")
        or Path(safe).suffix.lower() not in (*MESH_SUFFIXES, ".zip")
    ):
        raise InputError(
            "crop.model", name, f"allowed: a mesh ({', '.join(MESH_SUFFIXES)}) or a .zip"
        )
    with tempfile.TemporaryDirectory(prefix="agrinav-model-") as tmp:
        probe = Path(tmp) / safe
        shutil.copyfile(upload, probe)
        try:
            load_model(probe, height)
        except InputError as exc:  # in the uploaded file's name, not the temporary copy's
            raise InputError(
                exc.field,
                safe if str(exc.value) == str(probe) else exc.value,
                exc.allowed.replace(str(probe), safe).replace(tmp, "the upload"),
            ) from None
    models_dir.mkdir(parents=True, exist_ok=True)
    # Another model of the same name is kept, not replaced: a field drawn with it, and the
    # equivalent command shown for it, name that file. The same model again is that file.
    stem, suffix = Path(safe).stem, Path(safe).suffix
    target = models_dir / safe
    n = 1
    while target.exists() and not filecmp.cmp(target, upload, shallow=False):
        n += 1
        target = models_dir / f"{stem}-{n}{suffix}"
    if target.exists():
        return target
    tmp_target = models_dir / f".{target.name}.tmp"
    shutil.copyfile(upload, tmp_target)
    tmp_target.replace(target)
    return target


def metrics_rows(record: dict[str, Any]) -> list[dict[str, str]]:
    """The run's metrics as (metric, value) rows for a table."""
    from baselines.report import METRICS

    rows = []
    for key in (*METRICS, "steps", "termination"):
        v = record.get(key)
        rows.append({"metric": key, "value": "—" if v is None else _fmt(v)})
    return rows


def _fmt(v: Any) -> str:
    return f"{v:.3f}" if isinstance(v, float) else json.dumps(v) if not isinstance(v, str) else v
