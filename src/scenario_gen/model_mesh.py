"""A user model's mesh with its materials, as one mesh with one texture: the file's colours.

A model file is a scene of parts (COLLADA geometries, OBJ materials, glTF primitives), each
with a texture or a colour. The parts become one mesh whose texture is an atlas of the parts'
images — packed here rather than by trimesh's ``force="mesh"``, whose packing multiplies a
texture by its uint8 colour factor (255 × texel, modulo 256: green maize turned purple) and
drops the alpha channel of COLLADA and OBJ textures.

What a part's texels are: the image; glTF's ``baseColorFactor`` multiplies it (the glTF rule);
an OBJ's ``Kd`` beside a ``map_Kd`` does not (exporters write Kd 0.8 next to a texture that is
meant as is). A part without a texture gets a cell of the atlas per colour (material colour,
face or vertex colours). Alpha becomes a cut-out: texels with alpha below one half (glTF
``MASK``: below its ``alphaCutoff``) are holes, the rest opaque; glTF ``OPAQUE`` parts have no
holes. UVs outside [0, 1] repeat the image (glTF and OBJ wrap): such a part's image is tiled in
its atlas cell as often as its UVs span.

COLLADA's ``<unit meter>`` is applied (trimesh ignores it; Gazebo does not), so the mesh is in
metres.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any
from urllib.parse import unquote
from xml.etree import ElementTree

import numpy as np
from numpy.typing import NDArray

from .arrays import FloatArray
from .errors import Notice

#: Texels of one atlas side at most; larger atlases are built from scaled-down parts.
MAX_ATLAS = 4096
#: Repeats of an image per axis a part may span before its tiles are scaled down.
MAX_TILES = 8
#: Texels of a repeated texture built whole before it is shrunk (64 MB of RGBA); past it the
#: shrunk texture is sampled directly
MAX_TILED_TEXELS = 4096 * 4096
ALPHA_CUT = 0.5
CELL = 4  # texels per side of a flat colour's cell


def collada_unit(path: Path) -> float:
    """Metres per unit of a COLLADA file (``<asset><unit meter=...>``; 1 when absent)."""
    try:
        for _, el in ElementTree.iterparse(str(path), events=("start",)):
            tag = el.tag.rsplit("}", 1)[-1]
            if tag == "unit":
                value = float(el.get("meter", "1"))
                return value if math.isfinite(value) and value > 0 else 1.0
            if tag in ("library_geometries", "library_visual_scenes"):
                break
    except (ElementTree.ParseError, ValueError, OSError):
        pass
    return 1.0


def collada_up_axis(path: Path) -> str | None:
    """A COLLADA file's ``<asset><up_axis>`` (``X_UP``, ``Y_UP``, ``Z_UP``), None when absent."""
    try:
        for _, el in ElementTree.iterparse(str(path), events=("end",)):
            tag = el.tag.rsplit("}", 1)[-1]
            if tag == "up_axis":
                return (el.text or "").strip() or None
            if tag == "asset":
                break
    except (ElementTree.ParseError, OSError):
        pass
    return None


def spellings(name: str) -> list[str]:
    """The names a model's reference may mean, as ``model_files`` reads it: as written,
    URL-decoded (glTF and COLLADA references are URIs: ``leaf%20tex.png``), with Windows
    folder separators, and an MTL map's last word (``map_Kd -s 1 1 1 -bm 1 leaf.png``)."""
    out: list[str] = []
    for n in (name, unquote(name)):
        for m in (n, n.replace("\\", "/")):
            for k in (m, m.split()[-1] if m.split() else m):
                if k not in out:
                    out.append(k)
    return out


#: glTF extensions that change how a file's geometry is stored: trimesh reads none of them
#: (compressed buffers it cannot decode, integer coordinates it does not scale), so a file
#: that requires one is refused, naming how to write it without
GLTF_GEOMETRY_EXTENSIONS = {
    "KHR_draco_mesh_compression": "Draco-compressed geometry",
    "EXT_meshopt_compression": "meshoptimizer-compressed buffers",
    "KHR_mesh_quantization": "quantized (integer) vertex attributes",
    "EXT_mesh_gpu_instancing": "GPU-instanced nodes",
}


