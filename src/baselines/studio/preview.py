"""The live preview: where the plants and the route will be, without sampling the terrain.

A full ``generate`` samples the terrain on the LoD grid, adds the furrow relief and places every
plant on it (≈0.1 s for the default field, more for large ones). The plan view needs none of
that: plant x/y come from the layout stage alone, and the route only needs the grid's extent.
So the preview runs the generator's own ``plan_field``, ``layout`` and ``zigzag`` with the same
random streams, and its plant positions are those ``generate`` produces, to the bit (tested).
With obstacles asked for, it places the plants on flat ground (their heights, which lodging and
the stones' clearance need, do not depend on the ground) and runs the generator's own ``lodge``
and ``field_obstacles``: the same plants fall, the route avoids the same standing crop, and
every obstacle lies where ``generate`` puts it, with its kind, size and heading (its height and
tilt on the ground are not previewed).
The field is still checked against the terrain (off the DEM or mesh, a nodata hole, a grid too
large) on a coarse sample of the grid's extent, so those errors show while drawing.
"""

from __future__ import annotations

import functools
import math
import time
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from shapely.geometry.base import BaseGeometry

from scenario_gen import crops
from scenario_gen.arrays import FloatArray
from scenario_gen.drift import apply_drift
from scenario_gen.errors import InputError
from scenario_gen.generate import (
    FieldPlan,
    check_spec,
    field_obstacles,
    growth_of,
    lodge,
    place_plants,
    plan_field,
    streams,
)
from scenario_gen.layout import Layout, layout
from scenario_gen.models import inspect_model
from scenario_gen.obstacles import OBSTACLE_KINDS, STALK, Obstacles
from scenario_gen.preview import OBSTACLE_RGB
from scenario_gen.routes import Route, zigzag
from scenario_gen.rowcurve import row_curve
from scenario_gen.sources import Site, open_site, terrain_grid
from scenario_gen.spec import ScenarioSpec, TerrainSpec
from scenario_gen.terrain import Terrain

#: Plants drawn at most; larger fields are drawn decimated (every k-th plant) with the true
#: count shown. A canvas layer draws 20,000 dots in ≈10 ms, so the cap is set by the payload.
MAX_DRAWN = 20_000
CHECK_SAMPLES = 24  # per side of the coarse terrain-extent check


@dataclass(frozen=True, eq=False)
class FlatGround(Terrain):
    """The generation grid's extent without its samples: what the route checks against."""

    extent: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        return self.extent


class SiteCache:
    """Opened sites by (terrain spec, drawn field, window size, margin): opening one picks a window
    of the DEM (≈0.25 s for site=flattest) and builds transformers, which the preview must not
    repeat on every change."""

    def __init__(self, size: int = 16) -> None:
        self.size = size
        self._sites: OrderedDict[tuple[object, ...], Site] = OrderedDict()
        self._checked: OrderedDict[tuple[object, ...], None] = OrderedDict()

    def open(
        self, spec: TerrainSpec, field_ll: BaseGeometry | None, extent: float, margin: float
    ) -> Site:
        drawn = None if field_ll is None else field_ll.wkb
        key = (spec, drawn, extent if drawn is None else None, margin)
        if key not in self._sites:
            self._sites[key] = open_site(spec, field_ll, extent, margin)
            while len(self._sites) > self.size:
                self._sites.popitem(last=False)
        self._sites.move_to_end(key)
        return self._sites[key]

    def check_extent(self, site: Site, bounds: tuple[float, float, float, float]) -> None:
        """Raise the generator's own error if the grid over ``bounds`` leaves the terrain."""
        key = (id(site), bounds)
        if key in self._checked:
            return
        xmin, ymin, xmax, ymax = bounds
        gx, gy = np.meshgrid(
            np.linspace(xmin, xmax, CHECK_SAMPLES), np.linspace(ymin, ymax, CHECK_SAMPLES)
        )
        site.heights(gx.ravel(), gy.ravel())
        self._checked[key] = None
        while len(self._checked) > 4 * self.size:
            self._checked.popitem(last=False)


def _hex(rgb: tuple[int, int, int]) -> str:
    return "#" + "".join(f"{min(max(int(c), 0), 255):02x}" for c in rgb)


