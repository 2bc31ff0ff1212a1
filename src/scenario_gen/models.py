"""User plant models: a mesh file with the files it references, or a .zip holding them.

Archives are extracted defensively: absolute paths, ``..`` components, symbolic links, too many
members, too many bytes and implausible compression ratios (zip bombs) are refused before a
single byte is written. An archive must hold exactly one mesh file (two are refused, naming
both). A mesh file is kept with every file it references (``model_files``: a COLLADA file's
textures, an OBJ's material library and its maps, a glTF's buffers and images), which must
exist; a missing one is refused by name. The copy a scenario keeps in ``models/`` is then
complete: a single file as ``models/<file name>``, a mesh with references as
``models/<mesh stem>/`` holding them in their folders as they were (``meshes/corn.dae`` and
``materials/textures/corn.png``).

``inspect_model`` checks a model and records what a scenario keeps of it (``UserModel``: files,
content hashes, native size, scale rule, the proxy camera's shape); ``load_model`` gives the
mesh scaled to a height with the file's own colours (``model_mesh``).
"""

from __future__ import annotations

import hashlib
import re
import stat
import tempfile
import warnings
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np

from .errors import InputError, Notice
from .model_files import Bundle, bundle
from .model_mesh import (
    bad_vertices,
    check_gltf,
    collada_unit,
    file_up_axis,
    one_mesh,
    processed,
    read_scene,
)
from .model_shape import ProxyShape, proxy_shape
from .sources import MESH_SUFFIXES

MAX_MEMBERS = 1000
MAX_TOTAL_BYTES = 256 * 2**20
MAX_RATIO = 200.0
#: Triangles one crop model may have: every plant instance is drawn with all of them, and
#: the mesh camera's cost grows with the triangles under each pixel (a 100k-triangle model
#: made one 848 × 480 frame take minutes). Plant models made for simulation have 1-20k.
MAX_MODEL_TRIANGLES = 50_000
#: ``crop.model_up_axis``: the axis a model's file stands along
UP_AXES = ("auto", "y", "z")
#: How a model becomes each plant (``crop.model_scale``): recorded in scenario.json.
SCALE_RULES = {
    "stage": "uniform scale = plant height / native_size[2] (the plant heights follow the growth "
    "stage); base centred on the plant position, +z up (glTF/GLB are turned from +y up)",
    "native": "uniform scale = plant height / native_size[2] (the plant heights are the model's "
    "own native_size[2], metres, times the height spread); base centred on the plant position, "
    "+z up (glTF/GLB are turned from +y up)",
}


@dataclass(frozen=True)
class UserModel:
    """A user plant model as a scenario records it."""

    path: Path  # the mesh file now: the user's at generation, the folder's copy after ``load``
    name: str  # file name of the mesh (or the .zip)
    sha256: str  # of the file's bytes
    mesh: str  # the mesh: the .zip member, the file name, or its path in the bundle
    size: tuple[float, float, float]  # native bounding box (x, y, z), metres, +z up
    source: str  # absolute path of the user's file when the scenario was generated
    files: tuple[tuple[str, str], ...] = ()  # referenced files: (path in the bundle, sha256)
    bundle: str | None = None  # the folder under models/ of a mesh kept with its files
    scale: str = "stage"  # crop.model_scale
    shape: ProxyShape | None = None  # the proxy camera's cylinders for this model
    up_axis: str = "auto"  # crop.model_up_axis

    @property
    def file(self) -> str:
        """Path of the mesh's copy relative to a scenario folder."""
        if self.bundle is not None:
            return f"models/{self.bundle}/{self.mesh}"
        return f"models/{self.name}"

    @property
    def root(self) -> Path:
        """The folder holding the mesh and its referenced files (``files`` are relative to it)."""
        if self.bundle is None:
            return self.path.parent
        return self.path.parents[len(PurePosixPath(self.mesh).parts) - 1]

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "file": self.file,
            "sha256": self.sha256,
            "mesh": self.mesh,
            "native_size": list(self.size),
            "model_scale": self.scale,
            "model_up_axis": self.up_axis,
            "scale": SCALE_RULES[self.scale],
            "source": self.source,
        }
        if self.files:
            out["files"] = [{"path": p, "sha256": h} for p, h in self.files]
        if self.shape is not None:
            out["proxy"] = self.shape.to_dict()
        return out


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


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("._") or "model"


