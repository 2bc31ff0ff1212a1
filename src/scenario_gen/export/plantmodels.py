"""Plant models for Gazebo: one model per species and growth, plus size variants.

A scenario gives every plant its own height (``crop.height_std``) while an SDF ``<include>``
cannot scale what it includes. So each species/growth (or the user's ``crop.model``) becomes one
*base* model holding the mesh and texture, and plants are binned into size variants
``SCALE_STEP`` apart whose model.sdf reuses the base mesh at that scale: a plant's height is then
off by at most half a step (1 %). Weeds grow continuously, so their growth is binned too
(``GROWTH_STEPS``); a crop field has one growth and keeps it exactly.

A user model (``crop.model``) in a format both Gazebos read — COLLADA that says ``Z_UP``, OBJ,
STL — is exported as its own files, as the seed world's ``<include>``s reference their maize:
copied into the base model's ``user/`` folder in their own layout, byte for byte but for
references not every loader reads as written (``_literal_references``) (a COLLADA
file's ``../materials/textures`` beside its ``meshes/``, an OBJ's material library and maps, an
archive's members), the visual naming the mesh with the ``<scale>`` and ``<pose>`` that put
its foot (``models.base_point``) on the plant and make it the plant's height. Other formats
(glTF, GLB, PLY, COLLADA in another or no up axis, which Gazebo would turn, and any model
declared y-up by ``crop.model_up_axis``) become a COLLADA mesh and its texture as the catalog
models do.

Collision proxy: a stem cylinder of the catalog's stem radius at the model's growth times the
plant's scale — the circle agrinav_gym counts crop contact with — as tall as the plant. Weeds
have none.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any
from urllib.parse import unquote
from xml.sax.saxutils import escape

import numpy as np

from ..arrays import FloatArray, IntArray
from ..crops import CATALOG, WEED_SPECIES, crop_mesh
from ..errors import InputError
from ..model import Scenario
from ..model_mesh import collada_up_axis
from ..models import UserModel, inspect_model, load_model, native_bounds, safe_extract
from .meshes import face_colours, flat_colour_mesh, save_png, textured_mesh, write_dae

SCALE_STEP = 1.02
GROWTH_STEPS = 16
MAX_EXACT_GROWTHS = 8  # more distinct growth values than this are binned


#: Mesh formats both Gazebo Classic 11 and Gazebo Sim read, referenced as they are.
REFERENCED = (".dae", ".obj", ".stl")
USER_DIR = "user"


@dataclass(frozen=True)
class UserFiles:
    """A user model exported as its own files into the base model's ``user/`` folder."""

    model: UserModel
    mesh: str  # the mesh's path inside the base model's folder (user/...), URI-safe
    lo: tuple[float, ...]  # its bounding box as Gazebo reads it (metres, +z up)
    hi: tuple[float, ...]
    base: tuple[float, float, float]  # where it stands (``models.base_point``), as read
    original: str | None = None  # the mesh's own path under user/ where ``mesh`` renames it

    def placement(self, height: float) -> tuple[float, FloatArray]:
        """Uniform scale and offset (before the plant's rotation) that stand the mesh on the
        plant's base point, ``height`` tall."""
        s = height / (self.hi[2] - self.lo[2])
        return s, -s * np.asarray(self.base, np.float64)

    def copy_into(self, folder: Path) -> None:
        """The model's files under ``folder``/user/ in their own layout, byte for byte but for
        references no loader may read as written (``_literal_references``)."""
        um = self.model
        dest = folder / USER_DIR
        if um.path.suffix.lower() == ".zip":
            safe_extract(um.path, dest)
        else:
            pairs = [(um.path, PurePosixPath(um.mesh if um.bundle else um.name))]
            pairs += [(um.root / rel, PurePosixPath(rel)) for rel, _ in um.files]
            for src, rel in pairs:
                (dest / rel).parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(src, dest / rel)
        # the mesh where it was copied (its own path is made URI-safe below)
        copied = self.original or str(PurePosixPath(self.mesh).relative_to(USER_DIR))
        _literal_references(dest / copied)
        if self.original is None:
            return
        # the folders and file on the mesh's own path take their URI-safe names (everything
        # under a renamed folder moves with it, so the mesh's relative references still hold)
        cur = dest
        safe = PurePosixPath(self.mesh).relative_to(USER_DIR).parts
        for o, n in zip(PurePosixPath(self.original).parts, safe, strict=True):
            if o != n:
                if (cur / n).exists():
                    raise InputError(
                        "crop.model",
                        str(um.path),
                        f"has both {o!r} and {n!r} where the export must rename the first to "
                        "the second (a Gazebo URI allows letters, digits and ._- only here)",
                    )
                (cur / o).rename(cur / n)
            cur = cur / n