def gltf_document(path: Path) -> dict[str, Any] | None:
    """The JSON of a ``.gltf`` or ``.glb`` file (None where it cannot be parsed: the loader
    then says what is wrong with it)."""
    import json
    import struct

    try:
        data = path.read_bytes()
        if data[:4] == b"glTF":
            (length,) = struct.unpack_from("<I", data, 12)
            if data[16:20] != b"JSON":
                return None
            doc = json.loads(data[20 : 20 + length])
        else:
            doc = json.loads(data)
    except (OSError, ValueError, struct.error):
        return None
    return doc if isinstance(doc, dict) else None


def check_gltf(path: Path, given: Path, field: str = "crop.model", look: bool = True) -> None:
    """Refuse a glTF whose geometry is stored in a way trimesh does not read (``field`` names
    the file); note what of its look is drawn otherwise than the file says (a texture
    transform, a second UV set) where ``look``."""
    from .errors import InputError

    doc = gltf_document(path)
    if doc is None:
        return
    required = [str(e) for e in doc.get("extensionsRequired") or []]
    geometry = [e for e in required if e in GLTF_GEOMETRY_EXTENSIONS]
    if geometry:
        what = ", ".join(f"{e} ({GLTF_GEOMETRY_EXTENSIONS[e]})" for e in geometry)
        raise InputError(
            field,
            str(given),
            f"requires the glTF extension {what}, which the loader does not read; allowed: "
            "plain accessors (e.g. `gltf-transform copy IN OUT` decodes Draco and meshopt, "
            "`gltf-transform dequantize IN OUT` undoes quantization)",
        )
    if not look:
        return
    transformed, second_uv = set(), set()
    for i, mat in enumerate(doc.get("materials") or []):
        if not isinstance(mat, dict):
            continue
        tex = (mat.get("pbrMetallicRoughness") or {}).get("baseColorTexture")
        if not isinstance(tex, dict):
            continue
        name = str(mat.get("name") or f"#{i}")
        if "KHR_texture_transform" in (tex.get("extensions") or {}):
            transformed.add(name)
        if tex.get("texCoord", 0) not in (0, None):
            second_uv.add(name)
    for names, what in (
        (transformed, "KHR_texture_transform (offset, scale, rotation) is not applied"),
        (second_uv, "their texture's TEXCOORD_n set other than 0 is not read: TEXCOORD_0 maps it"),
    ):
        if names:
            warnings.warn(
                Notice(
                    f"crop.model {given.name}: material(s) {', '.join(sorted(names))}: {what}, "
                    "so their texture is drawn otherwise than the file shows it"
                ),
                stacklevel=3,
            )


def file_up_axis(p: Path, up_axis: str, field: str, key: str, given: Path | None = None) -> str:
    """The up axis (``key``'s value, e.g. ``crop.model_up_axis``) of the mesh file ``p``
    (``field`` and ``given`` name it in an error): auto is y for glTF/GLB (the format's rule),
    what a COLLADA file declares in ``<up_axis>`` (Y_UP, the format's default, where it
    declares none), z otherwise."""
    from .errors import InputError

    if up_axis != "auto":
        return up_axis
    suffix = p.suffix.lower()
    if suffix in (".glb", ".gltf"):
        return "y"
    if suffix == ".dae":
        declared = collada_up_axis(p)
        if declared == "X_UP":  # neither axis this project turns a mesh about
            raise InputError(
                field,
                str(given or p),
                "declares <up_axis>X_UP</up_axis>; allowed: a COLLADA file Y_UP or Z_UP "
                f"(re-export it), or {key} y or z to say which axis is up",
            )
        # none declared is Y_UP, COLLADA 1.4's default (as Gazebo's loader reads it too)
        return "z" if declared == "Z_UP" else "y"
    return "z"


