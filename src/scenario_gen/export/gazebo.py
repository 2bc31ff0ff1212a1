"""Gazebo worlds: SDF 1.7 for Gazebo Sim (Fortress and later) and for Gazebo Classic 11.

Layout of the export::

    worlds/field.sdf            Gazebo Sim   (spherical_coordinates heading 0)
    worlds/field_classic.world  Gazebo Classic 11 (heading 180, see below)
    models/<name>/model.config, model.sdf, meshes/, materials/textures/ (a user crop.model
                                referenced as its own files: user/ in its own layout)
    models/agrinav_obstacles/   the obstacles' meshes (obstacles.py), when the field has any
    setup.bash                  GAZEBO_MODEL_PATH / IGN_GAZEBO_RESOURCE_PATH / GZ_SIM_RESOURCE_PATH

The world frame is the scenario's ENU frame (x east, y north, z up) at the datum, so every
pose is the scenario's own number. Gazebo Sim's NavSat (``PositionTransform`` from
``LOCAL2``) reads ENU with ``heading_deg`` 0. Gazebo Classic 11's GPS sensor uses
``SphericalFromLocal``, whose LOCAL frame is rotated by 180° (gazebo-classic bug report 2022,
kept for backward compatibility), so the Classic world says ``heading_deg`` 180 — the same
compensation as Nav2's GPS demo world. Both then report the lat/lon of plants.csv.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np
from tqdm import tqdm

from ..model import Scenario
from .meshes import save_png
from .obstacles import write_gazebo_obstacles
from .options import ExportOptions
from .plantmodels import Assignment, assign, fmt, model_config, static_model_sdf, write_models
from .terrainmesh import heightmap, save_png16, soil_texture, write_terrain_dae
from .tiles import make_tiles, write_tiles

TERRAIN = "agrinav_terrain"
TERRAIN_HM = "agrinav_terrain_heightmap"

# Gazebo Sim drops its default systems once a world names any; these are the defaults plus the
# sensors a GNSS robot needs. Fortress names: Garden and Harmonic still accept them.
SIM_SYSTEMS = (
    ("physics", "Physics", ""),
    ("user-commands", "UserCommands", ""),
    ("scene-broadcaster", "SceneBroadcaster", ""),
    ("sensors", "Sensors", "<render_engine>ogre2</render_engine>"),
    ("imu", "Imu", ""),
    ("navsat", "NavSat", ""),
)


@dataclass(frozen=True)
class GazeboSummary:
    plants: int
    mode: str  # "include" or "tiles"
    models: int
    tiles: int
    triangles: int
    worlds: tuple[str, ...]
    obstacles: dict[str, int] | None = None  # count per kind; None: the field has none
    obstacle_mode: str = ""  # "models" (one static model each) or "tiles" (merged)
    obstacle_tiles: int = 0
    obstacle_triangles: int = 0


def spherical_xml(scn: Scenario, heading_deg: float) -> str:
    g = scn.geo
    return (
        "<spherical_coordinates>\n"
        "      <surface_model>EARTH_WGS84</surface_model>\n"
        "      <world_frame_orientation>ENU</world_frame_orientation>\n"
        f"      <latitude_deg>{g.lat:.10f}</latitude_deg>\n"
        f"      <longitude_deg>{g.lon:.10f}</longitude_deg>\n"
        f"      <elevation>{g.alt:.4f}</elevation>\n"
        f"      <heading_deg>{heading_deg:.1f}</heading_deg>\n"
        "    </spherical_coordinates>"
    )


def include_xml(uri: str, name: str, pose: str) -> str:
    return (
        f"<include><uri>model://{uri}</uri><name>{escape(name)}</name><pose>{pose}</pose></include>"
    )


def world_xml(scn: Scenario, body: list[str], flavour: str) -> str:
    """A whole world file; ``flavour`` is "sim" or "classic"."""
    classic = flavour == "classic"
    note = (
        "heading_deg 180: Gazebo Classic's SphericalFromLocal turns its local frame by 180 "
        "degrees (gazebo-classic bug report 2022); with it the GPS sensor reports ENU lat/lon"
        if classic
        else "heading_deg 0: Gazebo Sim's NavSat reads the world frame as ENU"
    )
    systems = (
        ""
        if classic
        else "\n    ".join(
            f'<plugin filename="ignition-gazebo-{f}-system" '
            f'name="ignition::gazebo::systems::{n}">{extra}</plugin>'
            for f, n, extra in SIM_SYSTEMS
        )
    )
    r = scn.route.xyz
    cam = ""
    if classic and len(r):
        x, y, z = r[0]
        cam = (
            '<gui fullscreen="0"><camera name="user_camera">'
            f"<pose>{fmt(x - 6, y - 6, z + 5, 0, 0.45, 0.785)}</pose></camera></gui>"
        )
    items = "\n    ".join(body)
    return f"""<?xml version="1.0"?>
