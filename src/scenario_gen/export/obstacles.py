"""The scenario's obstacles (stones, litter, fallen stalks) in the exports.

Every export names an obstacle ``<kind>_<id>`` (``stone_000003``: its row in obstacles.csv) and
colours it by kind (``KIND_RGB``, also the previews'). Stones are drawn per obstacle (each has
its own outline seed), so there is one mesh per obstacle, whatever its kind.

Gazebo, like the plants, two ways (``ExportOptions.plants``: auto switches above
``include_limit`` obstacles):

- **models**: one static ``<model>`` per obstacle in the world itself, posed at the obstacle's
  pose, its visual and collision the obstacle's own mesh (binary STL in its object frame,
  ``models/agrinav_obstacles/meshes/<name>.stl``), its material the kind's colour;
- **tiles**: the meshes at their poses merged into square static tiles
  (``models/agrinav_obstacle_tile_rRRR_cCCC``): one STL per kind as the visuals, all of them
  as the collision. libsdformat 12 spends ≈ 13-17 ms and ≈ 5.3 MB per obstacle model
  (tools/sdf_check on 249 and 506 stones: 3.1 s and 1.3 GB, 8.4 s and 2.7 GB more than none;
  as one link each of a single model still 2.5 MB), as much as per plant ``<include>``, so
  the 60,000 obstacles the bounds allow could not load one model each.

Nothing here is written for a scenario without obstacles, so its exports keep their bytes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..obstacles import OBSTACLE_KINDS, Obstacles
from ..preview import OBSTACLE_RGB
from .meshes import write_stl
from .plantmodels import fmt, model_config, static_model_sdf
from .tiles import Tile, grid_tiles

#: merged obstacle tiles' folder and model names: ``<prefix>_rRRR_cCCC``
TILE_PREFIX = "agrinav_obstacle_tile"

#: The resource folder of the obstacles' meshes (model://agrinav_obstacles/meshes/<name>.stl).
OBSTACLES_MODEL = "agrinav_obstacles"

#: Colour per kind (sRGB 0-255), the previews' (``preview.OBSTACLE_RGB``)
KIND_RGB = OBSTACLE_RGB


def obstacle_name(kind: str, i: int) -> str:
    """The name of obstacle ``i`` in every export: its kind and its row in obstacles.csv."""
    return f"{kind}_{i:06d}"


def names(obs: Obstacles) -> list[str]:
    return [obstacle_name(str(k), i) for i, k in enumerate(obs.kind.tolist())]


def pose_matrix(obs: Obstacles, i: int) -> NDArray[np.float64]:
    """4x4 object-to-ENU transform of obstacle ``i`` (R = Rz(yaw)·Ry(pitch)·Rx(roll))."""
    m = np.eye(4)
    m[:3, :3] = obs.rotation(i)
    m[:3, 3] = (obs.x[i], obs.y[i], obs.z[i])
    return m


def _material(kind: str) -> str:
    r, g, b = (np.array(KIND_RGB[kind]) / 255.0).tolist()
    return (
        f"<material><ambient>{fmt(r, g, b, 1, digits=4)}</ambient>"
        f"<diffuse>{fmt(r, g, b, 1, digits=4)}</diffuse>"
        "<specular>0.05 0.05 0.05 1</specular></material>"
    )


def _geometry(name: str) -> str:
    return (
        f"<geometry><mesh><uri>model://{OBSTACLES_MODEL}/meshes/{name}.stl</uri></mesh></geometry>"
    )


def _link(obs: Obstacles, i: int, name: str, link: str, pose: str = "") -> str:
    kind = str(obs.kind[i])
    return (
        f'<link name="{link}">{pose}'
        f'<visual name="visual">{_geometry(name)}{_material(kind)}</visual>'
        f'<collision name="collision">{_geometry(name)}</collision></link>'
    )


def _pose(obs: Obstacles, i: int) -> str:
    # positions to 1 µm and angles to 1e-7 rad, as the plants' poses
    return (
        f"<pose>{fmt(obs.x[i], obs.y[i], obs.z[i])} "
        f"{fmt(obs.roll[i], obs.pitch[i], obs.yaw[i], digits=7)}</pose>"
    )


@dataclass(frozen=True)
class GazeboObstacles:
    """What the world gets: its ``<model>``s or ``<include>``s, and what was written."""

    body: list[str]
    mode: str  # "models" or "tiles"
    models: int  # model folders written
    tiles: int
    triangles: int


def write_gazebo_obstacles(
    models_dir: Path, obs: Obstacles, tiles: bool, per_tile: int, area: float
) -> GazeboObstacles:
    """Write the obstacles' meshes and models under ``models_dir``: one model each, or (with
    ``tiles``) merged into tiles of about ``per_tile`` obstacles over the field's ``area``."""
    if tiles:
        return _write_tiles(models_dir, obs, grid_tiles(obs.x, obs.y, area, per_tile, TILE_PREFIX))
    folder = models_dir / OBSTACLES_MODEL
    (folder / "meshes").mkdir(parents=True)
    body: list[str] = []
    links: list[str] = []
    triangles = 0
    for i, name in enumerate(names(obs)):
        v, f = obs.local_mesh(i)
        write_stl(folder / "meshes" / f"{name}.stl", v[f])
        triangles += len(f)
        body.append(
            f'<model name="{name}"><static>true</static>{_pose(obs, i)}'
            f"{_link(obs, i, name, 'link')}</model>"
        )
        links.append(_link(obs, i, name, name, _pose(obs, i)))
    counts = ", ".join(f"{n} {k}" for k, n in obs.counts().items())
    # model.sdf: all of them as one static model (a link each, in the ENU frame), for inserting
    # the field's obstacles into another world; this export's worlds place each on its own
    (folder / "model.sdf").write_text(static_model_sdf(OBSTACLES_MODEL, links, link=None))
    desc = (
        f"{len(obs)} obstacles ({counts}): one binary STL each in its own frame; "
        "the worlds place each as a static model; agrinav export"
    )
    (folder / "model.config").write_text(model_config(OBSTACLES_MODEL, desc))
    return GazeboObstacles(body, "models", 1, 0, triangles)