def read_scene(path: Path) -> Any:
    """The file as a trimesh Scene, referenced files resolved from its folder as
    ``model_files.bundle`` checked them (``spellings``): trimesh asks for a reference as
    written and, not finding it, leaves the texture out without a word."""
    import trimesh
    from trimesh.resolvers import FilePathResolver

    # an OBJ's material library names its maps relative to its own folder (where
    # model_files.bundle found them), while trimesh looks in the OBJ's: both are tried
    folders = [""]
    if path.suffix.lower() == ".obj":
        from .model_files import obj_mtl_folders

        folders += [f for f in obj_mtl_folders(path) if f not in folders]

    class Resolver(FilePathResolver):
        def get(self, name: str) -> bytes:
            for folder in folders:
                for k in spellings(name):
                    try:
                        return bytes(super().get(f"{folder}/{k}" if folder else k))
                    except OSError:
                        continue
            return bytes(super().get(name))

    # loaded unprocessed: trimesh's processing drops faces on NaN vertices without a word, so
    # the caller sees the file as written (``bad_vertices``) before ``processed``
    return trimesh.load(
        str(path),
        force="scene",
        resolver=Resolver(str(path), allow_anywhere=True),
        process=False,
    )


def bad_vertices(scene: Any) -> tuple[int, int]:
    """How many of the scene's mesh vertices are NaN or infinite, and how many there are."""
    import trimesh

    meshes = [g for g in scene.geometry.values() if isinstance(g, trimesh.Trimesh)]
    bad = sum(int((~np.isfinite(np.asarray(g.vertices))).any(axis=1).sum()) for g in meshes)
    return bad, sum(len(g.vertices) for g in meshes)


def processed(scene: Any) -> Any:
    """``scene`` with each mesh processed as trimesh's loader does by default (vertices
    merged), in place."""
    import trimesh

    for g in scene.geometry.values():
        if isinstance(g, trimesh.Trimesh):
            g.process()
    return scene


def one_mesh(scene: Any, unit: float = 1.0, gltf: bool = False) -> Any:
    """The scene's parts as one trimesh: vertices in the scene frame (× ``unit``), an RGBA
    atlas texture where any part is textured (else face colours). ``gltf``: the scene is a
    glTF file's, whose materials without an ``alphaMode`` are opaque (the glTF 2.0 default)."""
    import trimesh

    for g in scene.geometry.values():
        _vertex_colours_as_look(g)
    parts = [g for g in scene.dump(concatenate=False) if len(getattr(g, "faces", ())) > 0]
    if not parts:
        return trimesh.Trimesh()
    looks = [_look(g, gltf) for g in parts]
    if not any(isinstance(lk, _Image) for lk in looks):
        v, f, rgba = [], [], []
        base = 0
        for g, lk in zip(parts, looks, strict=True):
            assert not isinstance(lk, _Image)
            v.append(np.asarray(g.vertices, np.float64))
            f.append(np.asarray(g.faces, np.int64) + base)
            rgba.append(lk)
            base += len(g.vertices)
        colours = trimesh.visual.ColorVisuals(face_colors=np.concatenate(rgba))
        return trimesh.Trimesh(
            np.concatenate(v) * unit, np.concatenate(f), visual=colours, process=False
        )
    return _atlas_mesh(parts, looks, unit)


class _Image:
    """A textured part: its RGBA texels (alpha already 0 or 255) and UVs."""

    def __init__(self, rgba: NDArray[np.uint8], uv: FloatArray) -> None:
        self.rgba = rgba
        self.uv = uv