@contextmanager
def _mesh_of(p: Path) -> Iterator[tuple[Path, Bundle, str]]:
    """The mesh file of a model (extracted from a .zip into a temporary folder), its bundle
    (references checked) and its name in the archive (or the file name)."""
    if p.suffix.lower() == ".zip":
        with tempfile.TemporaryDirectory(prefix="agrinav-model-") as tmp:
            root = Path(tmp).resolve()
            mesh_path = _one_mesh(safe_extract(p, tmp), root, p)
            member = mesh_path.relative_to(root).as_posix()
            yield mesh_path, bundle(mesh_path, p, limit_root=root), member
    else:
        yield p, bundle(p, p), p.name


def inspect_model(path: str | Path, scale: str = "stage", up_axis: str = "auto") -> UserModel:
    """Check a user model completely and record it (hashes, mesh, native size, proxy shape)."""
    p = Path(path).expanduser().resolve()
    _check_file(p)
    if scale not in SCALE_RULES:
        raise InputError("crop.model_scale", scale, f"allowed: {', '.join(SCALE_RULES)}")
    if up_axis not in UP_AXES:
        raise InputError("crop.model_up_axis", up_axis, f"allowed: {', '.join(UP_AXES)}")
    with _mesh_of(p) as (mesh_path, b, member):
        native = _read_mesh(mesh_path, p, up_axis)
        lo, hi = native.bounds
        size = (float(hi[0] - lo[0]), float(hi[1] - lo[1]), float(hi[2] - lo[2]))
        if max(size[:2]) > LYING_RATIO * size[2]:
            up = resolved_up_axis(mesh_path, up_axis, p)
            other = "z" if up == "y" else "y"
            warnings.warn(
                Notice(
                    f"crop.model {p.name} stands {size[2]:.3g} tall and {max(size[:2]):.3g} "
                    f"across along {up} (crop.model_up_axis {up_axis}): if it lies on its side, "
                    f"set crop.model_up_axis={other}"
                ),
                stacklevel=2,
            )
        shape = proxy_shape(_placed(native, 1.0))
        files: tuple[tuple[str, str], ...] = ()
        kept_as: str | None = None
        if p.suffix.lower() != ".zip" and b.files:  # kept with its files, in their folders
            files = tuple((str(f), sha256_file(b.root / f)) for f in b.files)
            member = str(b.mesh)
            kept_as = _slug(p.stem)
    return UserModel(
        p, p.name, sha256_file(p), member, size, str(p), files, kept_as, scale, shape, up_axis
    )


def model_shape(um: UserModel) -> ProxyShape:
    """The proxy camera's shape of a recorded model: the one scenario.json keeps, or (a
    scenario saved before it was recorded) measured from the model now."""
    if um.shape is not None:
        return um.shape
    return _measured_shape(str(um.path), um.sha256, um.up_axis)


@lru_cache(maxsize=8)
def _measured_shape(path: str, sha256: str, up_axis: str) -> ProxyShape:
    return proxy_shape(load_model(path, 1.0, up_axis))


def load_model(path: str | Path, height: float, up_axis: str = "auto") -> Any:
    """A user model scaled uniformly to ``height`` metres, standing on its ``base_point`` at
    the origin, +z up,
    with its file's colours and textures (an RGBA atlas: alpha 0 marks cut-outs)."""
    p = Path(path)
    _check_file(p)
    with _mesh_of(p) as (mesh_path, _, _):
        mesh = _read_mesh(mesh_path, p, up_axis)
    return _placed(mesh, height)