def _write_tiles(models_dir: Path, obs: Obstacles, tiles: list[Tile]) -> GazeboObstacles:
    body: list[str] = []
    triangles = 0
    for tile in tiles:
        ox, oy = tile.origin
        folder = models_dir / tile.name
        (folder / "meshes").mkdir(parents=True)
        by_kind: dict[str, list[NDArray[np.float64]]] = {k: [] for k in OBSTACLE_KINDS}
        for i in tile.plants.tolist():  # (``plants``: the tile's members) in csv order
            v, f = obs.mesh(i)
            by_kind[str(obs.kind[i])].append(v[f] - [ox, oy, 0.0])
        parts = []
        every = []
        for kind, tris in by_kind.items():
            if not tris:
                continue
            tri = np.concatenate(tris)
            every.append(tri)
            triangles += len(tri)
            write_stl(folder / "meshes" / f"{kind}.stl", tri)
            parts.append(
                f'<visual name="{kind}"><geometry><mesh><uri>model://{tile.name}/meshes/'
                f"{kind}.stl</uri></mesh></geometry>{_material(kind)}</visual>"
            )
        # one collision mesh for the tile: one <collision> per obstacle costs libsdformat as
        # much DOM as a model each (see the module docstring)
        write_stl(folder / "meshes" / "collision.stl", np.concatenate(every))
        parts.append(
            f'<collision name="collision"><geometry><mesh><uri>model://{tile.name}/meshes/'
            "collision.stl</uri></mesh></geometry></collision>"
        )
        (folder / "model.sdf").write_text(static_model_sdf(tile.name, parts))
        sel = obs.kind[tile.plants]
        counts = ", ".join(f"{int((sel == k).sum())} {k}" for k in OBSTACLE_KINDS)
        desc = f"{len(tile.plants)} obstacles merged (static: {counts}); agrinav export"
        (folder / "model.config").write_text(model_config(tile.name, desc))
        body.append(
            f"<include><uri>model://{tile.name}</uri>"
            f"<name>{tile.name.removeprefix('agrinav_')}</name>"
            f"<pose>{fmt(ox, oy, 0, 0, 0, 0)}</pose></include>"
        )
    return GazeboObstacles(body, "tiles", len(tiles), len(tiles), triangles)


# ---------------------------------------------------------------------------- mesh export
#: ENU (x east, y north, z up) to glTF's Y-up axes (x east, y up, z south)
ENU_TO_Y_UP = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]])


def write_obstacle_mesh(obs: Obstacles, path: Path) -> None:
    """Every obstacle of ``obs`` into one file, by the suffix of ``path``.

    GLB and COLLADA: one node per obstacle, named ``<kind>_<id>``, holding its mesh in its own
    frame and its pose as the node's transform (GLB in glTF's Y-up axes), coloured by kind.
    OBJ: one object (``o <kind>_<id>``) each, vertices in ENU (OBJ has no transforms). PLY has
    no names: one mesh in ENU whose faces carry their colour, ``obstacle`` (the id) and
    ``kind`` (an index into the header's ``comment kind`` lines).
    """
    suffix = path.suffix.lower().lstrip(".")
    if suffix == "dae":
        _write_dae(obs, path)
    elif suffix == "ply":
        _write_ply(obs, path)
    elif suffix in ("glb", "obj"):
        _scene(obs, y_up=suffix == "glb").export(path)
    else:
        raise ValueError(f"no obstacle writer for {path.name}")


def _scene(obs: Obstacles, y_up: bool) -> Any:
    import trimesh

    scene = trimesh.Scene()
    for i, name in enumerate(names(obs)):
        v, f = obs.local_mesh(i)
        m = trimesh.Trimesh(v, f, process=False)
        rgba = (*KIND_RGB[str(obs.kind[i])], 255)
        m.visual = trimesh.visual.ColorVisuals(m, face_colors=np.tile(rgba, (len(f), 1)))
        t = pose_matrix(obs, i)
        scene.add_geometry(
            m, node_name=name, geom_name=name, transform=ENU_TO_Y_UP @ t if y_up else t
        )
    return scene