#: A file name every loader reads as written (gz-common's URI checks, COLLADA loaders that do
#: not decode %-escapes, OBJ readers that split a line at its spaces).
_LITERAL = re.compile(r"^[A-Za-z0-9._/-]+$")
_INIT_FROM = re.compile(r"(<init_from>)([^<]+)(</init_from>)")
_OBJ_MAPS = ("map_kd", "map_ka", "map_ks", "map_ns", "map_d", "map_bump", "bump", "disp", "norm")


def _literal_references(mesh: Path) -> None:
    """Rename the copied files a mesh names by a reference not every loader reads as written
    (a space, a %-escape, a non-ASCII letter) and rewrite the reference to the new name: the
    same file, found by Gazebo Classic, Gazebo Sim and the export's own checker alike."""
    suffix = mesh.suffix.lower()
    done: dict[Path, Path] = {}  # a file named twice is renamed once
    if suffix == ".dae":
        text = mesh.read_text(encoding="utf-8", errors="surrogateescape")

        def swap(m: re.Match[str]) -> str:
            return m[1] + _renamed(mesh.parent, m[2].strip(), True, done) + m[3]

        new = _INIT_FROM.sub(swap, text)
        if new != text:
            mesh.write_text(new, encoding="utf-8", errors="surrogateescape")
    elif suffix == ".obj":
        for lib in _rewrite_lines(mesh, ("mtllib",), done):
            _rewrite_lines(mesh.parent / lib, _OBJ_MAPS, done)


def _rewrite_lines(path: Path, keys: tuple[str, ...], done: dict[Path, Path]) -> list[str]:
    """In an OBJ or MTL file, the files its ``keys`` statements name (the rest of the line,
    options first for maps) renamed to literal names; returns the names now written."""
    if not path.is_file():
        return []
    lines = path.read_text(encoding="utf-8", errors="surrogateescape").split("\n")
    named: list[str] = []
    for i, line in enumerate(lines):
        words = line.strip().split(None, 1)
        if len(words) != 2 or words[0].lower() not in keys:
            continue
        rest = words[1].strip()
        # the whole rest where it names a file (a name with spaces), else its last word
        name = rest if (path.parent / rest.replace("\\", "/")).is_file() else rest.split()[-1]
        new = _renamed(path.parent, name, False, done)
        named.append(new)
        if new != name:
            lines[i] = line[: line.index(rest)] + rest[: len(rest) - len(name)] + new
    path.write_text("\n".join(lines), encoding="utf-8", errors="surrogateescape")
    return named


def _renamed(folder: Path, ref: str, decode: bool, done: dict[Path, Path]) -> str:
    """``ref``'s file (relative to ``folder``) under a literal name beside it; the new
    reference (``ref`` itself where it is literal or names no copied file)."""
    if _LITERAL.match(ref):
        return ref
    name = (unquote(ref) if decode else ref).replace("\\", "/")
    old = Path(os.path.normpath(folder / name))
    # the folders on the way take literal names too ("tex ures/c.png"): the file is copied
    # there, its folder left as it was for whatever else names it
    parent = PurePosixPath(*(_literal_part(q) for q in PurePosixPath(name).parent.parts))
    if old not in done:
        if not old.is_file():
            return ref
        stem = re.sub(r"[^A-Za-z0-9._-]", "_", old.stem) or "file"
        suffix = re.sub(r"[^A-Za-z0-9.]", "_", old.suffix)
        at = Path(os.path.normpath(folder / parent))
        new, k = at / (stem + suffix), 1
        while new.exists() and new != old:
            new, k = at / f"{stem}_{k}{suffix}", k + 1
        if at == old.parent:
            old.rename(new)
        else:
            at.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(old, new)
        done[old] = new
    return str(parent / done[old].name) if str(parent) != "." else done[old].name


