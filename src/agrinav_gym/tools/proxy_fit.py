"""The analytic proxy's parameters, fitted to the crop meshes by rendering both cameras.

The proxy (``PlantField``) draws a plant as a vertical capped cylinder of radius
``fill × canopy width`` from its base to its top and — for planar-leaved maize — a leaf band
from ``base × height`` to the top whose radius is ``reach × half the canopy width ×
|sin(yaw − row angle)|`` (the leaf plane's extent across the row). The three numbers are fitted
per species and catalog stage, once per planting (``FIT_PRESETS``): on lanes of that crop —
ridged as the v1 envs made them (the ``ridged`` preset's terrain with its 0.12 m furrows, the
camera in the furrow) or flat as the default fields are (the ``default`` preset's) — rows 0.75
and 1 m apart, 0.18 m in the row, random yaw, heights ±8 %, they minimise, over 16 lane-centre
poses with heading (±6°) and lateral (±0.1 m) offsets, the sum of two quantities, both in
metres: the mean absolute per-pixel difference between the proxy's 64 × 48 depth image and the
mesh camera's — geometry against geometry (no noise, no stereo invalidation, no near limit;
nothing within range reads ``max_range``) — and the absolute difference of the lane's visible
width at the camera's height (``lane_width``). Per-pixel agreement alone prefers a proxy
without leaves (a thin leaf is missed by most pixels) and then misses the leaves closing the
lane; the lane width alone ignores the rest of the image. The residuals are kept: they are the
tolerances of the proxy-against-mesh test. ``fit_stage`` does one fit (coordinate descent over
grids); ``benchmarks/fit_proxy.py`` runs them all and ``write_table`` stores the result as the
planting's table beside ``render/proxy_params.py`` (``proxy_params.PLANTINGS``), which the
runtime reads; the figures are docs/camera.md's. This module is an offline tool: nothing at run
time imports it.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from scenario_gen import CATALOG, Scenario
from scenario_gen.arrays import FloatArray
from scenario_gen.crops import WEED_SPECIES

from ..config import PROXY_PLANTINGS, EnvConfig
from ..render.mesh_scene import MeshScene
from ..render.proxy_params import COLUMNS, PLANTINGS, ProxyParams, parse_table
from ..render.proxy_plants import PlantField
from ..robot import RobotGeometry, robot_interface
from ..sensors.depth import DepthCamera
from ..sensors.mesh_camera import MeshCamera

FILL_GRID = np.round(np.arange(0.0, 0.61, 0.02), 3)
BASE_GRID = np.round(np.arange(0.0, 1.0, 0.05), 3)
REACH_GRID = np.round(np.arange(0.0, 2.01, 0.05), 3)  # maize leaves span ≈ 2 canopy radii
COARSE = (
    (0.0, 0.05, 0.1, 0.2, 0.3, 0.45, 0.6),
    (0.0, 0.2, 0.4, 0.6, 0.8),
    (0.0, 0.4, 0.8, 1.2, 1.6),
)
LANE_BAND = 0.15  # m either side of the camera's height
LANE_RANGE = (0.2, 3.0)  # m ahead of the camera
LANE_CAP = 1.0  # m: a side with nothing nearer counts as this far
LANE_MIN_POINTS = 0.01  # of the image's pixels: fewer on a side (stray leaf tips) close nothing
ROW_SPACINGS = (0.75, 1.0)
#: each table's planting → the scenario preset whose terrain its lanes are drawn on
FIT_PRESETS = dict(zip(PROXY_PLANTINGS, ("ridged", "default"), strict=True))
POSE_YAW_DEG = (-6.0, 6.0)
POSE_LATERAL = (-0.1, 0.1)


# ----------------------------------------------------------------------------- the fit
@dataclass(frozen=True)
class FitScene:
    scenario: Scenario
    poses: tuple[tuple[FloatArray, FloatArray], ...]  # (rot, pos) of base_link


def fit_scenes(
    name: str, growth: float, seed: int = 0, preset: str = FIT_PRESETS["ridged"]
) -> list[FitScene]:
    """Lanes of species ``name`` at ``growth`` on ``preset``'s terrain and the camera poses the
    fit uses."""
    import scenario_gen as sg

    out = []
    for k, spacing in enumerate(ROW_SPACINGS):
        crop = "corn" if name == WEED_SPECIES else name
        sp = CATALOG[crop]
        spec = sg.preset(
            preset,
            terrain={"margin": 4.0},
            field={"width": 4.5 * spacing, "length": 14.0},
            layout={"row_spacing": spacing, "headland": 2.0, "weed_density": 0.0},
            crop={"species": crop, "growth": float(growth) if name != WEED_SPECIES else 0.5},
        )
        scn = sg.generate(spec, seed + k)
        if name == WEED_SPECIES:  # the same rows, planted with weeds
            p = scn.plants
            w = CATALOG[WEED_SPECIES]
            height = p.height / float(sp.height(0.5)) * float(w.height(growth))
            stage = np.full(len(p), float(w.stage_of_growth(growth)))
            plants = dataclasses.replace(
                p,
                species=np.full(len(p), WEED_SPECIES),
                stage=stage,
                height=height,
                row=np.full(len(p), -1, np.int64),
            )
            scn = dataclasses.replace(scn, plants=plants)
        out.append(FitScene(scn, _lane_poses(scn)))
    return out


def _lane_poses(scn: Scenario) -> tuple[tuple[FloatArray, FloatArray], ...]:
    rows = scn.rows
    mid = len(rows.offsets) // 2
    lane = 0.5 * (rows.offsets[mid - 1] + rows.offsets[mid])
    t0, t1 = float(rows.starts.min()), float(rows.ends.max())
    poses = []
    for t in (t0 + 0.35 * (t1 - t0), t0 + 0.55 * (t1 - t0)):
        for dyaw in POSE_YAW_DEG:
            for lat in POSE_LATERAL:
                x, y = rows.to_enu(np.array([t]), np.array([lane + lat]))
                yaw = rows.angle + math.radians(dyaw)
                c, s = math.cos(yaw), math.sin(yaw)
                rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
                z = float(scn.terrain.height_at(x[0], y[0])) + 0.11
                poses.append((rot, np.array([x[0], y[0], z])))
    return tuple(poses)


def _depth_error(a: NDArray[np.float32], b: NDArray[np.float32], far: float) -> float:
    za = np.where(a > 0, a, far)
    zb = np.where(b > 0, b, far)
    return float(np.abs(za - zb).mean())


def lane_width(depth: NDArray[np.float32], model: Any) -> float:
    """The lane's visible width at the camera's height: from a depth image of a camera on the
    robot (``model``: ``CameraModel``), the free lateral distance between the nearest points left
    and right within ``LANE_BAND`` of the camera's height, ``LANE_RANGE`` ahead (5th
    percentiles; a side with fewer than ``LANE_MIN_POINTS`` of the pixels counts ``LANE_CAP``)."""
    rays = model.pixel_rays() @ model.rotation.T  # base_link, z = 1 at unit x
    z = np.asarray(depth, np.float64).ravel()
    ok = z > 0
    p = rays[ok] * z[ok, None] + np.asarray(model.position)  # z-depth: rays have x_cam = 1
    ahead = p[:, 0] - model.position[0]
    band = np.abs(p[:, 2] - model.position[2]) <= LANE_BAND
    sel = band & (ahead >= LANE_RANGE[0]) & (ahead <= LANE_RANGE[1])
    y = p[sel, 1]
    enough = max(3, round(LANE_MIN_POINTS * z.size))
    left = float(np.percentile(y[y > 0], 5)) if (y > 0).sum() >= enough else LANE_CAP
    right = float(-np.percentile(y[y < 0], 95)) if (y < 0).sum() >= enough else LANE_CAP
    return min(left, LANE_CAP) + min(right, LANE_CAP)


@dataclass(frozen=True)
class FitResult:
    params: ProxyParams
    depth: tuple[float, float]  # mean |Δz| per pixel over the poses, m, and its SD over poses
    lane: tuple[float, float]  # mean |Δ lane width|, m, and its SD over poses
    start: float  # the objective with the former hand-tuned constants (0.2, 0.2, 0.9)
    reference: float | None = None  # the objective with ``fit_stage``'s reference parameters


class Comparison:
    """Mesh-camera references of a set of lanes and poses, and the proxy's errors against them."""

    def __init__(self, name: str, growth: float, seed: int = 0, planting: str = "ridged") -> None:
        self.planting = planting
        cfg = EnvConfig.from_dict({"camera": {"min_range": 0.0}})
        self.model = robot_interface(cfg, RobotGeometry.from_urdf()).camera
        self.far = cfg.camera.max_range
        self.proxy = DepthCamera(cfg.camera, self.model)
        mesh = MeshCamera(cfg.camera, self.model)
        self.scenes = fit_scenes(name, growth, seed, FIT_PRESETS[planting])
        self.refs = []
        for fs in self.scenes:
            ms = MeshScene.from_scenario(fs.scenario)
            self.refs.append([mesh.draw(r, p, ms, None, stereo=False).depth for r, p in fs.poses])
        self.ref_lanes = [[lane_width(d, self.model) for d in ref] for ref in self.refs]

    def errors(self, par: ProxyParams | None) -> tuple[FloatArray, FloatArray]:
        """Per pose: mean |Δz| per pixel and |Δ lane width| (``None``: the planting's table)."""
        dz, dl = [], []
        for fs, ref, lanes in zip(self.scenes, self.refs, self.ref_lanes, strict=True):
            fn = None if par is None else (lambda _n, _g: par.tuple())
            field = PlantField.from_scenario(fs.scenario, fn, planting=self.planting)
            for (r, p), zm, lm in zip(fs.poses, ref, lanes, strict=True):
                zp = self.proxy.draw(r, p, fs.scenario.terrain, field, None).depth
                dz.append(_depth_error(zp, zm, self.far))
                dl.append(abs(lane_width(zp, self.model) - lm))
        return np.asarray(dz), np.asarray(dl)


