"""User plant models: a mesh file, or a .zip holding one mesh and its textures.

Archives are extracted defensively: absolute paths, ``..`` components, symbolic links, too many
members, too many bytes and implausible compression ratios (zip bombs) are refused before a
single byte is written. An archive must hold exactly one mesh file (two are refused, naming
both). A single-file model must not reference other files (a glTF's external buffers or
images, an OBJ's material library): those come with it in a .zip, so that the copy a scenario
keeps in ``models/`` is complete.

``inspect_model`` checks a model and records what a scenario keeps of it (``UserModel``: file,
content hash, native size, scale rule); ``load_model`` gives the mesh scaled to a height.
"""

from __future__ import annotations

import hashlib
import json
import stat
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from .errors import InputError
from .sources import MESH_SUFFIXES

MAX_MEMBERS = 1000
MAX_TOTAL_BYTES = 256 * 2**20
MAX_RATIO = 200.0
#: Triangles one crop model may have: every plant instance is drawn with all of them, and
#: the mesh camera's cost grows with the triangles under each pixel (a 100k-triangle model
#: made one 848 × 480 frame take minutes). Plant models made for simulation have 1-20k.
MAX_MODEL_TRIANGLES = 50_000
#: How a model becomes each plant: recorded in scenario.json next to the model.
SCALE_RULE = (
    "uniform scale = plant height / native_size[2]; base centred on the plant position, +z up "
    "(glTF/GLB are turned from +y up)"
)


@dataclass(frozen=True)
class UserModel:
    """A user plant model as a scenario records it."""

    path: Path  # the file now: the user's at generation, the folder's copy after ``load``
    name: str  # file name; a saved scenario keeps a copy as models/<name>
    sha256: str  # of the file's bytes
    mesh: str  # the mesh inside: the .zip member, or the file name itself
    size: tuple[float, float, float]  # native bounding box (x, y, z), model units, +z up
    source: str  # absolute path of the user's file when the scenario was generated

    @property
    def file(self) -> str:
        """Path of the copy relative to a scenario folder."""
        return f"models/{self.name}"

    def to_dict(self) -> dict[str, Any]:
        return {
            "file": self.file,
            "sha256": self.sha256,
            "mesh": self.mesh,
            "native_size": list(self.size),
            "scale": SCALE_RULE,
            "source": self.source,
        }


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
            if not p.parts or name.replace("\\", "/").rstrip("/").split("/")[-1] == ".":
                raise InputError(where, name, "a member must name a file or folder (not '.')")
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


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(1 << 20):
            h.update(chunk)
    return h.hexdigest()


def _external_refs(p: Path) -> list[str]:
    """Files a single-file model references (which a copy of that file alone would lose)."""
    suffix = p.suffix.lower()
    if suffix == ".gltf":
        try:
            doc = json.loads(p.read_text())
        except (ValueError, UnicodeDecodeError):
            return []  # not JSON: trimesh reports it as unreadable
        items = [*(doc.get("buffers") or []), *(doc.get("images") or [])]
        return [
            str(it["uri"])
            for it in items
            if isinstance(it, dict)
            and isinstance(it.get("uri"), str)
            and not it["uri"].startswith("data:")
        ]
    if suffix == ".obj":
        with open(p, "rb") as f:
            return [
                line.split(None, 1)[1].decode("utf-8", "replace").strip()
                for line in f
                if line.startswith(b"mtllib") and len(line.split(None, 1)) == 2
            ]
    return []


def _one_mesh(files: list[Path], root: Path, archive: Path) -> Path:
    meshes = sorted(f for f in files if f.suffix.lower() in MESH_SUFFIXES)
    if not meshes:
        raise InputError(
            "crop.model", str(archive), f"holds no mesh file ({', '.join(MESH_SUFFIXES)})"
        )
    if len(meshes) > 1:
        names = ", ".join(str(m.relative_to(root)) for m in meshes[:4])
        raise InputError(
            "crop.model",
            str(archive),
            f"holds {len(meshes)} meshes ({names}{', ...' if len(meshes) > 4 else ''}); "
            "allowed: exactly one mesh per archive",
        )
    return meshes[0]


