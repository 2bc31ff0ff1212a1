"""CPU ray-casting backends on the same scene and rays.

The scene is what the mesh camera loads at one robot pose: the terrain tiles and plants of its
view, (a) on the paper's P1 field (1 × 1 m, 1.2 m maize) and (b) in mature maize (2.5 m, 1 m
rows, 0.18 m in the row). The rays are the D455 depth camera's at 64 × 48 and 848 × 480.

* ``embree-ctypes`` (chosen): Embree 4 from the ``embreex`` wheel through ``render/embree.py``,
  plants as instances of shared prototypes, 8-ray packets;
* ``embreex``: the same Embree through the ``embreex`` Python API (flat copied mesh, no
  instancing, one ray at a time in C);
* ``open3d``: ``open3d.t.geometry.RaycastingScene`` (flat copied mesh, its own threads);
* ``warp``: NVIDIA Warp ``wp.Mesh`` + ``mesh_query_ray`` in a kernel on the CPU device.

Backends that are not installed are skipped (``pip install open3d-cpu warp-lang``). Build time
(first frame's scene), cast time (median of several), the hit agreement with embree-ctypes and
the geometry each holds are printed. Run: ``python benchmarks/bench_raycast_backends.py``.
"""

from __future__ import annotations

import importlib.util
import platform
import statistics
import time
from typing import Any

import numpy as np

import scenario_gen as sg
from agrinav_gym.config import EnvConfig
from agrinav_gym.render.mesh_scene import MeshScene
from agrinav_gym.robot import RobotGeometry, robot_interface
from agrinav_gym.sensors.mesh_camera import MeshCamera
from common import lane_centre_pose

SCENES = {
    "paper-p1": ("paper-p1", {}),
    "maize 2.5 m": ("default", {"crop": {"stage": 5}, "layout": {"row_spacing": 1.0}}),
}


def _median_time(fn: Any, n: int) -> float:
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return statistics.median(out)


def flat_geometry(scene: MeshScene) -> tuple[np.ndarray, np.ndarray]:
    """The attached tiles as one triangle soup relative to the scene origin (what a backend
    without instancing must hold)."""
    verts, faces, off = [], [], 0
    for key in sorted(scene._attached):
        tile = scene._cache[key]
        if tile.terrain is not None:
            v, f = tile.terrain._keep[0]
            verts.append(v[:-1])
            faces.append(f.astype(np.int64) + off)
            off += len(v) - 1
        pl = scene.plants
        for i in tile.plants:
            pr = pl.prototypes[int(pl.proto[i])]
            verts.append((pl.world_vertices(i) - scene.origin).astype(np.float32))
            faces.append(pr.faces.astype(np.int64) + off)
            off += len(pr.vertices)
    return np.vstack(verts).astype(np.float32), np.vstack(faces).astype(np.int32)


def main() -> None:
    print(
        f"machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}"
    )
    have = {m: importlib.util.find_spec(m) is not None for m in ("embreex", "open3d", "warp")}
    for label, (name, over) in SCENES.items():
        scn = sg.generate(sg.preset(name, **over), 0)
        for w, h in ((64, 48), (848, 480)):
            run_case(label, scn, w, h, have)