def fit_stage(
    name: str,
    growth: float,
    sweeps: int = 2,
    planting: str = "ridged",
    reference: ProxyParams | None = None,
) -> FitResult:
    """Fit (fill, base, reach) for species ``name`` at ``growth`` (see the module docstring) on
    ``planting``'s lanes: the best of a coarse grid, then coordinate descent over the fine
    grids; ``reference``'s objective on the same lanes is kept beside it."""
    cmp = Comparison(name, growth, planting=planting)
    cache: dict[ProxyParams, float] = {}

    def error(par: ProxyParams) -> float:
        if par not in cache:
            dz, dl = cmp.errors(par)
            cache[par] = float(dz.mean() + dl.mean())
        return cache[par]

    planar = name != WEED_SPECIES and CATALOG[name].planar_leaves
    start = error(ProxyParams(0.2, 0.2 if planar else 1.0, 0.9 if planar else 0.0))
    if planar:
        coarse = [ProxyParams(f, b, r) for f in COARSE[0] for b in COARSE[1] for r in COARSE[2]]
    else:
        coarse = [ProxyParams(f, 1.0, 0.0) for f in COARSE[0]]
    best = min(coarse, key=error)
    grids: list[tuple[str, NDArray[np.float64]]] = [("fill", FILL_GRID)]
    if planar:
        grids += [("reach", REACH_GRID), ("base", BASE_GRID)]
    for _ in range(sweeps):
        before = best
        for field_name, grid in grids:
            cands = [dataclasses.replace(best, **{field_name: float(v)}) for v in grid]
            best = min([best, *cands], key=error)
        if best == before:
            break
    dz, dl = cmp.errors(best)
    return FitResult(
        best,
        (float(dz.mean()), float(dz.std())),
        (float(dl.mean()), float(dl.std())),
        start,
        None if reference is None else error(reference),
    )