#: How the map draws each obstacle kind: fill (the previews' ``OBSTACLE_RGB``), outline and
#: outline width in pixels. A fallen stalk is thinner than a pixel, so its outline, a lighter
#: straw two pixels wide, is what shows; the rest get a thin contrasting edge.
OBSTACLE_STYLE: dict[str, tuple[str, str, int]] = {
    k: (
        _hex(OBSTACLE_RGB[k]),
        _hex(tuple(min(c + 32, 255) for c in OBSTACLE_RGB[k])) if k == STALK else "#1a1a1a",  # type: ignore[arg-type]
        2 if k == STALK else 1,
    )
    for k in OBSTACLE_KINDS
}


@dataclass(frozen=True)
class Preview:
    """What the map draws, in lat/lon degrees, with the true counts."""

    plants: FloatArray  # (k, 2) lat, lon of the drawn crops (every ``stride``-th)
    weeds: FloatArray  # (w, 2)
    obstacles: dict[str, FloatArray]  # kind -> (n, 4, 2) lat, lon of each footprint's corners
    route: list[tuple[str, FloatArray]]  # ("furrow" | "headland", (n, 2) lat, lon)
    field: list[FloatArray]  # rings of the field outline, (n, 2) lat, lon
    n_plants: int
    n_weeds: int
    n_rows: int
    stride: int
    dot_m: float  # marker diameter on the ground, metres: the canopy, kept apart from neighbours
    route_m: float
    area_m2: float
    seconds: float

    def payload(self) -> dict[str, object]:
        """JSON for the page (coordinates rounded to 1e-7°, about 1 cm)."""

        def r(a: FloatArray) -> list[float]:
            return [float(v) for v in np.round(a, 7).ravel()]

        return {
            "plants": r(self.plants),
            "weeds": r(self.weeds),
            # every obstacle, never decimated: a stone dropped from the picture is one the
            # robot still meets (the bounds allow 20,000 of each kind)
            "obstacles": {k: r(v) for k, v in self.obstacles.items()},
            "obstacle_style": OBSTACLE_STYLE,
            "route": [[tag, r(pts)] for tag, pts in self.route],
            "field": [r(ring) for ring in self.field],
            "n_plants": self.n_plants,
            "n_weeds": self.n_weeds,
            "n_rows": self.n_rows,
            "stride": self.stride,
            "dot_m": self.dot_m,
            "route_m": round(self.route_m, 1),
            "area_m2": round(self.area_m2, 1),
            "compute_ms": round(1000 * self.seconds, 1),
        }


def plan_layout(
    spec: ScenarioSpec, seed: int, field_ll: BaseGeometry | None, sites: SiteCache
) -> tuple[FieldPlan, Layout, Route]:
    """The generator's field plan, layout and route for ``spec`` (no terrain sampled)."""
    plan, lay, route, _ = plan_scene(spec, seed, field_ll, sites)
    return plan, lay, route


def wants_obstacles(spec: ScenarioSpec) -> bool:
    o = spec.obstacles
    return o.stone_density > 0 or o.litter_density > 0 or o.stalk_lodging > 0


def plan_scene(
    spec: ScenarioSpec, seed: int, field_ll: BaseGeometry | None, sites: SiteCache
) -> tuple[FieldPlan, Layout, Route, Obstacles]:
    """``plan_layout`` plus the obstacles, with the lodged plants gone from the layout (their
    z, roll and pitch are those of flat ground; x, y, yaw and size are the generator's)."""
    check_spec(spec)
    rng = streams(seed)
    try:
        plan = plan_field(spec, field_ll, sites.open)
    except InputError as exc:
        if field_ll is None or exc.field != "terrain.site":
            raise
        # A drawn field fixes the site at its centroid: the field is what lies off the terrain.
        raise InputError("field", exc.value, exc.allowed) from None
    x0, y0, nx, ny, step = terrain_grid(plan.site, plan.bounds, spec.terrain.lod)
    extent = (x0, y0, x0 + (nx - 1) * step, y0 + (ny - 1) * step)
    sites.check_extent(plan.site, extent)
    curve = row_curve(
        spec.layout, plan.poly, plan.angle, plan.bounds, plan.site.heights, rng["rows"]
    )
    lay = layout(
        plan.poly, spec.layout, plan.angle, rng["jitter"], rng["gaps"], rng["weeds"], curve
    )
    lay = apply_drift(lay, spec.layout, plan.poly, rng["drift"])
    ground = FlatGround(np.zeros((2, 2)), x0, y0, step, spec.terrain.lod, extent=extent)
    lodging = None
    if wants_obstacles(spec):
        plants = place_plants(
            lay, ground, spec.crop, growth_of(spec.crop), rng["plants"], _nominal(spec)
        )
        lodging = lodge(plants, lay, spec.obstacles.stalk_lodging, rng["obstacles"])
        lay = lodging.layout
    crop_xy = np.column_stack([lay.x, lay.y])[~lay.is_weed]
    route = zigzag(lay.rows, spec.route, ground, plan.poly, crop_xy)
    if lodging is None:
        return plan, lay, route, Obstacles.empty()
    obs = field_obstacles(spec.obstacles, plan.poly, ground, lodging, route, rng["obstacles"])
    return plan, lay, route, obs


