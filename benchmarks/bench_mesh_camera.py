"""Mesh camera benchmarks, ratios measured side by side.

1. env step cost with the camera against the state-only step (gps, imu, odom, route), on the
   paper's P1 field, driving the same S-curve, blocks interleaved so drift cancels:
   64 × 48 mesh depth + segmentation (target ≤ 4×) and the analytic proxy depth (≤ 2×), the
   proxy both through the compiled kernels and through the reference path (numpy + Embree,
   ``AGRINAV_NATIVE=0`` during its blocks: the code before the kernels);
2. 848 × 480 RGB-D + semantic + instance frames against pybullet's ``getCameraImage``
   (TinyRenderer) at the same pose and resolution, the same meshes (every plant and the terrain)
   loaded as visual shapes merged per tile (≤ 100k vertices each), in interleaved blocks of
   three consecutive frames per renderer, as a dataset loop renders (≥ 20×); the mesh camera
   rasterising (``camera.renderer="raster"``) and, for reference, casting rays;
3. memory per plant (≤ 4 KB): RSS and traced allocations of a scene that has rendered, fields
   of two densities each in a fresh process, per plant and marginal;
4. a 100,000-plant field: scene build + first frame (≤ 10 s), generation timed apart;
5. frame cost on the 100k field against the 2k one (cost flat in field size), 64 × 48 rays and
   848 × 480 rasterised frames.

Medians of several runs. Run: ``python benchmarks/bench_mesh_camera.py`` (a few minutes).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from typing import Any

import gymnasium as gym
import numpy as np

import agrinav_gym  # noqa: F401  (registers the envs)
import scenario_gen as sg
from common import drive, lane_centre_pose, pybullet_camera

STATE = ("gps", "imu", "odom", "route")
BLOCK = 150


def step_costs(blocks: int) -> dict[str, float]:
    """Median seconds per env step: state only, + proxy depth (compiled, reference), + mesh depth
    and segmentation."""
    base = {"task": {"max_crops_hit": 10**6, "corridor": 2.0}}
    envs = {
        "state": gym.make(
            "AgriNav/FurrowFollow-v3", scenario="paper-p1", observations=STATE, config=base
        ),
        "proxy": gym.make(
            "AgriNav/FurrowFollow-v3",
            scenario="paper-p1",
            observations=(*STATE, "depth"),
            config=base,
        ),
        "mesh": gym.make(
            "AgriNav/FurrowFollow-v3",
            scenario="paper-p1",
            observations=(*STATE, "depth"),
            config={**base, "camera": {"model": "mesh", "segmentation": True}},
        ),
        "proxy-reference": gym.make(
            "AgriNav/FurrowFollow-v3",
            scenario="paper-p1",
            observations=(*STATE, "depth"),
            config=base,
        ),
    }
    times: dict[str, list[float]] = {k: [] for k in envs}

    def run(k: str, env: Any, n: int) -> float:
        if k.endswith("-reference"):
            os.environ["AGRINAV_NATIVE"] = "0"
        try:
            return drive(env, n)
        finally:
            os.environ.pop("AGRINAV_NATIVE", None)

    for k, env in envs.items():
        env.reset(seed=0)
        run(k, env, 50)  # warm: tiles, prototypes, caches
    for b in range(blocks):
        for k, env in envs.items():
            env.reset(seed=b)
            times[k].append(run(k, env, BLOCK) / BLOCK)
    for env in envs.values():
        env.close()
    return {k: statistics.median(v) for k, v in times.items()}


def load_pybullet(scn: sg.Scenario, scene: Any) -> tuple[int, int]:
    """The scenario's plants (the same prototypes and placements) and terrain as pybullet
    visual meshes merged per tile (≤ 100k vertices each); returns (client, triangles)."""
    import pybullet as p

    cid = p.connect(p.DIRECT)
    p.configureDebugVisualizer(p.COV_ENABLE_RENDERING, 0, physicsClientId=cid)
    pm = scene.plants
    verts: list[np.ndarray] = []
    faces: list[np.ndarray] = []
    count = [0, 0]  # vertices in the current batch, triangles in all

    def flush(rgba: list[float]) -> None:
        if verts:
            vs = p.createVisualShape(
                p.GEOM_MESH,
                vertices=np.vstack(verts).tolist(),
                indices=np.vstack(faces).ravel().tolist(),
                rgbaColor=rgba,
                physicsClientId=cid,
            )
            p.createMultiBody(0, -1, vs, physicsClientId=cid)
        verts.clear()
        faces.clear()
        count[0] = 0

    for i in np.argsort(scene._key(pm.x, pm.y), kind="stable"):  # tile by tile
        pr = pm.prototypes[int(pm.proto[i])]
        verts.append(pm.world_vertices(int(i)))
        faces.append(pr.faces.astype(np.int64) + count[0])
        count[0] += len(pr.vertices)
        count[1] += len(pr.faces)
        if count[0] > 100_000 - 2_000:
            flush([0.3, 0.6, 0.2, 1.0])
    flush([0.3, 0.6, 0.2, 1.0])
    t = scn.terrain
    ny, nx = t.shape
    step = 220  # 221² vertices < 100k
    for i0 in range(0, ny - 1, step):
        for j0 in range(0, nx - 1, step):
            sub = sg.Terrain(
                t.heights[i0 : i0 + step + 1, j0 : j0 + step + 1],
                t.x0 + j0 * t.spacing,
                t.y0 + i0 * t.spacing,
                t.spacing,
            ).to_trimesh()
            verts.append(np.asarray(sub.vertices))
            faces.append(np.asarray(sub.faces))
            count[1] += len(sub.faces)
            flush([0.45, 0.33, 0.22, 1.0])
    p.configureDebugVisualizer(p.COV_ENABLE_RENDERING, 1, physicsClientId=cid)
    return cid, count[1]


BLOCK = 3  # consecutive frames per renderer in section 2


def dataset_frames(name: str, over: dict[str, Any], repeat: int, threads: int) -> dict[str, Any]:
    import pybullet as p

    from agrinav_gym.config import EnvConfig
    from agrinav_gym.render.mesh_scene import MeshScene
    from agrinav_gym.robot import RobotGeometry, robot_interface
    from agrinav_gym.sensors.mesh_camera import MeshCamera

    scn = sg.generate(sg.preset(name, **over), 0)
    scene = MeshScene.from_scenario(scn)
    cid, tris = load_pybullet(scn, scene)
    cams = {}
    for renderer in ("raster", "raycast"):
        cfg = EnvConfig.from_dict({"camera": {"width": 848, "height": 480, "renderer": renderer}})
        model = robot_interface(cfg, RobotGeometry.from_urdf()).camera
        cams[renderer] = MeshCamera(cfg.camera, model, threads=threads)
    rot, pos = lane_centre_pose(scn)
    view, proj = pybullet_camera(cid, model, rot, pos, cfg.camera.vfov_deg, cfg.camera.max_range)
    rng = np.random.default_rng(0)
    for cam in cams.values():  # first frames: tiles, prototypes, the split between threads
        for _ in range(3):
            cam.draw(rot, pos, scene, rng, rgb=True, labels=True)
    times: dict[str, list[float]] = {"tiny": [], "raster": [], "raycast": []}
    for _ in range(repeat):  # blocks of BLOCK frames each, interleaved: drift cancels, and
        # each renderer runs frame after frame as a dataset loop runs it
        for _ in range(BLOCK):
            t0 = time.perf_counter()
            p.getCameraImage(848, 480, view, proj, renderer=p.ER_TINY_RENDERER, physicsClientId=cid)
            times["tiny"].append(time.perf_counter() - t0)
        for k, cam in cams.items():
            for i in range(BLOCK):
                t0 = time.perf_counter()
                cam.draw(rot, pos, scene, rng, rgb=True, labels=True)
                times[k].append(time.perf_counter() - t0)
                if i == 0:  # after the other renderers' frames: caches and threads cold
                    times.setdefault(f"{k} first", []).append(times[k][-1])
    p.disconnect(cid)
    out: dict[str, Any] = {"plants": len(scn.plants), "triangles": tris}
    out.update({k: statistics.median(v) for k, v in times.items()})
    return out


MEMORY_CHILD = r"""
import json, sys, time, tracemalloc, numpy as np, scenario_gen as sg
def rss():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096
preset, over, cam_over = sys.argv[1], json.loads(sys.argv[2]), json.loads(sys.argv[3])
from agrinav_gym.config import EnvConfig
from agrinav_gym.robot import robot_interface
from agrinav_gym.render.embree import device
from agrinav_gym.sensors.mesh_camera import MeshCamera
from agrinav_gym.render.mesh_scene import MeshScene
from agrinav_gym.robot import RobotGeometry
device()
t0 = time.perf_counter()
scn = sg.generate(sg.preset(preset, **over), 0)
gen = time.perf_counter() - t0
cfg = EnvConfig.from_dict({"camera": {"segmentation": True, **cam_over}})
cam = MeshCamera(cfg.camera, robot_interface(cfg, RobotGeometry.from_urdf()).camera)
rows = scn.rows
mid = len(rows.offsets) // 2
lane = 0.5 * (rows.offsets[mid - 1] + rows.offsets[mid])
t_mid = 0.5 * (rows.starts.min() + rows.ends.max())
c, s = np.cos(rows.angle), np.sin(rows.angle)
rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
def pose(k):
    x, y = rows.to_enu(np.array([t_mid + 0.05 * k]), np.array([lane]))
    return np.array([x[0], y[0], float(scn.terrain.height_at(x[0], y[0])) + 0.11])
