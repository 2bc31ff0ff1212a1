"""Mesh files Gazebo Classic 11 and Gazebo Sim both read: textured COLLADA and binary STL.

COLLADA (``.dae``) carries the per-model meshes with a texture: catalog plants are coloured per
face, so their colours become a small palette image and every face's texture coordinate points
at the middle of its colour's cell (cells of 8x8 texels, so mipmapping never blends two
colours). Merged tiles of thousands of plants use binary STL instead, one file per colour with
the colour in the SDF material: 50 bytes a triangle, written straight from numpy, where a text
format would need tens of bytes per number and minutes of formatting for a 100k-plant field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO
from xml.sax.saxutils import escape

import numpy as np
from numpy.typing import NDArray

from ..arrays import FloatArray, IntArray

CELL = 8  # texels per palette cell side


@dataclass(frozen=True, eq=False)
class MeshData:
    """Triangles with separate index streams for positions, normals and texture coordinates."""

    positions: FloatArray  # (n, 3)
    faces: IntArray  # (f, 3) position indices
    normals: FloatArray  # (m, 3)
    normal_index: IntArray  # (f, 3)
    uvs: FloatArray  # (k, 2)
    uv_index: IntArray  # (f, 3)


def palette(colours: NDArray[np.uint8]) -> tuple[NDArray[np.uint8], FloatArray]:
    """An RGB image with one ``CELL``-texel square per colour and each cell's centre UV."""
    n = max(len(colours), 1)
    cols = math.ceil(math.sqrt(n))
    rows = math.ceil(n / cols)
    img = np.zeros((rows * CELL, cols * CELL, 3), np.uint8)
    uv = np.empty((n, 2))
    for i, c in enumerate(colours):
        r, q = divmod(i, cols)
        img[r * CELL : (r + 1) * CELL, q * CELL : (q + 1) * CELL] = c[:3]
        # COLLADA's v runs up from the image's bottom row
        uv[i] = ((q + 0.5) / cols, 1.0 - (r + 0.5) / rows)
    return img, uv