def _look(g: Any, gltf: bool = False) -> _Image | NDArray[np.uint8]:
    """A part's texture (``_Image``) or its per-face RGBA colours."""
    visual = g.visual
    n = len(g.faces)
    if getattr(visual, "kind", None) == "texture":
        mat = getattr(visual, "material", None)
        uv = getattr(visual, "uv", None)
        image, factor, mode, cutoff = _material(mat)
        if gltf and mode is None:
            mode = "OPAQUE"
        if image is not None and (uv is None or len(uv) != len(g.vertices)):
            # a map_Kd (or baseColorTexture) with no vt / TEXCOORD_0 to place it: trimesh keeps
            # the image and nothing says it is not drawn
            warnings.warn(
                Notice(
                    f"crop.model: a part with {len(g.faces):,} faces has a texture but no "
                    "texture coordinates (OBJ vt, glTF TEXCOORD_0): drawn in its material's "
                    "colour"
                ),
                stacklevel=2,
            )
        if image is not None and uv is not None and len(uv) == len(g.vertices):
            rgba = np.asarray(_eight_bit(image).convert("RGBA"), np.float64)
            rgba = rgba * factor[None, None, :]
            alpha = rgba[..., 3] / 255.0
            if mode == "OPAQUE":
                rgba[..., 3] = 255.0
            else:
                rgba[..., 3] = np.where(alpha >= cutoff, 255.0, 0.0)
            img = np.clip(np.round(rgba), 0, 255).astype(np.uint8)
            return _Image(img, np.asarray(uv, np.float64))
        colour = _material_colour(mat) * factor
        return np.tile(np.clip(np.round(colour), 0, 255).astype(np.uint8), (n, 1))
    if getattr(visual, "kind", None) == "vertex":
        vc = np.asarray(visual.vertex_colors, np.float64)
        return np.asarray(np.round(vc[np.asarray(g.faces)].mean(axis=1)), np.uint8)
    fc = np.asarray(visual.face_colors, np.uint8)
    return fc if fc.shape == (n, 4) else np.tile(np.array([128, 128, 128, 255], np.uint8), (n, 1))


def _vertex_colours_as_look(g: Any) -> None:
    """A glTF part's COLOR_0 (trimesh keeps it beside the material, and drops it when the scene
    is flattened) as its vertex colours: it multiplies the base colour. Over a texture it is
    not drawn, and a note says so."""
    import trimesh

    visual = getattr(g, "visual", None)
    if getattr(visual, "kind", None) != "texture":
        return
    store = getattr(visual, "vertex_attributes", None)
    vc = store.get("color") if store is not None else None
    if vc is None or len(vc) != len(g.vertices):
        return
    mat = getattr(visual, "material", None)
    image, factor, _, _ = _material(mat)
    if image is not None:
        warnings.warn(
            Notice(
                f"crop.model: a part with {len(g.faces):,} faces has vertex colours (glTF "
                "COLOR_0) over a texture: drawn with the texture alone"
            ),
            stacklevel=3,
        )
        return
    rgba = _unit_colours(np.asarray(vc)) * (_material_colour(mat) * factor)[None, :]
    g.visual = trimesh.visual.ColorVisuals(
        mesh=g, vertex_colors=np.clip(np.round(rgba), 0, 255).astype(np.uint8)
    )


def _unit_colours(vc: NDArray[Any]) -> FloatArray:
    """Vertex colours as RGBA in [0, 1]: glTF stores them as floats or normalized integers,
    with or without alpha."""
    kind = vc.dtype.kind
    out = vc.astype(np.float64)
    if kind in "ui":
        out /= float(np.iinfo(vc.dtype).max)
    if out.ndim != 2 or out.shape[1] not in (3, 4):
        return np.ones((len(vc), 4))
    if out.shape[1] == 3:
        out = np.column_stack([out, np.ones(len(out))])
    return np.clip(out, 0.0, 1.0)


def _eight_bit(image: Any) -> Any:
    """A 16- or 32-bit greyscale image (a 16-bit PNG reads as mode ``I;16`` or ``I``) as 8-bit:
    Pillow's conversion clips it (a 60 % grey read as white)."""
    if image.mode not in ("I", "I;16", "I;16B", "I;16L", "I;16N"):
        return image
    from PIL import Image

    grey = np.asarray(image, np.float64) * (255.0 / 65535.0)
    return Image.fromarray(np.clip(np.round(grey), 0, 255).astype(np.uint8), "L")


