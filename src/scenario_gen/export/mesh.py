"""Meshes for 3-D tools: the terrain (and optionally every plant, merged, and every obstacle,
one node each) as GLB/OBJ/PLY/DAE.

The terrain goes through ``sources.export_terrain_mesh`` (the mesh a scenario can be generated
from, so a round trip works). Plants are the Gazebo tiles' geometry in one mesh — each plant's
model at its pose and exact size, coloured per face. Obstacles (``--with-plants`` too: the
field's objects, beside the terrain) go to ``obstacles.*`` by ``obstacles.write_obstacle_mesh``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..model import Scenario
from ..sources import export_terrain_mesh, save_mesh
from .options import ExportOptions
from .plantmodels import Assignment, assign
from .tiles import rotations

#: Triangles of the merged plants one export writes: a file holds them all in memory while it
#: is written (≈ 1.6 KB a triangle for OBJ and DAE, 0.7 KB for GLB: 8 M took 13 GB as OBJ).
#: The mature-corn preset's 2,214 plants are 1.0 M.
MAX_MERGED_TRIANGLES = 4_000_000


def check_merged_size(a: Assignment) -> int:
    """The merged plants' triangles, refused past ``MAX_MERGED_TRIANGLES`` before any work."""
    counts = np.bincount(a.model, minlength=len(a.models))
    total = sum(int(n) * len(pm.mesh.faces) for n, pm in zip(counts, a.models, strict=True))
    if total > MAX_MERGED_TRIANGLES:
        per = max(len(pm.mesh.faces) for pm in a.models)
        raise InputError(
            "--with-plants",
            f"{total:,} triangles ({len(a.model):,} plants of up to {per:,})",
            f"allowed: at most {MAX_MERGED_TRIANGLES:,} in one merged mesh; a model of fewer "
            "triangles, a smaller field, or --to gazebo (which references each model once)",
        )
    return total


def merged_plants(scn: Scenario, a: Assignment | None = None) -> Any:
    """Every plant's mesh at its pose and height, as one face-coloured trimesh (ENU, Z up);
    ``a``: the plants' models, where the caller has them already."""
    import trimesh

    from .meshes import face_colours, opaque_faces

    a = assign(scn) if a is None else a
    p = scn.plants
    parts = []
    for m, pm in enumerate(a.models):
        sel = np.flatnonzero(a.model == m)
        if len(sel) == 0:
            continue
        keep = opaque_faces(pm.mesh)  # a cut-out face is not painted its hidden colour
        v = np.asarray(pm.mesh.vertices, np.float64)
        f = np.asarray(pm.mesh.faces, np.int64)[keep]
        rot = rotations(p.roll[sel], p.pitch[sel], p.yaw[sel])
        rot *= (p.height[sel] / pm.height)[:, None, None]
        verts = np.einsum("kij,vj->kvi", rot, v) + np.column_stack([p.x, p.y, p.z])[sel, None]
        faces = f[None] + len(v) * np.arange(len(sel))[:, None, None]
        mesh = trimesh.Trimesh(verts.reshape(-1, 3), faces.reshape(-1, 3), process=False)
        rgb = np.tile(face_colours(pm.mesh)[keep], (len(sel), 1))
        mesh.visual = trimesh.visual.ColorVisuals(
            mesh, face_colors=np.column_stack([rgb, np.full(len(rgb), 255, np.uint8)])
        )
        parts.append(mesh)
    return trimesh.util.concatenate(parts) if parts else None


def _unshared(mesh: Any) -> Any:
    """A face-coloured trimesh with three vertices of its own per face, colours kept."""
    import trimesh

    f = np.asarray(mesh.faces)
    out = trimesh.Trimesh(
        np.asarray(mesh.vertices)[f.ravel()], np.arange(f.size).reshape(-1, 3), process=False
    )
    out.visual = trimesh.visual.ColorVisuals(out, face_colors=mesh.visual.face_colors)
    return out


def export_mesh(scn: Scenario, out: Path, opts: ExportOptions) -> dict[str, Any]:
    from .preview import render_export_preview
    from .readme import mesh_readme

    a = assign(scn) if opts.mesh_plants else None
    if a is not None:
        check_merged_size(a)
    files = []
    for fmt in opts.formats:
        name = f"terrain.{fmt}"
        export_terrain_mesh(scn.terrain, out / name)
        files.append(name)
    if opts.mesh_plants:
        plants = merged_plants(scn, a)
        if plants is not None:
            for fmt in opts.formats:
                name = f"plants.{fmt}"
                # glTF and OBJ carry colours per vertex: each face gets vertices of its own, so
                # no vertex is shared by two colours (and blended between them)
                own = plants if fmt == "ply" else _unshared(plants)
                if fmt in ("glb", "gltf"):  # glTF is Y-up: x east, y up, z south
                    y_up = own.copy()
                    y_up.vertices = np.column_stack(
                        [own.vertices[:, 0], own.vertices[:, 2], -own.vertices[:, 1]]
                    )
                    y_up.export(out / name)
                else:
                    save_mesh(own, out / name)
                files.append(name)
        if len(scn.obstacles):  # the field's other objects, one node each (obstacles.py)
            from .obstacles import write_obstacle_mesh

            for fmt in opts.formats:
                write_obstacle_mesh(scn.obstacles, out / f"obstacles.{fmt}")
                files.append(f"obstacles.{fmt}")
    (out / "README.md").write_text(mesh_readme(scn, files))
    render_export_preview(scn, out / "preview.png")
    return {"files": files}
