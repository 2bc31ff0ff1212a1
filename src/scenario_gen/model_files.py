"""The files a mesh file references: textures, material libraries, binary buffers.

A COLLADA model names its images (``<image><init_from>``), an OBJ its material libraries
(``mtllib``) whose maps name images (``map_Kd`` ...), a glTF its buffers and images (``uri``), a
PLY its texture (``comment TextureFile``). A copy of the mesh alone loses them, so a user model
is kept with all of them (``bundle``) or refused naming what is missing.

References are paths relative to the mesh's folder. They may climb out of it — Gazebo's model
layout keeps ``meshes/`` beside ``materials/textures/``, so a COLLADA file says
``../materials/textures/corn.png`` — at most ``MAX_UP_LEVELS`` folders; absolute paths and
URLs are refused (a copy could not keep them).
"""

from __future__ import annotations

import json
import os
import re
import struct
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from urllib.parse import unquote
from xml.etree import ElementTree

from .errors import InputError

#: How many folders above the mesh's own a referenced file may lie (Gazebo's layout: one).
MAX_UP_LEVELS = 2
#: Referenced files one model may have, and their bytes together.
MAX_FILES = 256
MAX_FILE_BYTES = 256 * 2**20
#: Bytes of a text mesh or material file read to find its references.
MAX_SCAN_BYTES = 64 * 2**20

_MTL_MAPS = (
    "map_kd",
    "map_ka",
    "map_ks",
    "map_ns",
    "map_d",
    "map_bump",
    "bump",
    "disp",
    "decal",
    "norm",
    "refl",
    "map_pr",
    "map_pm",
    "map_ke",
)
_URL = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")


@dataclass(frozen=True)
class Bundle:
    """A mesh and the files it references, all inside ``root``."""

    root: Path  # the deepest folder holding the mesh and every referenced file
    mesh: PurePosixPath  # the mesh, relative to root
    files: tuple[PurePosixPath, ...]  # the referenced files, relative to root, sorted

    @property
    def mesh_path(self) -> Path:
        return self.root / self.mesh


def references(path: Path) -> list[str]:
    """The files ``path`` references, as written (decoded), in order, without repeats."""
    suffix = path.suffix.lower()
    if suffix == ".dae":
        refs = _collada_refs(path)
    elif suffix == ".obj":
        refs = _obj_refs(path)
    elif suffix in (".gltf", ".glb"):
        refs = _gltf_refs(path)
    elif suffix == ".ply":
        refs = _ply_refs(path)
    else:
        refs = []
    return list(dict.fromkeys(r for r in refs if r))


def _read_text(path: Path) -> str:
    with open(path, "rb") as f:
        return f.read(MAX_SCAN_BYTES).decode("utf-8", "replace")


def _collada_refs(path: Path) -> list[str]:
    try:
        root = ElementTree.fromstring(_read_text(path))
    except ElementTree.ParseError:
        return []  # not XML: the mesh reader reports it as unreadable
    out = []
    for el in root.iter():
        if el.tag.rsplit("}", 1)[-1] != "image":
            continue
        for init in el:
            if init.tag.rsplit("}", 1)[-1] != "init_from":
                continue
            # COLLADA 1.4: <init_from>path</init_from>; 1.5: <init_from><ref>path</ref>
            ref = next((c.text for c in init if c.tag.rsplit("}", 1)[-1] == "ref"), init.text)
            if ref and ref.strip():
                out.append(unquote(ref.strip()))
    return out


def _obj_refs(path: Path) -> list[str]:
    libs = []
    for line in _read_text(path).splitlines():
        if line.startswith("mtllib"):
            rest = line[6:].strip()
            if rest:
                libs += [rest] if (path.parent / rest).is_file() else rest.split()
    out = list(libs)
    for lib in libs:
        mtl = path.parent / lib
        if mtl.is_file() and _inside(mtl, path.parent, MAX_UP_LEVELS):
            out += [str(PurePosixPath(lib).parent / m) for m in _mtl_maps(mtl)]
    return out


def obj_mtl_folders(path: Path) -> list[str]:
    """The folders (relative to the OBJ's, POSIX) of its material libraries other than its own:
    the folders their maps are named from."""
    out: list[str] = []
    for ref in _obj_refs(path):
        if ref.lower().endswith(".mtl"):
            parent = str(PurePosixPath(ref.replace("\\", "/")).parent)
            if parent != "." and parent not in out:
                out.append(parent)
    return out


def _mtl_maps(mtl: Path) -> list[str]:
    """Image files of a material library: the last word of a map statement (options first),
    or the whole rest of the line where that names a file (names with spaces)."""
    out = []
    for line in _read_text(mtl).splitlines():
        words = line.strip().split(None, 1)
        if len(words) == 2 and words[0].lower() in _MTL_MAPS:
            rest = words[1].strip()
            out.append(rest if (mtl.parent / rest).is_file() else rest.split()[-1])
    return out