def face_normals(positions: FloatArray, faces: IntArray) -> FloatArray:
    """Unit normals per face; degenerate faces get +z rather than NaN."""
    tri = positions[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    bad = length[:, 0] < 1e-15
    n = np.where(bad[:, None], [0.0, 0.0, 1.0], n / np.where(bad[:, None], 1.0, length))
    return np.asarray(n, np.float64)


def flat_colour_mesh(
    positions: FloatArray, faces: IntArray, face_rgb: NDArray[np.uint8]
) -> tuple[MeshData, NDArray[np.uint8]]:
    """A face-coloured mesh as flat-shaded COLLADA data plus its palette image."""
    colours, which = np.unique(face_rgb[:, :3], axis=0, return_inverse=True)
    img, uv = palette(colours)
    f = len(faces)
    md = MeshData(
        positions,
        faces,
        face_normals(positions, faces),
        np.repeat(np.arange(f)[:, None], 3, axis=1),
        uv,
        np.repeat(which.reshape(-1)[:, None], 3, axis=1),
    )
    return md, img


def textured_mesh(mesh: Any) -> tuple[MeshData, NDArray[np.uint8]] | None:
    """A trimesh with UVs and an image texture as COLLADA data, or None if it has none."""
    visual = getattr(mesh, "visual", None)
    uv = getattr(visual, "uv", None)
    material = getattr(visual, "material", None)
    image = getattr(material, "image", None) or getattr(material, "baseColorTexture", None)
    if uv is None or image is None or len(uv) != len(mesh.vertices):
        return None
    pos = np.asarray(mesh.vertices, np.float64)
    faces = np.asarray(mesh.faces, np.int64)
    f = len(faces)
    md = MeshData(
        pos,
        faces,
        face_normals(pos, faces),
        np.repeat(np.arange(f)[:, None], 3, axis=1),
        np.asarray(uv, np.float64),
        faces,
    )
    rgba = np.asarray(image.convert("RGBA"), np.uint8)
    # a cut-out texture keeps its alpha (the DAE then says so: ``write_dae``'s ``transparent``)
    return md, rgba if (rgba[..., 3] < 255).any() else np.ascontiguousarray(rgba[..., :3])


def opaque_faces(mesh: Any) -> NDArray[np.bool_]:
    """(f,) whether each face of a trimesh is drawn: False where a textured face's UV centroid
    lies on a cut-out texel (alpha below one half), as the cameras see it; a flat-colour copy
    drops those faces rather than paint the cut-out's hidden colour."""
    from trimesh.visual.color import uv_to_color

    visual = mesh.visual
    faces = np.asarray(mesh.faces)
    if getattr(visual, "kind", None) == "texture" and visual.uv is not None:
        material = visual.material
        image = getattr(material, "image", None) or getattr(material, "baseColorTexture", None)
        if image is not None:
            centroid = np.asarray(visual.uv, np.float64)[faces].mean(axis=1)
            alpha = np.asarray(uv_to_color(centroid, image.convert("RGBA")), np.uint8)[:, 3]
            return np.asarray(alpha >= 128)
    return np.ones(len(faces), bool)


def face_colours(mesh: Any) -> NDArray[np.uint8]:
    """(f, 3) RGB per face of a trimesh: its face colours, or its texture at each face's UV
    centroid (one texel per face: a flat-shaded copy of a textured model)."""
    from trimesh.visual.color import uv_to_color

    visual = mesh.visual
    faces = np.asarray(mesh.faces)
    if getattr(visual, "kind", None) == "texture":
        material = visual.material
        image = getattr(material, "image", None) or getattr(material, "baseColorTexture", None)
        if image is not None and visual.uv is not None:
            centroid = np.asarray(visual.uv, np.float64)[faces].mean(axis=1)
            return np.asarray(uv_to_color(centroid, image), np.uint8)[:, :3]
        colour: Any = getattr(material, "main_color", None)  # a texture that did not load
        if colour is None or np.shape(colour) != (4,):
            colour = (128, 128, 128, 255)
        return np.tile(np.asarray(colour, np.uint8)[:3], (len(faces), 1))
    if getattr(visual, "kind", None) == "vertex":
        vc = np.asarray(visual.vertex_colors, np.float64)[:, :3]
        return np.asarray(np.round(vc[faces].mean(axis=1)), np.uint8)
    return np.asarray(visual.face_colors, np.uint8)[:, :3]


CHUNK = 1 << 18  # numbers formatted at a time: bounded memory for million-vertex terrains


def _write_floats(f: TextIO, a: FloatArray, decimals: int) -> None:
    flat = np.asarray(a, np.float64).ravel()
    form = f"%.{decimals}f"
    for i in range(0, len(flat), CHUNK):
        part = np.round(flat[i : i + CHUNK], decimals) + 0.0  # + 0.0: no "-0.0"
        # one format string for the whole chunk: a third faster than formatting one by one
        f.write((" " if i else "") + " ".join([form] * len(part)) % tuple(part.tolist()))


def _write_ints(f: TextIO, a: IntArray) -> None:
    flat = np.asarray(a).ravel()
    for i in range(0, len(flat), CHUNK):
        f.write((" " if i else "") + " ".join(map(str, flat[i : i + CHUNK].tolist())))


def write_dae(
    path: Path,
    md: MeshData,
    texture: str,
    name: str,
    decimals: int = 5,
    cutout: bool = False,
) -> None:
    """COLLADA 1.4.1, Z up, metres: one textured triangle list named ``name``, streamed.

    When normals and texture coordinates are indexed like the positions (a smooth mesh such
    as the terrain) every corner carries one index instead of three. With ``cutout`` the
    texture's alpha is its opacity (``<transparent opaque="A_ONE">`` with the texture: what
    gz-common's COLLADA loader turns into an alpha test).
    """
    shared = np.array_equal(md.normal_index, md.faces) and np.array_equal(md.uv_index, md.faces)
    offsets = (0, 0, 0) if shared else (0, 1, 2)
    tex = escape(texture)
    transparent = (
        '<transparent opaque="A_ONE"><texture texture="texture-sampler" texcoord="UVMap"/>'
        "</transparent>"
        if cutout
        else ""
    )
    with open(path, "w") as f:
        f.write(
            f"""<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
<asset><contributor><authoring_tool>agrinav export</authoring_tool></contributor>
<unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>
<library_images><image id="texture-image" name="texture"><init_from>{tex}</init_from></image>
</library_images>
<library_effects><effect id="material-effect"><profile_COMMON>
<newparam sid="texture-surface"><surface type="2D"><init_from>texture-image</init_from></surface>
</newparam>
<newparam sid="texture-sampler"><sampler2D><source>texture-surface</source></sampler2D></newparam>
<technique sid="common"><lambert><diffuse><texture texture="texture-sampler" texcoord="UVMap"/>
</diffuse>{transparent}</lambert></technique></profile_COMMON></effect></library_effects>
<library_materials><material id="material" name="material">
<instance_effect url="#material-effect"/></material></library_materials>
<library_geometries><geometry id="mesh" name="{escape(name)}"><mesh>
"""
        )
        for sid, arr, stride, names, digits in (
            ("positions", md.positions, 3, "XYZ", decimals),
            ("normals", md.normals, 3, "XYZ", 5),
            ("uvs", md.uvs, 2, "ST", 6),
        ):
            params = "".join(f'<param name="{c}" type="float"/>' for c in names)
            f.write(f'<source id="{sid}"><float_array id="{sid}-array" count="{arr.size}">')
            _write_floats(f, arr, digits)
            f.write(
                f'</float_array><technique_common><accessor source="#{sid}-array" '
                f'count="{len(arr)}" stride="{stride}">{params}</accessor></technique_common>'
                "</source>\n"
            )
        f.write(
            f"""<vertices id="vertices"><input semantic="POSITION" source="#positions"/></vertices>
<triangles material="material" count="{len(md.faces)}">
<input semantic="VERTEX" source="#vertices" offset="{offsets[0]}"/>
<input semantic="NORMAL" source="#normals" offset="{offsets[1]}"/>
<input semantic="TEXCOORD" source="#uvs" offset="{offsets[2]}" set="0"/>
<p>"""
        )
        if shared:
            _write_ints(f, md.faces)
        else:
            _write_ints(f, np.stack([md.faces, md.normal_index, md.uv_index], axis=2))
        f.write(
            f"""</p></triangles></mesh></geometry></library_geometries>
<library_visual_scenes><visual_scene id="scene"><node id="node" name="{escape(name)}">
<instance_geometry url="#mesh"><bind_material><technique_common>
<instance_material symbol="material" target="#material">
<bind_vertex_input semantic="UVMap" input_semantic="TEXCOORD" input_set="0"/>
</instance_material></technique_common></bind_material></instance_geometry></node>
</visual_scene></library_visual_scenes>
<scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>
"""
        )


STL_DTYPE = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])


def write_stl(path: Path, triangles: FloatArray) -> None:
    """Binary STL of (f, 3, 3) triangles (float32: keep coordinates local, a few tens of m)."""
    tri = np.asarray(triangles, np.float64)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, length, out=np.zeros_like(n), where=length > 1e-15)
    rec = np.zeros(len(tri), STL_DTYPE)
    rec["normal"] = n
    rec["v"] = tri
    with open(path, "wb") as f:
        f.write(b"agrinav export binary STL".ljust(80, b" "))
        f.write(np.uint32(len(tri)).tobytes())
        rec.tofile(f)


def save_png(image: NDArray[np.uint8], path: Path) -> None:
    from PIL import Image

    Image.fromarray(np.ascontiguousarray(image)).save(path, compress_level=6)
