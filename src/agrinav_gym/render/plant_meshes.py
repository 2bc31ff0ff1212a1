"""Plant geometry for the sensors: shared prototype meshes and one placement per plant.

Every plant of a scenario is an *instance*: a prototype mesh (a catalog model at a growth node,
or the user's model) placed with the plant's x, y, z, roll, pitch, yaw (URDF rpy,
R = Rz·Ry·Rx) and a uniform scale (plant height / prototype height). Plants share prototypes;
per plant this keeps a prototype index and a scale next to the scenario's own arrays (6 bytes).

Growth is quantized per species into ``Species.mesh_intervals`` equal steps (nodes at
k / n, so every catalog stage is a node): the counts are the smallest, among multiples of the
species' stage intervals, whose mean surface distance between a model at a random growth and its
node's model (scaled to the same height) is at most 6 mm — the D455's depth RMS at 1.8 m in the
848×480 mode. ``benchmarks/growth_bins.py`` measures it (table in docs/camera.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from scenario_gen import CATALOG, Scenario
from scenario_gen.arrays import F32, FloatArray
from scenario_gen.crops import WEED_SPECIES, crop_mesh

from .classes import CROP, WEED


def growth_intervals(name: str) -> int:
    """Growth steps kept for species ``name`` (nodes 0, 1/n, ..., 1): its catalog entry's
    ``mesh_intervals`` (see the module docstring)."""
    return CATALOG[name].mesh_intervals


def growth_node(name: str, growth: Any) -> NDArray[np.int64]:
    """Index of the growth node nearest to ``growth`` (array or scalar) for species ``name``."""
    n = growth_intervals(name)
    return np.rint(np.clip(np.asarray(growth, np.float64), 0.0, 1.0) * n).astype(np.int64)


def node_growth(name: str, node: int) -> float:
    return node / growth_intervals(name)


def rotation_rpy(roll: Any, pitch: Any, yaw: Any) -> FloatArray:
    """URDF rpy rotation matrices R = Rz(yaw)·Ry(pitch)·Rx(roll), shape (..., 3, 3)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    return np.stack(
        [
            np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
            np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
            np.stack([-sp, cp * sr, cp * cr], -1),
        ],
        -2,
    )


@dataclass(frozen=True, eq=False)
class Prototype:
    """A mesh with its base at the origin and +z up, and how it looks."""

    name: str  # "corn@24/48", or the user model's file name
    vertices: F32  # (V, 3)
    faces: NDArray[np.uint32]  # (F, 3)
    face_rgb: NDArray[np.uint8]  # (F, 3) base colour (the texture's mean where textured)
    normals: F32  # (F, 3) unit face normals
    uv: F32 | None  # (V, 2) texture coordinates
    texture: NDArray[np.uint8] | None  # (h, w, 3), row 0 at v = 1 (image convention)
    height: float
    radius: float  # farthest vertex from the z axis, m
    label: int  # CROP or WEED
    alpha: NDArray[np.bool_] | None = None  # (h, w) texel opaque; None: no cut-outs

    @classmethod
    def from_trimesh(cls, mesh: Any, name: str, label: int) -> Prototype:
        v = np.asarray(mesh.vertices, np.float32)
        f = np.asarray(mesh.faces, np.uint32)
        tri = v[f.astype(np.int64)]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        uv, tex, alpha = _texture(mesh)
        if tex is not None and uv is not None:
            centre = uv[f.astype(np.int64)].mean(axis=1)
            rgb = sample_texture(tex, centre[:, 0], centre[:, 1])
        else:
            rgb = _face_rgb(mesh)
        return cls(
            name,
            v,
            f,
            np.ascontiguousarray(rgb, np.uint8),
            n.astype(np.float32),
            uv,
            tex,
            float(v[:, 2].max()) if len(v) else 0.0,
            float(np.hypot(v[:, 0], v[:, 1]).max()) if len(v) else 0.0,
            label,
            alpha,
        )

    @property
    def nbytes(self) -> int:
        arrays = (
            self.vertices, self.faces, self.face_rgb, self.normals, self.uv, self.texture,
            self.alpha,
        )  # fmt: skip
        return sum(a.nbytes for a in arrays if a is not None)

    def opaque(self, prim: NDArray[np.int64], u: Any, v: Any) -> NDArray[np.bool_]:
        """Whether the texel under each hit (triangle ``prim``, barycentric ``u``, ``v``) is
        opaque: False on a cut-out (alpha below one half)."""
        if self.alpha is None or self.uv is None:
            return np.ones(len(prim), bool)
        uv = hit_uv(self, prim, u, v)
        out: NDArray[np.bool_] = sample_texture(self.alpha, uv[:, 0], uv[:, 1])
        return out