def _nominal(spec: ScenarioSpec) -> float | None:
    """A crop's height before its spread, as ``generate`` takes it: the user model's own with
    ``crop.model_scale: native``, else the growth stage's (None)."""
    if spec.crop.model is None or spec.crop.model_scale != "native":
        return None
    path = Path(spec.crop.model)
    stat = path.stat()
    return _native_height(str(path), stat.st_mtime_ns, stat.st_size, spec.crop.model_up_axis)


@functools.lru_cache(maxsize=8)
def _native_height(path: str, mtime_ns: int, size: int, up_axis: str) -> float:
    # keyed by the file's time and size: reading a model takes a while, and a changed
    # file is read again
    return float(inspect_model(path, "native", up_axis).size[2])


def layout_preview(
    spec: ScenarioSpec,
    seed: int,
    field_ll: BaseGeometry | None,
    sites: SiteCache,
    max_drawn: int = MAX_DRAWN,
) -> Preview:
    """The plan view of the scenario ``spec`` and ``seed`` make, for the map."""
    t0 = time.perf_counter()
    plan, lay, route, obs = plan_scene(spec, seed, field_ll, sites)
    geo = plan.site.geo
    crop = ~lay.is_weed
    n_crop = int(crop.sum())
    stride = max(1, math.ceil((n_crop + int(lay.is_weed.sum())) / max_drawn))
    cx, cy = lay.x[crop][::stride], lay.y[crop][::stride]
    wx, wy = lay.x[lay.is_weed][::stride], lay.y[lay.is_weed][::stride]

    def ll(x: FloatArray, y: FloatArray) -> FloatArray:
        lat, lon, _ = geo.enu_to_geodetic(x, y, 0.0)
        return np.column_stack([lat, lon]).reshape(-1, 2)

    pieces: list[tuple[str, FloatArray]] = []
    seg = route.segment
    cuts = np.flatnonzero(seg[1:] != seg[:-1]) + 1
    # 0.2 m between drawn route points is far below a pixel at the zooms the field fills.
    keep = max(1, int(0.2 / spec.route.spacing))
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(seg)], strict=True):
        idx = np.unique(np.r_[np.arange(a, min(b + 1, len(seg)), keep), min(b, len(seg) - 1)])
        pieces.append((str(seg[a]), ll(route.xyz[idx, 0], route.xyz[idx, 1])))
    rings = []
    for poly in getattr(plan.poly, "geoms", [plan.poly]):
        for ring in (poly.exterior, *poly.interiors):
            xy = np.asarray(ring.coords)
            rings.append(ll(xy[:, 0], xy[:, 1]))
    sp = crops.species(spec.crop.species)
    height = float(sp.height(growth_of(spec.crop)))
    feet = obs.footprints()
    drawn = {}
    for kind in OBSTACLE_KINDS:
        sel = obs.kind == kind
        if sel.any():
            corners = feet[sel].reshape(-1, 2)
            drawn[kind] = ll(corners[:, 0], corners[:, 1]).reshape(-1, 4, 2)
    return Preview(
        plants=ll(cx, cy),
        weeds=ll(wx, wy),
        obstacles=drawn,
        route=pieces,
        field=rings,
        n_plants=n_crop,
        n_weeds=int(lay.is_weed.sum()),
        n_rows=len(lay.rows.offsets),
        stride=stride,
        dot_m=min(0.3 * height, 0.4 * spec.layout.row_spacing, 0.7 * spec.layout.plant_spacing),
        route_m=route.length,
        area_m2=float(plan.poly.area),
        seconds=time.perf_counter() - t0,
    )