def _literal_part(part: str) -> str:
    """A folder name any loader reads as written (``..`` and ``.`` kept)."""
    if part in ("..", "."):
        return part
    return re.sub(r"[^A-Za-z0-9._-]", "_", part) or "folder"


def user_files(um: UserModel) -> UserFiles | None:
    """How ``um`` is exported by reference, or None where Gazebo would read it otherwise than
    the cameras do (see the module docstring)."""
    mesh = PurePosixPath(um.mesh if (um.bundle or um.path.suffix.lower() == ".zip") else um.name)
    if mesh.suffix.lower() not in REFERENCED or um.up_axis == "y":
        return None  # Gazebo would stand a y-up OBJ, STL or COLLADA on its side
    if mesh.suffix.lower() == ".dae":
        if um.path.suffix.lower() == ".zip":
            with tempfile.TemporaryDirectory(prefix="agrinav-export-") as tmp:
                safe_extract(um.path, tmp)
                up = collada_up_axis(Path(tmp) / mesh)
        else:
            up = collada_up_axis(um.path)
        if up != "Z_UP":
            return None
    lo, hi, base = native_bounds(um.path, um.up_axis)
    # gz-common's URIPath::Valid refuses non-ASCII (and older releases spaces, ?, = and &):
    # the mesh's own path gets names of letters, digits and ._- only
    safe = PurePosixPath(*(re.sub(r"[^A-Za-z0-9._-]", "_", part) for part in mesh.parts))
    return UserFiles(um, f"{USER_DIR}/{safe}", lo, hi, base, None if safe == mesh else str(mesh))


@dataclass(frozen=True, eq=False)
class PlantModel:
    name: str  # the base model's folder and model name
    species: str
    growth: float
    label: str
    mesh: Any  # trimesh: base at the origin, +z up, ``height`` tall
    height: float
    proxy_radius: float  # stem radius at this growth and nominal size, m; 0 = no collision
    source: str  # "catalog" or the user model's path
    user: UserFiles | None = None  # the user model's own files, referenced as they are

    def variant(self, step: int) -> str:
        """Folder/model name of the size variant ``SCALE_STEP ** step``."""
        if step == 0:
            return self.name
        return f"{self.name}_s{'p' if step > 0 else 'm'}{abs(step):02d}"


@dataclass(frozen=True, eq=False)
class Assignment:
    models: list[PlantModel]
    model: IntArray  # per plant: index into ``models``
    step: IntArray  # per plant: size variant, scale = SCALE_STEP ** step

    @property
    def scale(self) -> FloatArray:
        return np.asarray(SCALE_STEP ** self.step.astype(np.float64))

    def variants(self) -> list[tuple[int, int]]:
        """Distinct (model, step) pairs in use, sorted."""
        pairs = np.unique(np.column_stack([self.model, self.step]), axis=0)
        return [(int(m), int(s)) for m, s in pairs]


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_") or "model"


def _stage_label(species: str, growth: float) -> str:
    sp = CATALOG[species]
    stage = float(sp.stage_of_growth(growth))
    nearest = min(max(round(stage), 1), sp.stages)
    name = sp.stage_names[nearest - 1]
    return name if abs(stage - nearest) < 1e-6 else f"{name}~{stage:.2f}"