def _material(mat: Any) -> tuple[Any, FloatArray, str | None, float]:
    """(image, RGBA factor in [0, 1] per channel, glTF alpha mode, alpha cutoff)."""
    from trimesh.visual.material import PBRMaterial

    one = np.ones(4)
    if isinstance(mat, PBRMaterial):
        factor = one
        if mat.baseColorFactor is not None:
            factor = np.asarray(mat.baseColorFactor, np.float64).reshape(4) / 255.0
        cutoff = mat.alphaCutoff if mat.alphaMode == "MASK" and mat.alphaCutoff else ALPHA_CUT
        return mat.baseColorTexture, factor, mat.alphaMode, float(cutoff)
    image = getattr(mat, "image", None)
    return image, one, None, ALPHA_CUT


def _material_colour(mat: Any) -> FloatArray:
    """A material's colour without a texture (RGBA 0-255; the factor multiplies it after)."""
    from trimesh.visual.material import PBRMaterial

    if isinstance(mat, PBRMaterial):
        return np.full(4, 255.0)  # the factor is the colour
    diffuse = getattr(mat, "diffuse", None)
    if diffuse is not None and np.shape(diffuse) == (4,):
        return np.asarray(diffuse, np.float64)
    return np.array([128.0, 128.0, 128.0, 255.0])


def _atlas_mesh(parts: list[Any], looks: list[Any], unit: float) -> Any:
    import trimesh

    # each textured part's block: its image tiled over the UV span
    blocks: list[NDArray[np.uint8]] = []
    spans: list[tuple[FloatArray, FloatArray]] = []  # (floor of uv min, repeats) per part
    colours: list[NDArray[np.uint8]] = []
    for lk in looks:
        if isinstance(lk, _Image):
            lo = np.floor(lk.uv.min(axis=0) + 1e-6) if len(lk.uv) else np.zeros(2)
            hi = np.ceil(lk.uv.max(axis=0) - 1e-6) if len(lk.uv) else np.ones(2)
            reps = np.maximum(hi - lo, 1.0)
            scale = max(reps.max() / MAX_TILES, 1.0)
            blocks.append(_tiled(lk.rgba, reps, scale))
            spans.append((lo, reps))
        else:
            colours.append(lk)
    palette = np.unique(np.concatenate(colours), axis=0) if colours else np.zeros((0, 4), np.uint8)
    if len(palette):
        side = math.ceil(math.sqrt(len(palette)))
        pal = np.zeros((math.ceil(len(palette) / side) * CELL, side * CELL, 4), np.uint8)
        for i, c in enumerate(palette):
            r, q = divmod(i, side)
            pal[r * CELL : (r + 1) * CELL, q * CELL : (q + 1) * CELL] = c
        blocks.append(pal)
    atlas, where = _pack(blocks)
    ah, aw = atlas.shape[:2]
    verts, faces, uvs = [], [], []
    base = 0
    k = 0
    for g, lk in zip(parts, looks, strict=True):
        v = np.asarray(g.vertices, np.float64)
        f = np.asarray(g.faces, np.int64)
        if isinstance(lk, _Image):
            (y0, x0), (bh, bw) = where[k], blocks[k].shape[:2]
            lo, reps = spans[k]
            s = (lk.uv - lo) / reps  # [0, 1] over the block
            px = x0 + np.clip(s[:, 0] * bw, 0.5, bw - 0.5)
            py = y0 + np.clip((1.0 - s[:, 1]) * bh, 0.5, bh - 0.5)
            uv = np.column_stack([px / aw, 1.0 - py / ah])
            k += 1
        else:  # flat colours: three vertices of its own per face, UVs at its colour's cell
            (y0, x0), (bh, bw) = where[-1], blocks[-1].shape[:2]
            cols = math.ceil(math.sqrt(len(palette)))
            rows = math.ceil(len(palette) / cols)
            idx = np.array([np.flatnonzero((palette == c).all(axis=1))[0] for c in lk])
            row, col = np.divmod(idx, cols)
            cu = (x0 + (col + 0.5) / cols * bw) / aw
            cv = 1.0 - (y0 + (row + 0.5) / rows * bh) / ah
            v = v[f.ravel()]
            f = np.arange(len(v)).reshape(-1, 3)
            uv = np.column_stack([np.repeat(cu, 3), np.repeat(cv, 3)])
        verts.append(v)
        faces.append(f + base)
        uvs.append(uv)
        base += len(v)
    from PIL import Image

    mesh = trimesh.Trimesh(np.concatenate(verts) * unit, np.concatenate(faces), process=False)
    mesh.visual = trimesh.visual.TextureVisuals(
        uv=np.concatenate(uvs),
        material=trimesh.visual.material.SimpleMaterial(image=Image.fromarray(atlas, "RGBA")),
    )
    return mesh