def run_case(label: str, scn: sg.Scenario, w: int, h: int, have: dict[str, bool]) -> None:
    rot, pos = lane_centre_pose(scn)
    cfg = EnvConfig.from_dict({"camera": {"width": w, "height": h}})
    model = robot_interface(cfg, RobotGeometry.from_urdf()).camera
    cam = MeshCamera(cfg.camera, model)
    t0 = time.perf_counter()
    scene = MeshScene.from_scenario(scn)
    scene.view(cam._view_points(rot, pos, False))
    build = time.perf_counter() - t0
    o, d = cam.rays.world(rot, pos)
    rel = (o - scene.origin).astype(np.float32)
    d32 = d.astype(np.float32)
    tfar = (6.05 / cam.rays.forward).astype(np.float32)
    reps = 15 if w == 64 else 3
    ours = scene.caster.intersect(scene.top, rel, d32, 0.0, tfar)
    t_ours = _median_time(lambda: scene.caster.intersect(scene.top, rel, d32, 0.0, tfar), reps)
    V, F = flat_geometry(scene)
    n_inst = sum(len(scene._cache[k].plants) for k in scene._attached)
    print(
        f"\n{label}, {w}x{h} ({len(d)} rays): view = {len(scene._attached)} tiles, "
        f"{n_inst} plants; flat copy {len(F)} triangles"
    )
    print(f"  embree-ctypes  build {build * 1e3:8.1f} ms  cast {t_ours * 1e3:8.2f} ms")
    ref = np.where(np.isfinite(ours.t), ours.t, np.inf)

    def agree(t: np.ndarray) -> float:
        t = np.where((t > 0) & (t < 1e30), t, np.inf)
        same = (np.isinf(t) & np.isinf(ref)) | (np.abs(t - ref) < 1e-3)
        return float(same.mean())

    if have["embreex"]:
        from embreex import mesh_construction, rtcore_scene

        origins = np.repeat(rel[None], len(d), axis=0)
        t0 = time.perf_counter()
        es = rtcore_scene.EmbreeScene()
        mesh_construction.TriangleMesh(es, V, F)
        es.run(origins[:1], d32[:1])
        b = time.perf_counter() - t0
        out = es.run(origins, d32, dists=tfar.copy(), output=1)
        t = _median_time(lambda: es.run(origins, d32, dists=tfar.copy(), output=1), reps)
        tt = np.where(out["geomID"] >= 0, out["tfar"], np.inf)
        a = agree(tt)
        print(f"  embreex        build {b * 1e3:8.1f} ms  cast {t * 1e3:8.2f} ms  agree {a:.4f}")
    if have["open3d"]:
        import open3d as o3d

        t0 = time.perf_counter()
        rs = o3d.t.geometry.RaycastingScene()
        rs.add_triangles(o3d.core.Tensor(V), o3d.core.Tensor(F.astype(np.uint32)))
        rays = o3d.core.Tensor(np.hstack([np.repeat(rel[None], len(d), 0), d32]))
        rs.cast_rays(rays[:1])
        b = time.perf_counter() - t0
        tt = rs.cast_rays(rays)["t_hit"].numpy()
        t = _median_time(lambda: rs.cast_rays(rays)["t_hit"].numpy(), reps)
        a = agree(np.where(tt <= tfar, tt, np.inf))
        print(f"  open3d         build {b * 1e3:8.1f} ms  cast {t * 1e3:8.2f} ms  agree {a:.4f}")
    if have["warp"]:
        import warp as wp

        wp.config.quiet = True
        wp.init()
        kernel = _warp_kernel(wp)
        t0 = time.perf_counter()
        mesh = wp.Mesh(
            points=wp.array(V, dtype=wp.vec3, device="cpu"),
            indices=wp.array(F.ravel(), dtype=int, device="cpu"),
        )
        b = time.perf_counter() - t0
        dw = wp.array(d32, dtype=wp.vec3, device="cpu")
        fw = wp.array(tfar, dtype=float, device="cpu")
        tw = wp.zeros(len(d), dtype=float, device="cpu")
        org = wp.vec3(*rel.tolist())

        def run() -> np.ndarray:
            wp.launch(kernel, dim=len(d), inputs=[mesh.id, org, dw, fw, tw], device="cpu")
            return np.asarray(tw.numpy())

        tt = run()  # compiles the kernel once
        t = _median_time(run, reps)
        a = agree(np.where(tt > 0, tt, np.inf))
        print(f"  warp (cpu)     build {b * 1e3:8.1f} ms  cast {t * 1e3:8.2f} ms  agree {a:.4f}")


def _warp_kernel(wp: Any) -> Any:
    @wp.kernel
    def cast(
        mesh: wp.uint64,
        o: wp.vec3,
        d: wp.array(dtype=wp.vec3),
        tfar: wp.array(dtype=float),
        t: wp.array(dtype=float),
    ) -> None:
        i = wp.tid()
        q = wp.mesh_query_ray(mesh, o, d[i], tfar[i])
        t[i] = wp.where(q.result, q.t, -1.0)

    return cast


if __name__ == "__main__":
    main()