before = rss()
tracemalloc.start()
t0 = time.perf_counter()
scene = MeshScene.from_scenario(scn)
cam.draw(rot, pose(0), scene, np.random.default_rng(0), rgb=cfg.camera.rgb, labels=True)
first = time.perf_counter() - t0
frames = []
for k in range(1, 200):
    t1 = time.perf_counter()
    cam.draw(rot, pose(k), scene, np.random.default_rng(k), rgb=cfg.camera.rgb, labels=True)
    frames.append(time.perf_counter() - t1)
traced, _ = tracemalloc.get_traced_memory()
print(json.dumps({
    "plants": len(scn.plants), "generate": gen, "first": first,
    "frame": float(np.median(frames)), "rss": rss() - before, "traced": traced,
    "attached_plants": sum(len(scene._cache[k].plants) for k in scene._attached),
}))
"""


def child(preset: str, over: dict[str, Any], cam: dict[str, Any] | None = None) -> dict[str, Any]:
    env = dict(os.environ)
    res = subprocess.run(
        [sys.executable, "-c", MEMORY_CHILD, preset, json.dumps(over), json.dumps(cam or {})],
        capture_output=True,
        text=True,
        check=True,
        env=env,
    )
    out: dict[str, Any] = json.loads(res.stdout.strip().splitlines()[-1])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--blocks", type=int, default=7, help="interleaved blocks of env steps")
    ap.add_argument("--frames", type=int, default=5, help="848x480 blocks per renderer")
    ap.add_argument("--threads", type=int, default=2, help="mesh camera threads at 848x480")
    ap.add_argument(
        "--sections", default="1,2,3", help="which to run: 1 steps, 2 frames, 3 fields (3-5)"
    )
    args = ap.parse_args()
    sections = {x.strip() for x in args.sections.split(",")}
    if not sections <= {"1", "2", "3"}:
        ap.error(f"--sections: {args.sections!r}; allowed: a comma list of 1, 2, 3")
    from agrinav_gym.render import native

    py = platform.python_version()
    print(f"machine: {platform.platform()}, {os.cpu_count()} cores, Python {py}")
    print(f"compiled kernels: {'built' if native.available() else 'NOT BUILT (reference paths)'}")

    if "1" in sections:
        steps(args.blocks)
    if "2" in sections:
        frames(args.frames, args.threads)
    if "3" in sections:
        fields(native.available())


def steps(blocks: int) -> None:
    s = step_costs(blocks)
    print("\n1. env step (paper-p1, S-curve), median ms per step")
    print(f"   state only (gps, imu, odom, route): {s['state'] * 1e3:.3f}")
    for k, label, target in (
        ("proxy", "proxy depth 64x48, compiled kernel", 2.0),
        ("proxy-reference", "proxy depth 64x48, reference path (numpy + Embree)", 2.0),
        ("mesh", "mesh depth 64x48 + segmentation (Embree rays)", 4.0),
    ):
        print(
            f"   + {label}: {s[k] * 1e3:.3f}  ratio {s[k] / s['state']:.2f} (target <= {target:g})"
        )


def frames(repeat: int, threads: int) -> None:
    print("\n2. 848x480 RGB-D + semantic + instance vs pybullet TinyRenderer, median ms")
    for label, (name, over) in {
        "paper-p1": ("paper-p1", {}),
        "maize 2.5 m, 1 m rows": (
            "default",
            {"crop": {"stage": 5}, "layout": {"row_spacing": 1.0}},
        ),
    }.items():
        r = dataset_frames(name, over, repeat, threads)
        print(
            f"   {label} ({r['plants']} plants, {r['triangles']} triangles in pybullet): "
            f"TinyRenderer {r['tiny'] * 1e3:.0f}; mesh camera ({threads} threads) "
            f"rasterising {r['raster'] * 1e3:.1f}: {r['tiny'] / r['raster']:.1f}x faster "
            f"(target >= 20; a block's first frame alone {r['raster first'] * 1e3:.1f}: "
            f"{r['tiny'] / r['raster first']:.1f}x); casting rays {r['raycast'] * 1e3:.0f}: "
            f"{r['tiny'] / r['raycast']:.1f}x"
        )


def fields(kernels: bool) -> None:
    print("\n3-5. fields of growing size (each in a fresh process)")
    small = child("paper-p1", {})
    # jitter within a sixth of the spacing (generate.check_spec)
    dense = child("paper-p1", {"layout": {"plant_spacing": 0.05, "jitter_longitudinal": 0.008}})
    # the default crop at its spacing: 130 m x 155 m holds just over 100,000 plants
    big_field = {"field": {"width": 130.0, "length": 155.0}}
    big = child("default", big_field)
    if big["plants"] < 100_000:
        sys.exit(f"the '100k field' has {big['plants']} plants: enlarge it (target is 100,000)")
    for label, r in (("paper-p1", small), ("paper-p1 at 0.05 m", dense), ("100k field", big)):
        print(
            f"   {label}: {r['plants']} plants, {r['attached_plants']} loaded; generate "
            f"{r['generate']:.2f} s; scene + first frame {r['first']:.2f} s; frame "
            f"{r['frame'] * 1e3:.2f} ms; RSS +{r['rss'] / 2**20:.1f} MiB "
            f"({r['rss'] / r['plants']:.0f} B/plant), traced "
            f"{r['traced'] / r['plants']:.0f} B/plant"
        )
    n = dense["plants"] - small["plants"]
    print(
        f"   marginal per plant (paper-p1, 1 m -> 0.05 m spacing): RSS "
        f"{(dense['rss'] - small['rss']) / n:.0f} B, traced "
        f"{(dense['traced'] - small['traced']) / n:.0f} B (target <= 4096)"
    )
    print(
        f"   100k field: scene build + first frame {big['first']:.2f} s (target <= 10), "
        f"frame cost 100k / 2k = {big['frame'] / small['frame']:.2f} (64x48 rays)"
    )
    if kernels:
        wide = {"width": 848, "height": 480, "renderer": "raster", "rgb": True}
        small_r = child("default", {}, wide)
        big_r = child("default", big_field, wide)
        print(
            f"   848x480 rasterised RGB-D + labels (default crop, one thread): "
            f"{small_r['plants']} plants {small_r['frame'] * 1e3:.1f} ms, "
            f"{big_r['plants']} plants {big_r['frame'] * 1e3:.1f} ms: "
            f"100k / 2k = {big_r['frame'] / small_r['frame']:.2f}; scene + first frame "
            f"{big_r['first']:.2f} s"
        )


if __name__ == "__main__":
    main()