def user_model_path(scn: Scenario) -> Path | None:
    """The scenario's user plant model, refused up front if it is gone."""
    model = scn.spec.crop.model
    if model is None:
        return None
    p = Path(model)
    if not p.is_file():
        raise InputError(
            "crop.model",
            model,
            "the scenario's user plant model no longer exists; allowed: an existing mesh or .zip",
        )
    return p


def assign(scn: Scenario) -> Assignment:
    """Base models and size variants for every plant of ``scn``."""
    p = scn.plants
    user = user_model_path(scn)
    um = scn.crop_model
    if user is not None and um is None:  # a scenario made in memory from a spec
        um = inspect_model(user, scn.spec.crop.model_scale, scn.spec.crop.model_up_axis)
    ref = user_files(um) if um is not None else None
    models: list[PlantModel] = []
    model = np.zeros(len(p), np.int64)
    step = np.zeros(len(p), np.int64)
    for name in sorted(np.unique(p.species).tolist()):
        sp = CATALOG[name]
        idx = np.flatnonzero(p.species == name)
        growth = np.clip(sp.growth_of_stage(p.stage[idx]), 0.0, 1.0)
        if len(np.unique(np.round(growth, 6))) > MAX_EXACT_GROWTHS:
            growth = np.round(growth * GROWTH_STEPS) / GROWTH_STEPS
        keys, which = np.unique(np.round(growth, 6), return_inverse=True)
        for g, members in ((float(g), idx[which.ravel() == i]) for i, g in enumerate(keys)):
            nominal = float(sp.height(g))
            base = f"agrinav_{name}_g{round(g * 1000):04d}"
            mine = user is not None and um is not None and name != WEED_SPECIES
            if mine:
                assert user is not None and um is not None
                if um.scale == "native":
                    nominal = um.size[2]
                mesh = load_model(user, nominal, um.up_axis)
                base = f"agrinav_{_slug(user.stem)}_{name}_g{round(g * 1000):04d}"
                source = str(user)
            else:
                mesh = crop_mesh(name, g)
                source = "catalog"
            model[members] = len(models)
            ratio = np.maximum(p.height[members], 1e-6) / nominal
            step[members] = np.round(np.log(ratio) / math.log(SCALE_STEP)).astype(np.int64)
            models.append(
                PlantModel(
                    base,
                    name,
                    g,
                    f"{name} {_stage_label(name, g)}",
                    mesh,
                    nominal,
                    float(sp.stem_radius(g)),
                    source,
                    ref if mine else None,
                )
            )
    return Assignment(models, model, step)


# ----------------------------------------------------------------------------- SDF text
def fmt(*values: float, digits: int = 6) -> str:
    return " ".join(f"{v + 0.0:.{digits}f}" for v in values)


def static_model_sdf(name: str, parts: list[str], link: str | None = "link") -> str:
    """A static model's model.sdf: ``parts`` (XML elements) in one link named ``link``, or,
    with ``link`` None, straight in the model (the parts are links)."""
    if link is None:
        inner = "\n    ".join(parts)
    else:
        body = "\n      ".join(parts)
        inner = f'<link name="{link}">\n      {body}\n    </link>'
    return f"""<?xml version="1.0"?>
<sdf version="1.7">
  <model name="{name}">
    <static>true</static>
    {inner}
  </model>
</sdf>
"""


def model_config(name: str, description: str) -> str:
    return f"""<?xml version="1.0"?>
<model>
  <name>{escape(name)}</name>
  <version>1.0</version>
  <sdf version="1.7">model.sdf</sdf>
  <author><name>agrinav export</name><email>agrinav@localhost</email></author>
  <description>{escape(description)}</description>
</model>
"""


def stem_collision(name: str, pose: str, radius: float, length: float) -> str:
    return (
        f'<collision name="{name}"><pose>{pose}</pose><geometry><cylinder>'
        f"<radius>{radius:.5f}</radius><length>{length:.5f}</length>"
        f"</cylinder></geometry></collision>"
    )