<!-- AgriNav field "{escape(scn.spec.name)}" (seed {scn.seed}), written by agrinav export.
     World frame = the scenario's ENU frame: x east, y north, z up, metres from the datum.
     {note}. -->
<sdf version="1.7">
  <world name="agrinav_field">
    <physics name="default_physics" type="ode">
      <max_step_size>0.001</max_step_size>
      <real_time_factor>1.0</real_time_factor>
    </physics>
    {systems}
    <scene>
      <ambient>0.5 0.5 0.5 1</ambient>
      <background>0.70 0.80 0.95 1</background>
      <shadows>true</shadows>
    </scene>
    <light name="sun" type="directional">
      <cast_shadows>true</cast_shadows>
      <pose>0 0 50 0 0 0</pose>
      <diffuse>0.9 0.9 0.85 1</diffuse>
      <specular>0.2 0.2 0.2 1</specular>
      <direction>-0.4 0.3 -0.87</direction>
    </light>
    {spherical_xml(scn, 180.0 if classic else 0.0)}
    {cam}
    {items}
  </world>
</sdf>
"""


def terrain_model(scn: Scenario, models: Path) -> None:
    folder = models / TERRAIN
    (folder / "meshes").mkdir(parents=True)
    (folder / "materials" / "textures").mkdir(parents=True)
    write_terrain_dae(
        scn.terrain, folder / "meshes" / "terrain.dae", folder / "materials/textures/soil.png"
    )
    uri = f"model://{TERRAIN}/meshes/terrain.dae"
    geom = f"<geometry><mesh><uri>{uri}</uri></mesh></geometry>"
    parts = [
        f'<collision name="collision">{geom}</collision>',
        f'<visual name="visual">{geom}</visual>',
    ]
    (folder / "model.sdf").write_text(static_model_sdf(TERRAIN, parts))
    t = scn.terrain
    desc = f"terrain {t.shape[1]}x{t.shape[0]} nodes at {t.spacing:.4f} m, ENU at the datum"
    (folder / "model.config").write_text(model_config(TERRAIN, desc))


def heightmap_model(scn: Scenario, models: Path) -> None:
    folder = models / TERRAIN_HM
    (folder / "materials" / "textures").mkdir(parents=True)
    textures = folder / "materials" / "textures"
    img, side, (cx, cy), rng, square = heightmap(scn.terrain)
    save_png16(img, textures / "heightmap.png")
    save_png(soil_texture(square), textures / "soil.png")  # shaded like the mesh's texture
    flat = np.zeros((8, 8, 3), np.uint8) + np.array([128, 128, 255], np.uint8)
    save_png(flat, textures / "flat_normal.png")  # lighting comes from the heightmap itself
    zmin = float(scn.terrain.heights.min())
    tex = f"model://{TERRAIN_HM}/materials/textures"
    hm = (
        f"<heightmap><uri>model://{TERRAIN_HM}/materials/textures/heightmap.png</uri>"
        f"<size>{fmt(side, side, rng)}</size><pos>{fmt(cx, cy, zmin)}</pos>"
    )
    visual = (
        f"{hm}<texture><diffuse>{tex}/soil.png</diffuse><normal>{tex}/flat_normal.png</normal>"
        f"<size>{side:.3f}</size>"
    )
    parts = [
        f'<collision name="collision"><geometry>{hm}</heightmap></geometry></collision>',
        f'<visual name="visual"><geometry>{visual}</texture></heightmap></geometry></visual>',
    ]
    (folder / "model.sdf").write_text(static_model_sdf(TERRAIN_HM, parts))
    desc = f"16-bit heightmap {img.shape[1]}x{img.shape[0]}, {side:.2f} m square, Gazebo Sim"
    (folder / "model.config").write_text(model_config(TERRAIN_HM, desc))


def _plant_includes(scn: Scenario, a: Assignment) -> list[str]:
    p = scn.plants
    out = []
    for i in range(len(p)):
        pm = a.models[a.model[i]]
        pose = fmt(p.x[i], p.y[i], p.z[i]) + " " + fmt(p.roll[i], p.pitch[i], p.yaw[i], digits=7)
        out.append(include_xml(pm.variant(int(a.step[i])), f"plant_{i:06d}", pose))
    return out


def export_gazebo(scn: Scenario, out: Path, opts: ExportOptions) -> GazeboSummary:
    """Write worlds/, models/ and setup.bash for ``scn`` into ``out`` (an empty folder)."""
    models = out / "models"
    worlds = out / "worlds"
    models.mkdir()
    worlds.mkdir()
    a = assign(scn)
    terrain_model(scn, models)
    tiles_mode = opts.use_tiles(len(scn.plants))
    body = [include_xml(TERRAIN, "terrain", fmt(0, 0, 0, 0, 0, 0))]
    n_tiles = 0
    triangles = 0
    if tiles_mode:
        tiles = make_tiles(scn, opts.tile_plants)
        n_models = len(tiles) + len(write_models(models, a, only_base=True, only_user=True))
        for tile, tri in tqdm(
            write_tiles(models, scn, a, tiles), total=len(tiles), desc="tiles", unit="tile"
        ):
            body.append(
                include_xml(
                    tile.name,
                    tile.name.removeprefix("agrinav_"),
                    fmt(tile.origin[0], tile.origin[1], 0, 0, 0, 0),
                )
            )
            triangles += tri
        n_tiles = len(tiles)
    else:
        n_models = len(write_models(models, a))
        faces = np.array([len(pm.mesh.faces) for pm in a.models])
        triangles = int(faces[a.model].sum()) if len(a.model) else 0
        body += _plant_includes(scn, a)
    obs = None
    if len(scn.obstacles):  # nothing at all without obstacles: those exports keep their bytes
        obs = write_gazebo_obstacles(
            models,
            scn.obstacles,
            opts.use_tiles(len(scn.obstacles)),
            opts.tile_plants,
            float(scn.field.area),
        )
        body += obs.body
    names = ["field.sdf", "field_classic.world"]
    (worlds / names[0]).write_text(world_xml(scn, body, "sim"))
    (worlds / names[1]).write_text(world_xml(scn, body, "classic"))
    if opts.heightmap:
        heightmap_model(scn, models)
        hm_body = [include_xml(TERRAIN_HM, "terrain", fmt(0, 0, 0, 0, 0, 0)), *body[1:]]
        names.append("field_heightmap.sdf")
        (worlds / names[2]).write_text(world_xml(scn, hm_body, "sim"))
    (out / "setup.bash").write_text(SETUP)
    return GazeboSummary(
        len(scn.plants),
        "tiles" if tiles_mode else "include",
        n_models + 1 + int(opts.heightmap) + (obs.models if obs else 0),
        n_tiles,
        triangles,
        tuple(f"worlds/{n}" for n in names),
        scn.obstacles.counts() if obs else None,
        obs.mode if obs else "",
        obs.tiles if obs else 0,
        obs.triangles if obs else 0,
    )


SETUP = """# Source this file (". setup.bash") to let Gazebo find the models of this export.
_m="$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")" && pwd)/models"
export GAZEBO_MODEL_PATH="$_m${GAZEBO_MODEL_PATH:+:$GAZEBO_MODEL_PATH}"
export IGN_GAZEBO_RESOURCE_PATH="$_m${IGN_GAZEBO_RESOURCE_PATH:+:$IGN_GAZEBO_RESOURCE_PATH}"
export GZ_SIM_RESOURCE_PATH="$_m${GZ_SIM_RESOURCE_PATH:+:$GZ_SIM_RESOURCE_PATH}"
unset _m
"""