def _numbers(values: NDArray[np.float64], digits: int) -> str:
    return " ".join(f"{v + 0.0:.{digits}f}" for v in np.asarray(values, np.float64).ravel())


def _write_dae(obs: Obstacles, path: Path) -> None:
    """COLLADA 1.4.1, Z up, metres: a geometry and a node per obstacle, a material per kind.
    (trimesh's writer names everything by random UUIDs and says Y_UP: not reproducible.)"""
    effects = []
    materials = []
    for kind in OBSTACLE_KINDS:
        r, g, b = (np.array(KIND_RGB[kind]) / 255.0).tolist()
        effects.append(
            f'<effect id="{kind}-effect"><profile_COMMON><technique sid="common"><lambert>'
            f"<diffuse><color>{r:.4f} {g:.4f} {b:.4f} 1</color></diffuse></lambert></technique>"
            "</profile_COMMON></effect>"
        )
        materials.append(
            f'<material id="{kind}-material" name="{kind}">'
            f'<instance_effect url="#{kind}-effect"/></material>'
        )
    with open(path, "w") as f:
        f.write(
            '<?xml version="1.0" encoding="utf-8"?>\n'
            '<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">\n'
            "<asset><contributor><authoring_tool>agrinav export</authoring_tool></contributor>\n"
            '<unit name="meter" meter="1"/><up_axis>Z_UP</up_axis></asset>\n'
            f"<library_effects>{''.join(effects)}</library_effects>\n"
            f"<library_materials>{''.join(materials)}</library_materials>\n"
            "<library_geometries>\n"
        )
        for i, name in enumerate(names(obs)):
            v, fc = obs.local_mesh(i)
            f.write(
                f'<geometry id="{name}-mesh" name="{name}"><mesh>'
                f'<source id="{name}-positions"><float_array id="{name}-positions-array" '
                f'count="{v.size}">{_numbers(v, 6)}</float_array><technique_common>'
                f'<accessor source="#{name}-positions-array" count="{len(v)}" stride="3">'
                '<param name="X" type="float"/><param name="Y" type="float"/>'
                '<param name="Z" type="float"/></accessor></technique_common></source>'
                f'<vertices id="{name}-vertices"><input semantic="POSITION" '
                f'source="#{name}-positions"/></vertices>'
                f'<triangles material="material" count="{len(fc)}">'
                f'<input semantic="VERTEX" source="#{name}-vertices" offset="0"/>'
                f"<p>{' '.join(map(str, fc.ravel().tolist()))}</p></triangles></mesh></geometry>\n"
            )
        f.write('</library_geometries>\n<library_visual_scenes><visual_scene id="scene">\n')
        for i, name in enumerate(names(obs)):
            kind = str(obs.kind[i])
            f.write(
                f'<node id="{name}" name="{name}" type="NODE">'
                f'<matrix sid="transform">{_numbers(pose_matrix(obs, i), 9)}</matrix>'
                f'<instance_geometry url="#{name}-mesh"><bind_material><technique_common>'
                f'<instance_material symbol="material" target="#{kind}-material"/>'
                "</technique_common></bind_material></instance_geometry></node>\n"
            )
        f.write(
            "</visual_scene></library_visual_scenes>\n"
            '<scene><instance_visual_scene url="#scene"/></scene>\n</COLLADA>\n'
        )


def _write_ply(obs: Obstacles, path: Path) -> None:
    """Binary PLY: ENU vertices (double), faces with colour, obstacle id and kind index."""
    v, faces, owner = obs.meshes()
    kind_index = np.array([OBSTACLE_KINDS.index(str(k)) for k in obs.kind], np.uint8)
    rgb = np.array([KIND_RGB[k] for k in OBSTACLE_KINDS], np.uint8)
    face = np.zeros(
        len(faces),
        [("n", "u1"), ("v", "<i4", (3,)), ("rgb", "u1", (3,)), ("obstacle", "<i4"), ("kind", "u1")],
    )
    face["n"] = 3
    face["v"] = faces
    face["rgb"] = rgb[kind_index[owner]]
    face["obstacle"] = owner
    face["kind"] = kind_index[owner]
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        "comment agrinav export: obstacles, ENU metres (x east, y north, z up)\n"
        + "".join(f"comment kind {k} {name}\n" for k, name in enumerate(OBSTACLE_KINDS))
        + f"element vertex {len(v)}\n"
        "property double x\nproperty double y\nproperty double z\n"
        f"element face {len(faces)}\n"
        "property list uchar int vertex_indices\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\n"
        "property int obstacle\nproperty uchar kind\nend_header\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(np.ascontiguousarray(v, "<f8").tobytes())
        f.write(face.tobytes())