def hit_uv(p: Prototype, prim: NDArray[np.int64], u: Any, v: Any) -> FloatArray:
    """Texture coordinates of hits on ``p``'s triangles ``prim`` at barycentric (u, v)."""
    assert p.uv is not None
    f = p.faces[prim].astype(np.int64)
    u = np.asarray(u, np.float64)[:, None]
    v = np.asarray(v, np.float64)[:, None]
    out: FloatArray = p.uv[f[:, 0]] * (1.0 - u - v) + p.uv[f[:, 1]] * u + p.uv[f[:, 2]] * v
    return out


def _texture(
    mesh: Any,
) -> tuple[F32 | None, NDArray[np.uint8] | None, NDArray[np.bool_] | None]:
    """UVs, RGB texels and (where any texel is cut out) the opaque mask of a textured mesh."""
    visual = mesh.visual
    if getattr(visual, "kind", None) != "texture" or getattr(visual, "uv", None) is None:
        return None, None, None
    material = visual.material
    image = getattr(material, "image", None)
    if image is None:
        image = getattr(material, "baseColorTexture", None)
    if image is None:
        return None, None, None
    rgba = np.asarray(image.convert("RGBA"), np.uint8)
    uv = np.asarray(visual.uv, np.float32)
    if len(uv) != len(mesh.vertices) or rgba.size == 0:
        return None, None, None
    opaque = rgba[..., 3] >= 128
    alpha = None if opaque.all() else np.ascontiguousarray(opaque)
    return uv, np.ascontiguousarray(rgba[..., :3]), alpha


def _face_rgb(mesh: Any) -> NDArray[np.uint8]:
    """(F, 3) colours of an untextured mesh: face colours, vertex colours averaged, or its
    material's colour (a texture that did not load leaves only that)."""
    visual = mesh.visual
    n = len(mesh.faces)
    if getattr(visual, "kind", None) == "texture":
        colour = getattr(getattr(visual, "material", None), "main_color", None)
        if colour is None or np.shape(colour) != (4,):
            return np.full((n, 3), 128, np.uint8)
        return np.tile(np.asarray(colour, np.uint8)[:3], (n, 1))
    if getattr(visual, "kind", None) == "vertex":
        vc = np.asarray(visual.vertex_colors, np.float64)[:, :3]
        return np.asarray(np.round(vc[np.asarray(mesh.faces)].mean(axis=1)), np.uint8)
    fc = np.asarray(getattr(visual, "face_colors", np.zeros((0, 4))), np.uint8)
    if fc.ndim != 2 or len(fc) != n:
        return np.full((n, 3), 128, np.uint8)
    return np.ascontiguousarray(fc[:, :3])


def sample_texture(tex: NDArray[Any], u: Any, v: Any) -> NDArray[Any]:
    """Nearest texel at (u, v), wrapping (glTF/OBJ repeat); v = 0 is the image's bottom row."""
    h, w = tex.shape[:2]
    x = np.floor(np.mod(u, 1.0) * w).astype(np.int64).clip(0, w - 1)
    y = np.floor((1.0 - np.mod(v, 1.0)) * h).astype(np.int64).clip(0, h - 1)
    out: NDArray[Any] = tex[y, x]
    return out


@lru_cache(maxsize=512)
def catalog_prototype(
    name: str, node: int, leaf_length: float = 1.0, leaf_droop: float = 1.0
) -> Prototype:
    """The catalog model of species ``name`` at growth node ``node`` (shared per process);
    ``leaf_length``/``leaf_droop`` scale its leaves (``crop_mesh``)."""
    g = node_growth(name, node)
    mesh = crop_mesh(name, g, leaf_length, leaf_droop)
    label = WEED if name == WEED_SPECIES else CROP
    tag = "" if (leaf_length, leaf_droop) == (1.0, 1.0) else f" L{leaf_length:g} D{leaf_droop:g}"
    return Prototype.from_trimesh(mesh, f"{name}@{node}/{growth_intervals(name)}{tag}", label)


