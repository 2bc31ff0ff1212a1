"""User plant models: a mesh file, or a .zip holding a mesh and its textures.

Archives are extracted defensively: absolute paths, ``..`` components, symbolic links, too many
members, too many bytes and implausible compression ratios (zip bombs) are refused before a
single byte is written.
"""

from __future__ import annotations

import stat
import tempfile
import zipfile
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from .errors import InputError
from .sources import MESH_SUFFIXES

MAX_MEMBERS = 1000
MAX_TOTAL_BYTES = 256 * 2**20
MAX_RATIO = 200.0


def safe_extract(archive: str | Path, dest: str | Path) -> list[Path]:
    """Extract ``archive`` into ``dest`` after checking every member; returns written files."""
    where = "crop.model"
    try:
        zf = zipfile.ZipFile(archive)
    except (zipfile.BadZipFile, OSError) as exc:
        raise InputError(where, str(archive), f"is not a readable zip archive ({exc})") from None
    with zf:
        infos = zf.infolist()
        if len(infos) > MAX_MEMBERS:
            raise InputError(
                where,
                f"{len(infos)} members",
                f"allowed: at most {MAX_MEMBERS} files in a model archive",
            )
        total = 0
        for info in infos:
            name = info.filename
            p = PurePosixPath(name.replace("\\", "/"))
            if (
                name.startswith(("/", "\\"))
                or (len(name) > 1 and name[1] == ":")
                or p.is_absolute()
            ):
                raise InputError(where, name, "absolute paths are not allowed in an archive")
            if ".." in p.parts:
                raise InputError(where, name, "'..' path components are not allowed (zip-slip)")
            mode = info.external_attr >> 16
            if stat.S_ISLNK(mode):
                raise InputError(where, name, "symbolic links are not allowed in an archive")
            total += info.file_size
            if total > MAX_TOTAL_BYTES:
                raise InputError(
                    where,
                    f"{total} bytes uncompressed",
                    f"allowed: at most {MAX_TOTAL_BYTES} bytes",
                )
            if info.compress_size and info.file_size / info.compress_size > MAX_RATIO:
                raise InputError(
                    where,
                    name,
                    f"compression ratio above {MAX_RATIO:.0f}:1 (zip bomb?) is not allowed",
                )
        out: list[Path] = []
        root = Path(dest).resolve()
        for info in infos:
            target = (root / info.filename.replace("\\", "/")).resolve()
            if root not in target.parents and target != root:
                raise InputError(where, info.filename, "resolves outside the extraction folder")
            if info.is_dir():
                target.mkdir(parents=True, exist_ok=True)
                continue
            target.parent.mkdir(parents=True, exist_ok=True)
            with zf.open(info) as src, open(target, "wb") as dst:
                remaining = info.file_size + 1
                while chunk := src.read(min(2**20, remaining)):
                    remaining -= len(chunk)
                    if remaining <= 0:
                        raise InputError(where, info.filename, "is larger than its header says")
                    dst.write(chunk)
            out.append(target)
    return out


def load_model(path: str | Path, height: float, up_axis: str = "auto") -> Any:
    """A user model scaled uniformly to ``height`` metres, base centred at the origin, +z up."""
    import trimesh

    p = Path(path)
    if not p.is_file():
        raise InputError("crop.model", str(path), "allowed: an existing mesh or .zip file")
    if p.suffix.lower() == ".zip":
        with tempfile.TemporaryDirectory(prefix="agrinav-model-") as tmp:
            files = safe_extract(p, tmp)
            meshes = sorted(f for f in files if f.suffix.lower() in MESH_SUFFIXES)
            if not meshes:
                raise InputError(
                    "crop.model", str(path), f"holds no mesh file ({', '.join(MESH_SUFFIXES)})"
                )
            return load_model(meshes[0], height, up_axis)
    if p.suffix.lower() not in MESH_SUFFIXES:
        raise InputError(
            "crop.model", str(path), f"allowed: a mesh ({', '.join(MESH_SUFFIXES)}) or a .zip"
        )
    try:
        mesh = trimesh.load(p, force="mesh")
    except Exception as exc:  # trimesh raises many types for malformed files
        raise InputError("crop.model", str(path), f"cannot be read as a mesh ({exc})") from None
    if len(getattr(mesh, "vertices", [])) < 3:
        raise InputError("crop.model", str(path), "holds no geometry")
    up = up_axis if up_axis != "auto" else ("y" if p.suffix.lower() in (".glb", ".gltf") else "z")
    if up == "y":
        mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    lo, hi = mesh.bounds
    extent = float(hi[2] - lo[2])
    if extent <= 0:
        raise InputError("crop.model", str(path), "is flat (zero height); allowed: a 3-D plant")
    mesh.apply_translation([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    mesh.apply_scale(height / extent)
    return mesh