def _gltf_refs(path: Path) -> list[str]:
    try:
        if path.suffix.lower() == ".glb":
            with open(path, "rb") as f:
                head = f.read(20)
                if len(head) < 20 or head[:4] != b"glTF":
                    return []
                length, kind = struct.unpack("<II", head[12:20])
                if kind != 0x4E4F534A or length > MAX_SCAN_BYTES:  # "JSON"
                    return []
                doc = json.loads(f.read(length))
        else:
            doc = json.loads(_read_text(path))
    except (ValueError, OSError):
        return []  # not JSON: the mesh reader reports it as unreadable
    if not isinstance(doc, dict):
        return []
    items = [*(doc.get("buffers") or []), *(doc.get("images") or [])]
    return [
        unquote(it["uri"])
        for it in items
        if isinstance(it, dict) and isinstance(it.get("uri"), str)
        if not it["uri"].startswith("data:")
    ]


def _ply_refs(path: Path) -> list[str]:
    with open(path, "rb") as f:
        head = f.read(65536)
    end = head.find(b"end_header")
    out = []
    for line in head[: max(end, 0)].decode("ascii", "replace").splitlines():
        words = line.split(None, 2)
        if len(words) == 3 and words[0] == "comment" and words[1] == "TextureFile":
            out.append(words[2].strip())
    return out


def _inside(p: Path, folder: Path, up: int) -> bool:
    """Whether ``p`` lies under ``folder`` or at most ``up`` levels above it (lexically)."""
    base = Path(os.path.normpath(folder))
    for _ in range(up):
        base = base.parent
    return Path(os.path.normpath(p)).is_relative_to(base)


#: Texture files by their suffix: each must open as an image (a loader that cannot read one
#: leaves the texture out without a word, and the plants turn the material's grey)
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tga", ".bmp", ".tif", ".tiff", ".gif", ".webp")


def _check_image(ref: str, path: Path, given: Path) -> None:
    if path.suffix.lower() not in IMAGE_SUFFIXES:
        return
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as im:
            im.verify()
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as exc:
        raise InputError(
            "crop.model",
            str(given),
            f"references {ref}, which is not an image that can be read ({exc}); allowed: "
            "PNG, JPEG, TGA, BMP, TIFF, GIF or WebP textures",
        ) from None


def bundle(mesh: Path, given: Path | None = None, limit_root: Path | None = None) -> Bundle:
    """``mesh`` with every file it references, checked: each a relative path that exists as a
    regular file at most ``MAX_UP_LEVELS`` folders above the mesh (and inside ``limit_root``
    when given: an extracted archive). Refused in one line naming what is missing."""
    given = given or mesh
    folder = Path(os.path.normpath(mesh.parent.absolute()))
    refs = references(mesh)
    if len(refs) > MAX_FILES:
        raise InputError(
            "crop.model", str(given), f"references {len(refs)} files; allowed: at most {MAX_FILES}"
        )
    bad = [r for r in refs if _URL.match(r) or PurePosixPath(r.replace("\\", "/")).is_absolute()]
    if bad:
        raise InputError(
            "crop.model",
            str(given),
            f"references {', '.join(bad[:3])} by an absolute path or URL; allowed: paths "
            "relative to the mesh's folder (a copy of the model keeps only those)",
        )
    paths = [Path(os.path.normpath(folder / r.replace("\\", "/"))) for r in refs]
    limit = Path(os.path.normpath(limit_root.absolute())) if limit_root is not None else None
    far = [
        r
        for r, p in zip(refs, paths, strict=True)
        if not _inside(p, folder, MAX_UP_LEVELS)
        or (limit is not None and not p.is_relative_to(limit))
    ]
    if far:
        where = "the archive" if limit is not None else f"{MAX_UP_LEVELS} folders above the mesh"
        raise InputError(
            "crop.model",
            str(given),
            f"references {', '.join(far[:3])} outside {where}; allowed: files beside the mesh "
            "or in folders near it (as Gazebo's meshes/ and materials/textures/)",
        )
    links = [r for r, p in zip(refs, paths, strict=True) if p.is_symlink()]
    if links:  # a copy of the model would hold a link to a file that is not in it
        raise InputError(
            "crop.model",
            str(given),
            f"references {', '.join(links[:3])}, a symbolic link; allowed: the file itself "
            "(copy it beside the mesh)",
        )
    missing = [r for r, p in zip(refs, paths, strict=True) if not p.is_file()]
    if missing:
        more = f" and {len(missing) - 3} more" if len(missing) > 3 else ""
        # inside an archive the folder is a temporary extraction: name the member's folder
        where = (
            f"in the archive's {PurePosixPath(folder.relative_to(limit).as_posix())}/"
            if limit is not None and folder.is_relative_to(limit)
            else f"beside the mesh, in {folder}"
        )
        raise InputError(
            "crop.model",
            str(given),
            f"references {', '.join(missing[:3])}{more}, which "
            f"{'is' if len(missing) == 1 else 'are'} missing (looked for {where}); allowed: "
            "a model with all its files (or a .zip holding them)",
        )
    total = sum(p.stat().st_size for p in paths)
    if total > MAX_FILE_BYTES:
        raise InputError(
            "crop.model",
            str(given),
            f"references {total:,} bytes of files; allowed: at most {MAX_FILE_BYTES:,}",
        )
    for r, p in zip(refs, paths, strict=True):
        _check_image(r, p, given)
    root = Path(os.path.commonpath([folder, *(p.parent for p in paths)]))
    rel = tuple(sorted({PurePosixPath(p.relative_to(root).as_posix()) for p in paths}))
    mesh_rel = PurePosixPath((folder / mesh.name).relative_to(root).as_posix())
    return Bundle(root, mesh_rel, tuple(r for r in rel if r != mesh_rel))