def _check_file(p: Path) -> None:
    if not p.is_file():
        raise InputError("crop.model", str(p), "allowed: an existing mesh or .zip file")
    size = p.stat().st_size
    if size > MAX_TOTAL_BYTES:
        raise InputError(
            "crop.model", str(p), f"is {size} bytes; allowed: at most {MAX_TOTAL_BYTES}"
        )
    suffix = p.suffix.lower()
    if suffix != ".zip" and suffix not in MESH_SUFFIXES:
        raise InputError(
            "crop.model", str(p), f"allowed: a mesh ({', '.join(MESH_SUFFIXES)}) or a .zip"
        )


def inspect_model(path: str | Path) -> UserModel:
    """Check a user model completely and record it (hash, mesh, native size)."""
    p = Path(path).expanduser().resolve()
    _check_file(p)
    if p.suffix.lower() == ".zip":
        with tempfile.TemporaryDirectory(prefix="agrinav-model-") as tmp:
            mesh_path = _one_mesh(safe_extract(p, tmp), Path(tmp).resolve(), p)
            mesh_name = str(mesh_path.relative_to(Path(tmp).resolve()))
            native = _read_mesh(mesh_path, p)
    else:
        refs = _external_refs(p)
        if refs:
            raise InputError(
                "crop.model",
                str(p),
                f"references other files ({', '.join(refs[:3])}) that a copy of it alone would "
                "lose; allowed: the model and those files together in one .zip",
            )
        mesh_name = p.name
        native = _read_mesh(p, p)
    lo, hi = native.bounds
    size = tuple(float(v) for v in hi - lo)
    return UserModel(p, p.name, sha256_file(p), mesh_name, size, str(p))  # type: ignore[arg-type]


def load_model(path: str | Path, height: float, up_axis: str = "auto") -> Any:
    """A user model scaled uniformly to ``height`` metres, base centred at the origin, +z up."""
    p = Path(path)
    _check_file(p)
    if p.suffix.lower() == ".zip":
        with tempfile.TemporaryDirectory(prefix="agrinav-model-") as tmp:
            mesh_path = _one_mesh(safe_extract(p, tmp), Path(tmp).resolve(), p)
            mesh = _read_mesh(mesh_path, p, up_axis)
    else:
        mesh = _read_mesh(p, p, up_axis)
    lo, hi = mesh.bounds
    extent = float(hi[2] - lo[2])
    mesh.apply_translation([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    mesh.apply_scale(height / extent)
    return mesh


def _read_mesh(p: Path, given: Path, up_axis: str = "auto") -> Any:
    """The mesh in ``p`` turned +z up, checked to be a 3-D object (``given`` names it)."""
    import trimesh

    try:
        mesh = trimesh.load(p, force="mesh")
    except Exception as exc:  # trimesh raises many types for malformed files
        raise InputError("crop.model", str(given), f"cannot be read as a mesh ({exc})") from None
    v = np.asarray(getattr(mesh, "vertices", np.empty((0, 3))))
    if len(v) < 3 or len(getattr(mesh, "faces", [])) == 0:
        raise InputError("crop.model", str(given), "holds no geometry")
    if not np.isfinite(v).all():
        raise InputError("crop.model", str(given), "has NaN or infinite vertex coordinates")
    n_faces = len(getattr(mesh, "faces", []))
    if n_faces > MAX_MODEL_TRIANGLES:
        raise InputError(
            "crop.model",
            str(given),
            f"has {n_faces:,} triangles; allowed: at most {MAX_MODEL_TRIANGLES:,} (decimate it "
            "first, e.g. Blender's Decimate modifier: every plant is drawn with all of them)",
        )
    if not float(getattr(mesh, "area", 0.0)) > 0.0:
        raise InputError("crop.model", str(given), "has no surface area (degenerate triangles)")
    up = up_axis if up_axis != "auto" else ("y" if p.suffix.lower() in (".glb", ".gltf") else "z")
    if up == "y":
        mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    lo, hi = mesh.bounds
    if float(hi[2] - lo[2]) <= 0:
        raise InputError("crop.model", str(given), "is flat (zero height); allowed: a 3-D plant")
    return mesh