def visual_xml(
    pm: PlantModel, height: float, name: str = "visual", rot: Any = None, pos: Any = None
) -> str:
    """A visual of ``pm``'s mesh ``height`` m tall, its base at ``pos`` turned by ``rot``
    (URDF rpy matrix; default: the model's own origin, upright)."""
    r = np.eye(3) if rot is None else np.asarray(rot, np.float64)
    at = np.zeros(3) if pos is None else np.asarray(pos, np.float64)
    if pm.user is not None:
        s, offset = pm.user.placement(height)
        uri = f"model://{pm.name}/{pm.user.mesh}"
    else:
        s, offset = height / pm.height, np.zeros(3)
        uri = f"model://{pm.name}/meshes/plant.dae"
    xyz = at + r @ offset
    rpy = _rpy(r)
    return (
        f'<visual name="{name}"><pose>{fmt(*xyz)} {fmt(*rpy, digits=7)}</pose>'
        f"<geometry><mesh><uri>{escape(uri)}</uri><scale>{fmt(s, s, s)}</scale></mesh>"
        "</geometry></visual>"
    )


def _rpy(r: FloatArray) -> tuple[float, float, float]:
    """URDF/SDF roll, pitch, yaw of R = Rz(yaw)·Ry(pitch)·Rx(roll)."""
    pitch = math.asin(max(-1.0, min(1.0, -float(r[2, 0]))))
    return (
        math.atan2(float(r[2, 1]), float(r[2, 2])),
        pitch,
        math.atan2(float(r[1, 0]), float(r[0, 0])),
    )


def plant_sdf(pm: PlantModel, step: int) -> str:
    scale = SCALE_STEP**step
    h = pm.height * scale
    col = (
        stem_collision("stem", fmt(0, 0, h / 2, 0, 0, 0), pm.proxy_radius * scale, h)
        if pm.proxy_radius > 0
        else ""
    )
    return static_model_sdf(pm.variant(step), [visual_xml(pm, h), col])


def write_models(
    models_dir: Path, a: Assignment, only_base: bool = False, only_user: bool = False
) -> list[str]:
    """Write every base model (mesh, texture; a referenced user model's own files) and, unless
    ``only_base``, every size variant; ``only_user``: the referenced user models alone."""
    written = []
    for m, pm in enumerate(a.models):
        if only_user and pm.user is None:
            continue
        folder = models_dir / pm.name
        folder.mkdir(parents=True)
        if pm.user is not None:
            pm.user.copy_into(folder)
        else:
            _write_mesh(folder, pm)
        desc = f"{pm.label}, {pm.height:.3f} m, from {pm.source}; agrinav export"
        (folder / "model.config").write_text(model_config(pm.name, desc))
        (folder / "model.sdf").write_text(plant_sdf(pm, 0))
        written.append(pm.name)
        if only_base:
            continue
        for mm, s in a.variants():
            if mm != m or s == 0:
                continue
            vfolder = models_dir / pm.variant(s)
            vfolder.mkdir()
            vdesc = f"{pm.label} at {SCALE_STEP**s:.4f}x ({pm.height * SCALE_STEP**s:.3f} m)"
            (vfolder / "model.config").write_text(model_config(pm.variant(s), vdesc))
            (vfolder / "model.sdf").write_text(plant_sdf(pm, s))
            written.append(pm.variant(s))
    return written


def _write_mesh(folder: Path, pm: PlantModel) -> None:
    """meshes/plant.dae and materials/textures/plant.png of ``pm``'s mesh."""
    (folder / "meshes").mkdir()
    (folder / "materials" / "textures").mkdir(parents=True)
    data = textured_mesh(pm.mesh)
    if data is None:
        data = flat_colour_mesh(
            np.asarray(pm.mesh.vertices, np.float64),
            np.asarray(pm.mesh.faces, np.int64),
            face_colours(pm.mesh),
        )
    md, image = data
    save_png(image, folder / "materials" / "textures" / "plant.png")
    write_dae(
        folder / "meshes" / "plant.dae",
        md,
        "../materials/textures/plant.png",
        pm.name,
        cutout=image.shape[2] == 4,
    )