def _tiled(rgba: NDArray[np.uint8], reps: FloatArray, factor: float) -> NDArray[np.uint8]:
    """The image repeated ``reps`` (x, y) times, shrunk by ``factor``. Where the repeats would
    be large (UVs spanning hundreds of tiles: 15 GB for a 64-texel image over UVs 0..1000)
    each output texel is looked up in the one image instead, nearest to its centre, and the
    result holds at most ``MAX_TILED_TEXELS`` (a 2048² texture over UVs 0..20 took 10 GB)."""
    h, w = rgba.shape[:2]
    rx, ry = int(reps[0]), int(reps[1])
    if h * w * rx * ry <= MAX_TILED_TEXELS:
        return _shrink(np.tile(rgba, (ry, rx, 1)), factor)
    big_w, big_h = w * rx, h * ry
    factor = max(factor, math.sqrt(big_w * big_h / MAX_TILED_TEXELS))  # the same texel budget
    ow, oh = max(1, round(big_w / factor)), max(1, round(big_h / factor))
    xs = np.minimum(((np.arange(ow) + 0.5) * (big_w / ow)).astype(np.int64), big_w - 1) % w
    ys = np.minimum(((np.arange(oh) + 0.5) * (big_h / oh)).astype(np.int64), big_h - 1) % h
    return np.ascontiguousarray(rgba[ys[:, None], xs[None, :]])


def _shrink(img: NDArray[np.uint8], factor: float) -> NDArray[np.uint8]:
    if factor <= 1.0:
        return img
    from PIL import Image

    h, w = img.shape[:2]
    size = (max(1, round(w / factor)), max(1, round(h / factor)))
    out = Image.fromarray(img, "RGBA").resize(size, Image.Resampling.NEAREST)
    return np.asarray(out, np.uint8)


def _pack(blocks: list[NDArray[np.uint8]]) -> tuple[NDArray[np.uint8], list[tuple[int, int]]]:
    """Shelf packing, tallest first: the atlas and each block's (row, column) corner. Blocks
    are scaled down together when the atlas would exceed ``MAX_ATLAS`` a side."""
    scale = 1.0
    while True:
        sized = [_shrink(b, scale) for b in blocks]
        area = sum(b.shape[0] * b.shape[1] for b in sized)
        width = max(max(b.shape[1] for b in sized), math.ceil(math.sqrt(area)))
        order = sorted(range(len(sized)), key=lambda i: -sized[i].shape[0])
        where: list[tuple[int, int]] = [(0, 0)] * len(sized)
        x = y = shelf = 0
        for i in order:
            h, w = sized[i].shape[:2]
            if x + w > width:
                x, y, shelf = 0, y + shelf, 0
            where[i] = (y, x)
            x += w
            shelf = max(shelf, h)
        height = y + shelf
        if max(width, height) <= MAX_ATLAS or scale > 64:
            break
        scale *= max(width, height) / MAX_ATLAS * 1.01
    atlas = np.zeros((height, width, 4), np.uint8)
    # the space between blocks is opaque: no UV reaches it, and transparent padding would make
    # every multi-part model look cut out (and be ray-cast through its alpha)
    atlas[..., 3] = 255
    for b, (r, c) in zip(sized, where, strict=True):
        atlas[r : r + b.shape[0], c : c + b.shape[1]] = b
    if scale > 1.0:
        blocks[:] = sized
    return atlas, where
