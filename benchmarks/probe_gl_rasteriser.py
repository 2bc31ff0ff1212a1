"""Probe: would rasterising primary rays reach 20× TinyRenderer?

Renders the paper's P1 field from the lane centre at 848 × 480 with OpenGL 3.3 through EGL
(``moderngl``; on a machine without a GPU, Mesa's llvmpipe on the CPU): the same plant
prototypes instanced with the mesh camera's transforms plus the whole terrain mesh, into a
linear-depth, plant-id and colour target, read back to numpy — against pybullet's
TinyRenderer on the same triangles (``bench_mesh_camera.load_pybullet``), alternating, medians.
Twice: every plant, and only the plants in the camera's horizontal field of view within the
colour camera's 12 m (the terrain always whole). Nothing of the D455 model (noise, stereo
holes, shading) is in it: it bounds what the rasteriser alone costs.

Needs ``pip install moderngl`` and an EGL driver (Debian: libegl1, libgl1-mesa-dri).
Run: ``LP_NUM_THREADS=2 python benchmarks/probe_gl_rasteriser.py``.
"""

from __future__ import annotations

import math
import platform
import statistics
import sys
import time
from typing import Any

import numpy as np

import scenario_gen as sg
from agrinav_gym.config import EnvConfig
from agrinav_gym.render.mesh_scene import MeshScene
from agrinav_gym.robot import RobotGeometry, robot_interface
from bench_mesh_camera import load_pybullet
from common import lane_centre_pose, pybullet_camera

W, H = 848, 480
VERTEX = """
#version 330
uniform mat4 vp;
in vec3 pos; in vec4 r0; in vec4 r1; in vec4 r2; in int pid;
flat out int id; out float vz;
void main() {
    vec4 q = vec4(pos, 1.0);
    gl_Position = vp * vec4(dot(r0, q), dot(r1, q), dot(r2, q), 1.0);
    id = pid;
    vz = gl_Position.w;
}"""
FRAGMENT = """
#version 330
flat in int id; in float vz;
layout(location = 0) out float depth;
layout(location = 1) out int inst;
layout(location = 2) out vec4 col;
void main() {
    depth = vz;
    inst = id;
    col = vec4(0.3, 0.6, 0.2, 1.0) * (0.5 + 0.5 * float(gl_PrimitiveID % 7) / 7.0);
}"""