def native_bounds(
    path: str | Path, up_axis: str = "auto"
) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, float, float]]:
    """The model's bounding box and ``base_point`` as read (metres, +z up), before it is
    placed and scaled: what an exporter that references the file itself needs to place it."""
    p = Path(path)
    _check_file(p)
    with _mesh_of(p) as (mesh_path, _, _):
        mesh = _read_mesh(mesh_path, p, up_axis)
    lo, hi = mesh.bounds
    return tuple(float(v) for v in lo), tuple(float(v) for v in hi), base_point(mesh)


def _unreadable(p: Path, exc: Exception) -> str:
    """Why a mesh file did not load, in the file's terms: trimesh reads a .gltf that is not
    JSON as a binary file and reports a missing internal key."""
    if p.suffix.lower() == ".gltf":
        import json

        try:
            json.loads(p.read_text(encoding="utf-8-sig"))
        except (ValueError, OSError) as bad:
            return f"not valid glTF JSON: {bad}"
    return f"{type(exc).__name__}: {exc}"


def resolved_up_axis(p: Path, up_axis: str, given: Path | None = None) -> str:
    """``crop.model_up_axis`` for the mesh file ``p`` (``given`` names it):
    ``model_mesh.file_up_axis``'s rule."""
    return file_up_axis(p, up_axis, "crop.model", "crop.model_up_axis", given)


#: a model read this many times wider than tall most likely lies on its side (a maize plant
#: is about as wide as tall; a spreading crop two or three times)
LYING_RATIO = 4.0


#: the slice at the foot of a model whose vertices place it: its lowest 2 % of height (a
#: stalk's foot; a head's or a pot's bottom)
BASE_SLICE = 0.02


def base_point(mesh: Any) -> tuple[float, float, float]:
    """Where a model stands on its plant's position: the centre of the box of its vertices in
    its lowest ``BASE_SLICE`` of height (a stalk's foot, wherever its leaves reach: the whole
    model's box put a one-sided plant's stalk up to half a metre off its plant), at its lowest
    z. A box, not a mean: a seam's duplicated vertices weigh nothing."""
    v = np.asarray(mesh.vertices, np.float64)
    z0, z1 = float(v[:, 2].min()), float(v[:, 2].max())
    foot = v[v[:, 2] <= z0 + BASE_SLICE * (z1 - z0)]
    lo, hi = foot[:, :2].min(axis=0), foot[:, :2].max(axis=0)
    return float(0.5 * (lo[0] + hi[0])), float(0.5 * (lo[1] + hi[1])), z0


def _placed(mesh: Any, height: float) -> Any:
    """A copy of ``mesh`` standing at the origin on its ``base_point``, scaled to ``height``."""
    out = mesh.copy()
    x, y, z = base_point(out)
    extent = float(out.bounds[1][2] - out.bounds[0][2])
    out.apply_translation([-x, -y, -z])
    out.apply_scale(height / extent)
    return out


def _read_mesh(p: Path, given: Path, up_axis: str = "auto") -> Any:
    """The mesh in ``p`` turned +z up, in metres, checked to be a 3-D object (``given`` names
    it)."""
    import trimesh

    if p.suffix.lower() in (".gltf", ".glb"):
        check_gltf(p, given)
    try:
        scene = read_scene(p)
        bad, total = bad_vertices(scene)
        if bad:
            raise InputError(
                "crop.model",
                str(given),
                f"has NaN or infinite coordinates in {bad:,} of its {total:,} vertices; "
                "allowed: finite coordinates (re-export it from the modelling tool)",
            )
        processed(scene)
        unit = collada_unit(p) if p.suffix.lower() == ".dae" else 1.0
        mesh = one_mesh(scene, unit, gltf=p.suffix.lower() in (".gltf", ".glb"))
    except InputError:
        raise
    except Exception as exc:  # trimesh raises many types for malformed files
        raise InputError(
            "crop.model", str(given), f"cannot be read as a mesh ({_unreadable(p, exc)})"
        ) from None
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
    up = resolved_up_axis(p, up_axis, given)
    if up == "y":
        mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    lo, hi = mesh.bounds
    if float(hi[2] - lo[2]) <= 0:
        raise InputError("crop.model", str(given), "is flat (zero height); allowed: a 3-D plant")
    return mesh
