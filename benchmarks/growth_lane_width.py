"""The lane as the mesh camera sees it at the growth suite's stages.

Maize at 0.3 / 0.6 / 1.2 / 1.8 / 2.5 m (the catalog's five stages) in 1 m rows, 0.18 m in the row
(the growth suite's fields). From 24 lane-centre poses (4 along the lane × heading −5°, 0°,
+5° × lateral −0.1, +0.1 m), the mesh camera's 64 × 48 depth (the RL mode, with the D455 stereo
model, noise-free) gives:

* the lane's visible width at the camera's height (``tools.proxy_fit.lane_width``: free width
  between the nearest points left and right within 0.15 m of the camera's height, 0.2-3 m ahead; 2 m
  when nothing is seen on either side);
* the fraction of valid depth pixels, and of those nearer than 1 m (leaves in the lane);

for the catalog models and with every leaf 20 % longer / shorter and drooping 20 % more / less
(``crop_mesh(leaf_length=…, leaf_droop=…)``). The proxy's lane width at the same poses is shown
for comparison. Prints a markdown table and draws docs/img/growth_lane_width.png.

Run: ``python benchmarks/growth_lane_width.py`` (about a minute).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from tqdm import tqdm

import scenario_gen as sg
from agrinav_gym.config import EnvConfig
from agrinav_gym.render.mesh_scene import MeshScene
from agrinav_gym.render.plant_meshes import PlantMeshes
from agrinav_gym.render.proxy_plants import PlantField
from agrinav_gym.robot import RobotGeometry, robot_interface
from agrinav_gym.sensors.depth import DepthCamera
from agrinav_gym.sensors.mesh_camera import MeshCamera
from agrinav_gym.tools.proxy_fit import lane_width

ROOT = Path(__file__).resolve().parents[1]
VARIANTS = {
    "catalog": (1.0, 1.0),
    "leaves +20 %": (1.2, 1.0),
    "leaves −20 %": (0.8, 1.0),
    "droop +20 %": (1.0, 1.2),
    "droop −20 %": (1.0, 0.8),
}


def poses(scn: sg.Scenario) -> list[tuple[np.ndarray, np.ndarray]]:
    rows = scn.rows
    mid = len(rows.offsets) // 2
    lane = 0.5 * (rows.offsets[mid - 1] + rows.offsets[mid])
    t0, t1 = float(rows.starts.min()), float(rows.ends.max())
    out = []
    for f in (0.3, 0.45, 0.6, 0.75):
        for dyaw in (-5.0, 0.0, 5.0):
            for lat in (-0.1, 0.1):
                x, y = rows.to_enu(np.array([t0 + f * (t1 - t0)]), np.array([lane + lat]))
                yaw = rows.angle + math.radians(dyaw)
                c, s = math.cos(yaw), math.sin(yaw)
                rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
                z = float(scn.terrain.height_at(x[0], y[0])) + 0.11
                out.append((rot, np.array([x[0], y[0], z])))
    return out


def main() -> None:
    cfg = EnvConfig.from_dict({})
    model = robot_interface(cfg, RobotGeometry.from_urdf()).camera
    mesh_cam, proxy_cam = MeshCamera(cfg.camera, model), DepthCamera(cfg.camera, model)
    results: dict[str, dict[float, tuple[float, float, float]]] = {v: {} for v in VARIANTS}
    proxy: dict[float, float] = {}
    heights = []
    for stage in tqdm(range(1, 6), desc="stages"):
        spec = sg.preset("default", crop={"stage": stage}, layout={"row_spacing": 1.0})
        scn = sg.generate(spec, 0)
        h = float(sg.CATALOG["corn"].heights[stage - 1])
        heights.append(h)
        ps = poses(scn)
        field = PlantField.from_scenario(scn)
        proxy[h] = float(
            np.mean(
                [
                    lane_width(proxy_cam.draw(r, p, scn.terrain, field, None).depth, model)
                    for r, p in ps
                ]
            )
        )
        for name, (length, droop) in VARIANTS.items():
            plants = PlantMeshes.from_scenario(scn, leaf_length=length, leaf_droop=droop)
            scene = MeshScene(scn.terrain, plants, seed=scn.seed)
            w, valid, near = [], [], []
            for r, p in ps:
                d = mesh_cam.draw(r, p, scene, None).depth
                w.append(lane_width(d, model))
                valid.append(float((d > 0).mean()))
                near.append(float(((d > 0) & (d < 1.0)).mean()))
            results[name][h] = (float(np.mean(w)), float(np.mean(valid)), float(np.mean(near)))
    print("| maize height | " + " | ".join(VARIANTS) + " | proxy |")
    print("|---" * (len(VARIANTS) + 2) + "|")
    for h in heights:
        cells = [f"{results[v][h][0]:.2f}" for v in VARIANTS]
        print(f"| {h:g} m | " + " | ".join(cells) + f" | {proxy[h]:.2f} |")
    print("\nvalid depth pixels / pixels nearer than 1 m (catalog models):")
    for h in heights:
        _, valid, near = results["catalog"][h]
        print(f"  {h:g} m: {valid:.2f} valid, {near:.2f} nearer than 1 m")
    fig = Figure(figsize=(7, 4.5))
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    for v in VARIANTS:
        ax.plot(heights, [results[v][h][0] for h in heights], "o-", label=f"mesh, {v}")
    ax.plot(heights, [proxy[h] for h in heights], "k--", label="analytic proxy (fitted)")
    ax.axhline(0.62, color="grey", lw=0.8)
    ax.text(0.3, 0.64, "robot width 0.62 m", color="grey", fontsize=8)
    ax.axvline(0.66, color="grey", lw=0.8, ls=":")
    ax.text(0.68, 1.9, "camera height", color="grey", fontsize=8, rotation=90, va="top")
    ax.set(
        xlabel="maize height, m (1 m rows)",
        ylabel="visible lane width at camera height, m",
        title="The lane as the 64 × 48 mesh camera sees it",
        ylim=(0, 2.05),
    )
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    out = ROOT / "docs/img/growth_lane_width.png"
    fig.savefig(out, dpi=100)
    print(f"wrote {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