def main() -> None:
    try:
        import moderngl
    except ImportError:
        sys.exit("this probe needs moderngl: pip install moderngl")
    import pybullet as p

    scn = sg.generate(sg.preset("paper-p1"), 0)
    scene = MeshScene.from_scenario(scn)
    cid, tris = load_pybullet(scn, scene)
    cfg = EnvConfig.from_dict({"camera": {"width": W, "height": H}})
    model = robot_interface(cfg, RobotGeometry.from_urdf()).camera
    rot, pos = lane_centre_pose(scn)
    view, proj = pybullet_camera(cid, model, rot, pos, cfg.camera.vfov_deg, cfg.camera.max_range)
    o = pos + rot @ np.asarray(model.position)
    axis = rot @ model.rotation
    ctx = moderngl.create_standalone_context(backend="egl")
    gl_name = ctx.info["GL_RENDERER"]
    print(f"machine: {platform.machine()}, {platform.python_version()}; GL: {gl_name}")
    prog = ctx.program(vertex_shader=VERTEX, fragment_shader=FRAGMENT)
    origin = scene.origin
    # pybullet's matrices are column-major; the model's coordinates are relative to origin
    shift = np.eye(4, dtype="f4")
    shift[:3, 3] = origin
    vp = np.array(proj, "f4").reshape(4, 4).T @ np.array(view, "f4").reshape(4, 4).T @ shift
    prog["vp"].write(vp.T.astype("f4").tobytes())
    ctx.enable(moderngl.DEPTH_TEST)
    targets = [
        ctx.renderbuffer((W, H), 1, dtype="f4"),
        ctx.renderbuffer((W, H), 1, dtype="i4"),
        ctx.renderbuffer((W, H), 4),
    ]
    fbo = ctx.framebuffer(targets, ctx.depth_renderbuffer((W, H)))
    terrain = scn.terrain.to_trimesh()
    ident = ctx.buffer(np.array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0], "f4").tobytes())
    tvao = ctx.vertex_array(
        prog,
        [
            (ctx.buffer((np.asarray(terrain.vertices) - origin).astype("f4")), "3f", "pos"),
            (ident, "4f 4f 4f/i", "r0", "r1", "r2"),
            (ctx.buffer(np.array([-1], "i4").tobytes()), "i/i", "pid"),
        ],
        ctx.buffer(np.asarray(terrain.faces).astype("i4").tobytes()),
    )
    pm = scene.plants
    assert pm is not None
    rel = np.column_stack([pm.x, pm.y]) - o[:2]
    f2 = axis[:2, 0] / np.linalg.norm(axis[:2, 0])
    ahead = rel @ f2
    side = np.abs(rel @ np.array([-f2[1], f2[0]]))
    half = math.radians(45.0)  # the colour camera's half HFOV
    in_view = (ahead > -1.0) & (side <= ahead * math.tan(half) + 1.0)
    in_view &= np.hypot(rel[:, 0], rel[:, 1]) < 2 * cfg.camera.max_range

    def plant_vaos(keep: np.ndarray) -> tuple[list[tuple[Any, int]], int]:
        out, n_tri = [], len(terrain.faces)
        for k, pr in enumerate(pm.prototypes):
            ids = np.flatnonzero((pm.proto == k) & keep)
            if len(ids) == 0:
                continue
            x = pm.transforms(ids, origin).reshape(-1, 12).astype("f4")
            vao = ctx.vertex_array(
                prog,
                [
                    (ctx.buffer(pr.vertices.astype("f4").tobytes()), "3f", "pos"),
                    (ctx.buffer(x.tobytes()), "4f 4f 4f/i", "r0", "r1", "r2"),
                    (ctx.buffer(ids.astype("i4").tobytes()), "i/i", "pid"),
                ],
                ctx.buffer(pr.faces.astype("i4").tobytes()),
            )
            out.append((vao, len(ids)))
            n_tri += len(pr.faces) * len(ids)
        return out, n_tri

    for label, keep in (("every plant", np.ones(len(pm), bool)), ("plants in view", in_view)):
        vaos, n_tri = plant_vaos(keep)

        def frame(vaos: list[tuple[Any, int]] = vaos) -> tuple[np.ndarray, ...]:
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            tvao.render()
            for vao, n in vaos:
                vao.render(instances=n)
            d = np.frombuffer(fbo.read(attachment=0, components=1, dtype="f4"), "f4")
            i = np.frombuffer(fbo.read(attachment=1, components=1, dtype="i4"), "i4")
            c = np.frombuffer(fbo.read(attachment=2, components=3), "u1")
            return d, i, c

        frame()
        gl, tiny = [], []
        for _ in range(5):
            t0 = time.perf_counter()
            p.getCameraImage(W, H, view, proj, renderer=p.ER_TINY_RENDERER, physicsClientId=cid)
            tiny.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            _, i, _ = frame()
            gl.append(time.perf_counter() - t0)
        t_tiny, t_gl = statistics.median(tiny), statistics.median(gl)
        print(
            f"{label:15s} ({int(keep.sum())} plants, {n_tri:,} triangles; TinyRenderer "
            f"{tris:,}): TinyRenderer {t_tiny * 1e3:.0f} ms, GL depth+id+colour with read-back "
            f"{t_gl * 1e3:.1f} ms = {t_tiny / t_gl:.1f}x; plant pixels {(i >= 0).sum()}"
        )
    p.disconnect(cid)


if __name__ == "__main__":
    main()
