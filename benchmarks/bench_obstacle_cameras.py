"""Obstacles in the cameras: how far the proxy's stand-ins read from the meshes, and what they
cost.

1. Depth: noise-free 848 × 480 frames of the proxy camera (compiled cast) and the mesh camera
   (rasterised) at the same poses on a plane field without plants, strewn with one kind of
   obstacle at a time (generated: stones, litter; stalks from lodged maize, the standing plants
   then removed), the robot on lane centres facing along the rows (default mount: 0.66 m,
   25° down). Over the pixels both cameras label OBSTACLE: |Δz| (mean, median, 95th
   percentile) and the signed mean (proxy − mesh); and the silhouettes: obstacle pixels of one
   camera that the other does not label obstacle, as a share of the mesh's obstacle pixels.
2. Step cost: median seconds per env step with 64 × 48 proxy depth against the state-only step
   on paper-P1 (no obstacles), and the same field with obstacles, blocks interleaved. Run it
   with another checkout's ``src`` on ``PYTHONPATH`` to compare code versions (``--sections 2
   --json``), as docs/camera.md reports.

Run: ``python benchmarks/bench_obstacle_cameras.py`` (≈ 1 minute).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import statistics
from typing import Any

import gymnasium as gym
import numpy as np

import agrinav_gym  # noqa: F401  (registers the envs)
import scenario_gen as sg
from agrinav_gym.config import EnvConfig
from agrinav_gym.robot import RobotGeometry, robot_interface
from agrinav_gym.sensors.camera import FieldView
from agrinav_gym.sensors.depth import DepthCamera
from agrinav_gym.sensors.mesh_camera import MeshCamera
from common import drive

STATE = ("gps", "imu", "odom", "route")
FIELD = {
    "field": {"width": 12.0, "length": 16.0},
    "layout": {"headland": 2.0},
    "terrain": {"source": "plane", "margin": 4.0, "site": "flattest"},
    "furrows": {"enabled": False, "roughness": 0.0},
}
KINDS = {
    "stone": {"obstacles": {"stone_density": 2.0}},
    "litter": {"obstacles": {"litter_density": 1.0}},
    "stalk": {"obstacles": {"stalk_lodging": 0.25}, "crop": {"stage": 4}},
}


def strewn(kind: str, seed: int) -> sg.Scenario:
    """A plane field with obstacles of one kind and no standing plants."""
    scn = sg.generate(sg.preset("default", **FIELD).replace(KINDS[kind]), seed)
    p = scn.plants
    bare = sg.Plants(**{k: v[:0] for k, v in p.arrays().items()})
    return dataclasses.replace(scn, plants=bare)


def depth_difference(seeds: int) -> dict[str, dict[str, float]]:
    from agrinav_gym.render.classes import OBSTACLE  # here: section 2 runs on older checkouts

    cfg = EnvConfig.from_dict({"camera": {"width": 848, "height": 480, "renderer": "raster"}})
    model = robot_interface(cfg, RobotGeometry.from_urdf()).camera
    proxy, mesh = DepthCamera(cfg.camera, model), MeshCamera(cfg.camera, model)
    out = {}
    for kind in KINDS:
        dz: list[np.ndarray] = []
        mesh_px = proxy_only = mesh_only = 0
        n_obs = 0
        for seed in range(seeds):
            scn = strewn(kind, seed)
            n_obs += len(scn.obstacles)
            fv = FieldView(scn)
            for k in range(10, len(scn.route.xy) - 10, 12):
                xy = scn.route.xy[k]
                a = math.atan2(*(scn.route.xy[k + 1] - xy)[::-1])
                c, s = math.cos(a), math.sin(a)
                rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
                pos = np.array([xy[0], xy[1], float(scn.terrain.height_at(*xy)) + 0.11])
                fp = proxy.render(rot, pos, fv, None, labels=True)
                fm = mesh.render(rot, pos, fv, None, labels=True)
                op, om = fp.label == OBSTACLE, fm.label == OBSTACLE
                both = op & om & (fp.depth > 0) & (fm.depth > 0)
                dz.append((fp.depth[both] - fm.depth[both]).astype(np.float64))
                mesh_px += int(om.sum())
                proxy_only += int((op & ~om).sum())
                mesh_only += int((om & ~op).sum())
        d = np.concatenate(dz)
        out[kind] = {
            "obstacles": n_obs,
            "pixels_compared": len(d),
            "mean_abs_m": float(np.abs(d).mean()),
            "median_abs_m": float(np.median(np.abs(d))),
            "p95_abs_m": float(np.percentile(np.abs(d), 95)),
            "signed_mean_m": float(d.mean()),
            "proxy_only_share": proxy_only / max(mesh_px, 1),
            "mesh_only_share": mesh_only / max(mesh_px, 1),
        }
    return out


def step_costs(blocks: int, block: int = 150) -> dict[str, float]:
    """Median seconds per step: state only, 64 × 48 proxy depth on paper-P1, and with
    obstacles (0.3 stones, 0.05 litter per m², 3 % of the maize lodged)."""
    base = {"task": {"max_crops_hit": 10**6, "corridor": 2.0}}
    obstacles = {"obstacles": {"stone_density": 0.3, "litter_density": 0.05, "stalk_lodging": 0.03}}
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
    }
    try:  # a checkout from before obstacles has no such keys
        envs["proxy+obstacles"] = gym.make(
            "AgriNav/FurrowFollow-v3",
            scenario="paper-p1",
            scenario_overrides=obstacles,
            observations=(*STATE, "depth"),
            config=base,
        )
    except Exception:
        pass
    times: dict[str, list[float]] = {k: [] for k in envs}
    for env in envs.values():
        env.reset(seed=0)
        drive(env, 20)  # warm: first frames, scenes, caches
    for b in range(blocks):
        for k, env in envs.items():
            times[k].append(drive(env, block, b * block) / block)
    for env in envs.values():
        env.close()
    med = {k: statistics.median(v) for k, v in times.items()}
    out = {f"{k}_ms": 1e3 * v for k, v in med.items()}
    out.update({f"{k}_ratio": v / med["state"] for k, v in med.items() if k != "state"})
    out.update(frame_cost(blocks))
    return out


def frame_cost(blocks: int, block: int = 400, labels: bool = True) -> dict[str, float]:
    """Median µs per 64 × 48 proxy frame (noise and labels on, as an env with segmentation
    draws it) at paper-P1's lane centre, turning a little each frame: the only part of a step
    obstacles touch, timed alone (steps add the physics' noise on a busy machine)."""
    import time

    from agrinav_gym.sensors.camera import FieldView

    scn = sg.generate(sg.preset("paper-p1"), 0)
    cfg = EnvConfig.from_dict({"camera": {"segmentation": True}})
    cam = DepthCamera(cfg.camera, robot_interface(cfg, RobotGeometry.from_urdf()).camera)
    fv = FieldView(scn)
    rows = scn.rows
    mid = len(rows.offsets) // 2
    lane = 0.5 * (rows.offsets[mid - 1] + rows.offsets[mid])
    t = 0.5 * (rows.starts.min() + rows.ends.max())
    x, y = rows.to_enu(np.array([t]), np.array([lane]))
    pos = np.array([x[0], y[0], float(scn.terrain.height_at(x[0], y[0])) + 0.11])
    rng = np.random.default_rng(0)
    per: list[float] = []
    for b in range(blocks + 1):
        t0 = time.perf_counter()
        for i in range(block):
            a = rows.angle + 0.2 * math.sin(0.05 * i)
            c, s = math.cos(a), math.sin(a)
            rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
            cam.render(rot, pos, fv, rng, labels=labels)
        if b:  # the first block warms the caches
            per.append((time.perf_counter() - t0) / block)
    return {"proxy_frame_us": 1e6 * statistics.median(per)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sections", default="1,2")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--blocks", type=int, default=7)
    ap.add_argument("--json", action="store_true", help="one JSON object instead of tables")
    args = ap.parse_args()
    sections = {int(s) for s in args.sections.split(",")}
    res: dict[str, Any] = {}
    if 1 in sections:
        res["depth"] = depth_difference(args.seeds)
    if 2 in sections:
        res["step"] = step_costs(args.blocks)
    if args.json:
        print(json.dumps(res))
        return
    if "depth" in res:
        print("1. proxy - mesh depth on obstacle pixels, 848x480, noise-free")
        for kind, r in res["depth"].items():
            print(
                f"  {kind:6s} {r['obstacles']:4d} obstacles, {r['pixels_compared']:7d} px: "
                f"|dz| mean {r['mean_abs_m'] * 100:.1f} cm, "
                f"median {r['median_abs_m'] * 100:.1f} cm, p95 {r['p95_abs_m'] * 100:.1f} cm, "
                f"signed {r['signed_mean_m'] * 100:+.1f} cm;"
                f" proxy-only {r['proxy_only_share']:.0%}, mesh-only {r['mesh_only_share']:.0%}"
            )
    if "step" in res:
        print("2. env step, median ms (ratio to state-only)")
        for k, v in res["step"].items():
            print(f"  {k}: {v:.3f}")


if __name__ == "__main__":
    main()
