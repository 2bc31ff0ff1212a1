"""Writes the test crop models beside this file (run it after changing it; the files are
committed): small COLLADA and OBJ plants with known texel colours and an alpha cut-out.

``cutout_plant/``: Gazebo's model layout (``meshes/plant.dae`` naming
``../materials/textures/leaf.png`` and ``stem.png``): a 0.6 × 0.8 m leaf quad in the model's
y-z plane from z = 0.2 to 1.0 m whose texture is ``LEAF`` green in its middle half of columns
and cut out (alpha 0, magenta) in the outer quarters, and a 2 × 2 cm ``STEM`` brown stalk
1 m tall 5 cm behind it (+x). Two geometries with a texture each: the colours only survive
if each part keeps its own texels.

``textured_obj/``: ``plant.obj`` with ``plant.mtl`` (``map_Kd plant.png``, ``Kd 0.8``): a box
stalk 0.1 × 0.1 × 0.5 m whose texture is ``OBJ_RGB``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

HERE = Path(__file__).resolve().parent
LEAF = (40, 150, 40)
STEM = (120, 90, 50)
CUT = (255, 0, 255)  # the colour under the cut-out texels: never seen where alpha works
OBJ_RGB = (200, 60, 30)


def _floats(a: np.ndarray) -> str:
    return " ".join(f"{v:.5f}" for v in np.asarray(a, float).ravel())


def _geometry(i: int, pos: np.ndarray, uv: np.ndarray, faces: np.ndarray) -> str:
    idx = " ".join(str(int(k)) for k in faces.ravel())
    xyz = "".join(f'<param name="{c}" type="float"/>' for c in "XYZ")
    st = "".join(f'<param name="{c}" type="float"/>' for c in "ST")
    return f"""<geometry id="g{i}" name="part{i}"><mesh>
<source id="p{i}"><float_array id="p{i}a" count="{pos.size}">{_floats(pos)}</float_array>
<technique_common><accessor source="#p{i}a" count="{len(pos)}" stride="3">{xyz}</accessor>
</technique_common></source>
<source id="t{i}"><float_array id="t{i}a" count="{uv.size}">{_floats(uv)}</float_array>
<technique_common><accessor source="#t{i}a" count="{len(uv)}" stride="2">{st}</accessor>
</technique_common></source>
<vertices id="v{i}"><input semantic="POSITION" source="#p{i}"/></vertices>
<triangles material="m{i}" count="{len(faces)}">
<input semantic="VERTEX" source="#v{i}" offset="0"/>
<input semantic="TEXCOORD" source="#t{i}" offset="0" set="0"/><p>{idx}</p></triangles>
</mesh></geometry>"""


def write_dae(path: Path, parts: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]) -> None:
    """COLLADA 1.4.1, Z up, metres: one geometry and one textured material per part."""
    images = "".join(
        f'<image id="img{i}"><init_from>{tex}</init_from></image>'
        for i, (tex, *_) in enumerate(parts)
    )
    effects = "".join(
        f'<effect id="e{i}"><profile_COMMON><newparam sid="s{i}"><surface type="2D">'
        f'<init_from>img{i}</init_from></surface></newparam><newparam sid="sm{i}"><sampler2D>'
        f'<source>s{i}</source></sampler2D></newparam><technique sid="common"><lambert><diffuse>'
        f'<texture texture="sm{i}" texcoord="UVMap"/></diffuse></lambert></technique>'
        "</profile_COMMON></effect>"
        for i in range(len(parts))
    )
    materials = "".join(
        f'<material id="mat{i}"><instance_effect url="#e{i}"/></material>'
        for i in range(len(parts))
    )
    geometries = "".join(_geometry(i, *p[1:]) for i, p in enumerate(parts))
    nodes = "".join(
        f'<node id="n{i}"><instance_geometry url="#g{i}"><bind_material><technique_common>'
        f'<instance_material symbol="m{i}" target="#mat{i}"><bind_vertex_input semantic="UVMap" '
        'input_semantic="TEXCOORD" input_set="0"/></instance_material></technique_common>'
        "</bind_material></instance_geometry></node>"
        for i in range(len(parts))
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        '<?xml version="1.0" encoding="utf-8"?>\n'
        '<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">\n'
        '<asset><unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>\n'
        f"<library_images>{images}</library_images>\n"
        f"<library_effects>{effects}</library_effects>\n"
        f"<library_materials>{materials}</library_materials>\n"
        f"<library_geometries>{geometries}</library_geometries>\n"
        f'<library_visual_scenes><visual_scene id="scene">{nodes}</visual_scene>'
        "</library_visual_scenes>\n"
        '<scene><instance_visual_scene url="#scene"/></scene>\n</COLLADA>\n'
    )


def box(lo: tuple[float, ...], hi: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    b = trimesh.creation.box(bounds=np.array([lo, hi], float))
    return np.asarray(b.vertices), np.asarray(b.faces)


def cutout_plant(root: Path) -> None:
    tex = root / "materials" / "textures"
    tex.mkdir(parents=True, exist_ok=True)
    leaf = np.zeros((16, 16, 4), np.uint8)
    leaf[..., :3] = CUT
    leaf[:, 4:12, :3] = LEAF
    leaf[:, 4:12, 3] = 255
    Image.fromarray(leaf, "RGBA").save(tex / "leaf.png")
    Image.fromarray(np.full((4, 4, 3), STEM, np.uint8)).save(tex / "stem.png")
    quad = np.array([[0, -0.3, 0.2], [0, 0.3, 0.2], [0, 0.3, 1.0], [0, -0.3, 1.0]])
    quad_uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    quad_f = np.array([[0, 1, 2], [0, 2, 3]])
    sv, sf = box((0.04, -0.01, 0.0), (0.06, 0.01, 1.0))
    stem_uv = np.full((len(sv), 2), 0.5)
    write_dae(
        root / "meshes" / "plant.dae",
        [
            ("../materials/textures/leaf.png", quad, quad_uv, quad_f),
            ("../materials/textures/stem.png", sv, stem_uv, sf),
        ],
    )


def textured_obj(root: Path) -> None:
    root.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.full((4, 4, 3), OBJ_RGB, np.uint8)).save(root / "plant.png")
    (root / "plant.mtl").write_text("newmtl stalk\nKd 0.8 0.8 0.8\nmap_Kd plant.png\n")
    v, f = box((-0.05, -0.05, 0.0), (0.05, 0.05, 0.5))
    lines = ["mtllib plant.mtl", *(f"v {x:.4f} {y:.4f} {z:.4f}" for x, y, z in v)]
    lines += ["vt 0.25 0.25", "vt 0.75 0.25", "vt 0.5 0.75", "usemtl stalk"]
    lines += [f"f {a + 1}/1 {b + 1}/2 {c + 1}/3" for a, b, c in f]
    (root / "plant.obj").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    cutout_plant(HERE / "cutout_plant")
    textured_obj(HERE / "textured_obj")
