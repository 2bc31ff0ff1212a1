"""Probe: what would the proxy's step cost with its exact parts approximated?

The proxy depth camera is exact in two places that cost time: terrain hits are moved by
Newton onto the bilinear surface the tyres and plants stand on (``refine_ground``), and plants
are true cylinders (Embree cone curves). This swaps each for its tessellation —

* ``triangles``: terrain hits left on the grid's triangles (error: the cells' twist);
* ``prisms``: each cylinder as a 32-gon prism whose faces lie within ±0.24 % of the radius
  (vertices at 2r / (1 + cos(π/32))), all in one flat triangle mesh;

— and times the env step against the state-only step on the benchmark drive
(``bench_mesh_camera``: paper-P1, S-curve, blocks interleaved), with the depth error each
approximation makes on the same frames. Nothing here changes the env: it answers whether the
≤ 2× target is within reach of cheaper geometry. Run: ``python
benchmarks/probe_proxy_approximations.py`` (about two minutes).
"""

from __future__ import annotations

import argparse
import math
import platform
import statistics
from typing import Any

import gymnasium as gym
import numpy as np

import agrinav_gym  # noqa: F401  (registers the envs)
from agrinav_gym.render.embree import Scene
from agrinav_gym.render.mesh_scene import MeshScene
from common import drive, s_curve

STATE = ("gps", "imu", "odom", "route")
BLOCK = 150
SIDES = 32
PRISM_TRIS = 4 * SIDES - 4  # sides 2N, two caps of N - 2 each


def prism_mesh(bottom: np.ndarray, top: np.ndarray, radius: np.ndarray) -> tuple[Any, Any]:
    """Vertical ``SIDES``-gon prisms with faces within ±(1 − cos(π/N)) / (1 + cos(π/N)) of r."""
    k = 2.0 / (1.0 + math.cos(math.pi / SIDES))
    a = 2 * np.pi * np.arange(SIDES) / SIDES
    x = bottom[:, :1] + (k * radius)[:, None] * np.cos(a)
    y = bottom[:, 1:2] + (k * radius)[:, None] * np.sin(a)
    zb = np.repeat(bottom[:, 2:3], SIDES, 1)
    zt = np.repeat(top[:, 2:3], SIDES, 1)
    v = np.concatenate([np.stack([x, y, zb], -1), np.stack([x, y, zt], -1)], 1).reshape(-1, 3)
    i = np.arange(SIDES)
    j = (i + 1) % SIDES
    fan = np.arange(1, SIDES - 1)
    one = np.concatenate(
        [
            np.stack([i, j, SIDES + j], 1),
            np.stack([i, SIDES + j, SIDES + i], 1),
            np.stack([0 * fan, fan + 1, fan], 1),
            np.stack([SIDES + 0 * fan, SIDES + fan, SIDES + fan + 1], 1),
        ]
    )
    f = (one[None] + (2 * SIDES * np.arange(len(radius)))[:, None, None]).reshape(-1, 3)
    return v.astype(np.float32), f.astype(np.uint32)


class ProbeScene(MeshScene):
    """The proxy camera's scene with terrain hits left on the triangles and/or its cylinders
    (``DepthCamera`` adds them with ``add_static``) rebuilt as prisms."""

    def __init__(self, terrain: Any, triangles: bool, prisms: bool) -> None:
        super().__init__(terrain)
        self.triangles, self.prisms = triangles, prisms

    def add_static(self, child: Scene) -> int:
        if self.prisms:
            v = child._keep[0][0]  # the cone curves' vertices: bottom, top pairs with radius
            mesh = Scene(self.dev, "medium")
            mesh.attach_triangles(0, *prism_mesh(v[0:-1:2, :3], v[1:-1:2, :3], v[0:-1:2, 3]))
            child = mesh
        return super().add_static(child)

    def cast(
        self, o: Any, d: Any, tnear: Any = 0.0, tfar: Any = np.inf, refine: bool = True
    ) -> Any:
        h = super().cast(o, d, tnear, tfar, refine=refine and not self.triangles)
        if self.prisms:  # a prism's triangle -> its cylinder
            h.prim = np.where(h.inst >= self._n_ground, h.prim // PRISM_TRIS, h.prim)
        return h


VARIANTS = {
    "exact (shipped)": (False, False),
    "terrain as triangles": (True, False),
    "cylinders as prisms": (False, True),
    "both": (True, True),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--blocks", type=int, default=5, help="interleaved blocks of env steps")
    args = ap.parse_args()
    print(f"machine: {platform.platform()}, Python {platform.python_version()}")
    base = {"task": {"max_crops_hit": 10**6, "corridor": 2.0}}
    envs: dict[str, Any] = {
        "state": gym.make(
            "AgriNav/FurrowFollow-v3", scenario="paper-p1", observations=STATE, config=base
        )
    }
    for name, (tri, pri) in VARIANTS.items():
        env = gym.make(
            "AgriNav/FurrowFollow-v3",
            scenario="paper-p1",
            observations=(*STATE, "depth"),
            config=base,
        )
        env.reset(seed=0)
        cam = env.unwrapped.obs_models["depth"].camera
        terrain = env.unwrapped.scenario.terrain  # one field: the scene is never rebuilt
        cam._scene, cam._cylinders = (terrain, ProbeScene(terrain, tri, pri)), None
        envs[name] = env
    times: dict[str, list[float]] = {k: [] for k in envs}
    for env in envs.values():
        env.reset(seed=0)
        drive(env, 50)
    for b in range(args.blocks):
        for k, env in envs.items():
            env.reset(seed=b)
            times[k].append(drive(env, BLOCK) / BLOCK)
    state = statistics.median(times["state"])
    print(f"\nenv step, paper-p1 S-curve, median of {args.blocks} blocks of {BLOCK} steps")
    print(f"   state only: {state * 1e3:.3f} ms")
    for k in VARIANTS:
        t = statistics.median(times[k])
        print(f"   + 64x48 proxy depth, {k}: {t * 1e3:.3f} ms, ratio {t / state:.2f} (target <= 2)")

    # the depth error each approximation makes, on the frames of one drive (noise off)
    exact = envs["exact (shipped)"]
    env = exact.unwrapped
    cams = {k: envs[k].unwrapped.obs_models["depth"].camera for k in VARIANTS}
    exact.reset(seed=0)
    diffs: dict[str, list[np.ndarray]] = {k: [] for k in VARIANTS if k != "exact (shipped)"}
    for i in range(300):
        exact.step(s_curve(i))
        s = env.state
        ref = cams["exact (shipped)"].draw(s.rot, s.pos, env.scenario.terrain, env.plants, None)
        for k in diffs:
            own = envs[k].unwrapped  # the same field, generated in that env: its own scene
            z = cams[k].draw(s.rot, s.pos, own.scenario.terrain, own.plants, None).depth
            both = (z > 0) & (ref.depth > 0)
            diffs[k].append(np.abs(z - ref.depth)[both])
    print("\n|depth − exact| over 300 frames (valid in both)")
    for k, d in diffs.items():
        x = np.concatenate(d)
        print(
            f"   {k}: median {np.median(x) * 1e3:.3f} mm, 99.9th pct "
            f"{np.percentile(x, 99.9) * 1e3:.2f} mm, max {x.max() * 1e3:.0f} mm; pixels off "
            f"by > 1 cm: {np.mean(x > 0.01):.3%} (silhouettes: a grazing ray meets one and "
            "misses the other)"
        )
    for e in envs.values():
        e.close()


if __name__ == "__main__":
    main()