@lru_cache(maxsize=8)
def _user_prototype(path: str, mtime: float, height: float, up_axis: str) -> Prototype:
    from scenario_gen.models import load_model

    return Prototype.from_trimesh(load_model(path, height, up_axis), Path(path).name, CROP)


def user_prototype(path: str | Path, height: float, up_axis: str = "auto") -> Prototype:
    """A user model (mesh file or zip with textures) at ``height`` m, cached by file and time."""
    p = Path(path)
    return _user_prototype(str(p.resolve()), p.stat().st_mtime, round(float(height), 6), up_axis)


@dataclass(frozen=True, eq=False)
class PlantMeshes:
    """Every plant as (prototype, transform); the pose arrays are the scenario's own."""

    prototypes: tuple[Prototype, ...]
    proto: NDArray[np.int16]  # (n,) prototype index per plant
    scale: F32  # (n,) plant height / prototype height
    x: FloatArray
    y: FloatArray
    z: FloatArray
    roll: FloatArray
    pitch: FloatArray
    yaw: FloatArray

    @classmethod
    def from_scenario(
        cls, scn: Scenario, leaf_length: float = 1.0, leaf_droop: float = 1.0
    ) -> PlantMeshes:
        """Placements of ``scn``'s plants; leaf factors as ``crop_mesh`` (catalog models)."""
        p = scn.plants
        n = len(p)
        proto = np.zeros(n, np.int16)
        protos: list[Prototype] = []
        index: dict[str, int] = {}

        def add(pr: Prototype) -> int:
            if pr.name not in index:
                index[pr.name] = len(protos)
                protos.append(pr)
            return index[pr.name]

        model = scn.spec.crop.model
        for name in np.unique(p.species):
            sel = np.flatnonzero(p.species == name)
            sp = CATALOG[str(name)]
            if model is not None and name != WEED_SPECIES:
                growth = float(sp.growth_of_stage(float(np.median(p.stage[sel]))))
                up = scn.spec.crop.model_up_axis
                k = add(user_prototype(model, float(sp.height(growth)), up))
                proto[sel] = k
                continue
            nodes = growth_node(str(name), sp.growth_of_stage(p.stage[sel]))
            for node in np.unique(nodes):
                pr = catalog_prototype(str(name), int(node), leaf_length, leaf_droop)
                proto[sel[nodes == node]] = add(pr)
        heights = np.array([pr.height for pr in protos] or [1.0])
        scale = (p.height / np.maximum(heights[proto], 1e-6)).astype(np.float32)
        return cls(tuple(protos), proto, scale, p.x, p.y, p.z, p.roll, p.pitch, p.yaw)

    def __len__(self) -> int:
        return len(self.proto)

    @property
    def reach(self) -> float:
        """Farthest any plant's geometry reaches from its base point horizontally, m."""
        if len(self) == 0:
            return 0.0
        radius = np.array([pr.radius for pr in self.prototypes])
        return float((radius[self.proto] * self.scale).max())

    def transforms(self, idx: NDArray[np.int64], origin: FloatArray) -> F32:
        """Row-major 3×4 transforms (scale·R | position − origin) of plants ``idx``."""
        r = rotation_rpy(self.roll[idx], self.pitch[idx], self.yaw[idx])
        out = np.empty((len(idx), 3, 4), np.float32)
        out[:, :, :3] = r * self.scale[idx, None, None]
        out[:, 0, 3] = self.x[idx] - origin[0]
        out[:, 1, 3] = self.y[idx] - origin[1]
        out[:, 2, 3] = self.z[idx] - origin[2]
        return out

    def per_plant_bytes(self) -> float:
        """Memory this placement adds per plant (the pose arrays belong to the scenario)."""
        return (self.proto.nbytes + self.scale.nbytes) / max(len(self), 1)

    def world_vertices(self, i: int) -> FloatArray:
        """Plant ``i``'s mesh vertices in world coordinates (tests and figures)."""
        pr = self.prototypes[int(self.proto[i])]
        r = rotation_rpy(self.roll[i], self.pitch[i], self.yaw[i])
        v = pr.vertices.astype(np.float64) * float(self.scale[i])
        out: FloatArray = v @ r.T + np.array([self.x[i], self.y[i], self.z[i]])
        return out