def table_document(
    results: dict[str, list[tuple[float, FitResult]]], planting: str = "ridged"
) -> dict[str, Any]:
    """The table document of per-species ``(growth, FitResult)`` lists fitted on
    ``planting``'s lanes."""
    species = {
        name: [
            [
                round(g, 4),
                round(r.params.fill, 3),
                round(r.params.base, 3),
                round(r.params.reach, 3),
                round(r.depth[0], 4),
                round(r.depth[1], 4),
                round(r.lane[0], 4),
                round(r.lane[1], 4),
            ]
            for g, r in rows
        ]
        for name, rows in results.items()
    }
    doc = {
        "about": "Fitted parameters of the proxy camera's plant cylinders, per species and "
        "catalog stage. Written by benchmarks/fit_proxy.py (agrinav_gym.tools.proxy_fit); "
        "read by agrinav_gym.render.proxy_params.",
        "fitted_on": {
            "planting": planting,
            "preset": FIT_PRESETS[planting],
            "row_spacing_m": list(ROW_SPACINGS),
            "poses_per_lane": 8,
            "image": [64, 48],
        },
        "columns": list(COLUMNS),
        "species": species,
    }
    parse_table(doc, PLANTINGS[planting])  # what the runtime would refuse is not written
    return doc


def write_table(
    results: dict[str, list[tuple[float, FitResult]]],
    path: Path | None = None,
    planting: str = "ridged",
) -> Path:
    """Store the fit as the runtime's table of ``planting`` (default: beside
    ``render/proxy_params.py``)."""
    here = Path(__file__).resolve().parent.parent / "render" / PLANTINGS[planting]
    out = path or here
    tmp = out.with_suffix(".tmp")
    tmp.write_text(json.dumps(table_document(results, planting), indent=1) + "\n")
    tmp.replace(out)
    return out
