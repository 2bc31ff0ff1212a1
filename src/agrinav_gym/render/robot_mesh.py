"""The Summit-XL's visual geometry as one coloured triangle mesh in base_link, from its URDF.

Read from the packaged URDF's ``<visual>`` boxes, cylinders and spheres (a link's pose from its
joint to base_link), so the mesh camera and the chase view show the robot the physics uses.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from functools import lru_cache
from typing import Any

import numpy as np

from ..robot import urdf_text
from .classes import ROBOT
from .plant_meshes import Prototype, rotation_rpy


def _floats(text: str | None, n: int) -> list[float]:
    vals = [float(v) for v in (text or "").split()]
    return vals if len(vals) == n else [0.0] * n


def _pose(el: ET.Element | None) -> np.ndarray:
    T = np.eye(4)
    if el is not None:
        T[:3, :3] = rotation_rpy(*_floats(el.get("rpy"), 3))
        T[:3, 3] = _floats(el.get("xyz"), 3)
    return T


@lru_cache(maxsize=2)
def robot_prototype(camera_housing: bool = True) -> Prototype:
    """The robot in base_link; without ``camera_housing`` the camera link (the mast-top camera
    itself, which its own rays would start inside) is left out."""
    import trimesh

    root = ET.fromstring(urdf_text())
    colours = {}
    for m in root.iter("material"):
        c = m.find("color")
        if m.get("name") and c is not None:
            colours[m.get("name")] = [round(255 * v) for v in _floats(c.get("rgba"), 4)]
    link_pose = {"base_link": np.eye(4)}
    for j in root.iter("joint"):
        parent, child = j.find("parent"), j.find("child")
        if parent is not None and child is not None and parent.get("link") == "base_link":
            link_pose[str(child.get("link"))] = _pose(j.find("origin"))
    parts: list[Any] = []
    for link in root.iter("link"):
        name = str(link.get("name"))
        if name not in link_pose or (name == "camera_link" and not camera_housing):
            continue
        for vis in link.iter("visual"):
            geo = vis.find("geometry")
            if geo is None or len(geo) == 0:
                continue
            g = geo[0]
            if g.tag == "box":
                part = trimesh.creation.box(extents=_floats(g.get("size"), 3))
            elif g.tag == "cylinder":
                part = trimesh.creation.cylinder(
                    radius=float(g.get("radius", 0)), height=float(g.get("length", 0)), sections=24
                )
            elif g.tag == "sphere":
                part = trimesh.creation.icosphere(subdivisions=2, radius=float(g.get("radius", 0)))
            else:
                continue
            part.apply_transform(link_pose[name] @ _pose(vis.find("origin")))
            mat = vis.find("material")
            rgba = colours.get(mat.get("name") if mat is not None else None, [128, 128, 128, 255])
            part.visual.face_colors = np.array(rgba, np.uint8)
            parts.append(part)
    mesh = trimesh.util.concatenate(parts)
    return Prototype.from_trimesh(mesh, "summit_xl", ROBOT)
