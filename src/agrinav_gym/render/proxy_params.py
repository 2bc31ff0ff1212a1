"""The proxy camera's plant parameters, read from the tables the offline fit writes.

Each table (beside this module) holds, per species and catalog stage, the core's ``fill``, the
leaf band's ``base`` and ``reach`` (see ``PlantField``) and the fit's residuals, which are the
tolerances of the proxy-against-mesh test. There is one table per planting the fit's lanes were
made on (``PLANTINGS``): where the camera stands against the plants differs by the ridge height
(in the furrow, the plants on the crests), so the parameters that best match the meshes differ
too. ``agrinav_gym.tools.proxy_fit`` makes them (``python benchmarks/fit_proxy.py``); the
runtime only reads them. Between stages the parameters are interpolated linearly in growth.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from importlib import resources
from typing import Any

import numpy as np

from scenario_gen.arrays import FloatArray
from scenario_gen.errors import InputError
from scenario_gen.spec import FurrowSpec

from ..config import PROXY_PLANTINGS

ParamsFn = Callable[[str, Any], tuple[Any, Any, Any]]

#: the fit's lanes → the table fitted on them: "ridged", the v1 envs' 0.12 m ridges (every
#: published proxy-camera result used it); "flat", the default fields' flat planting
PLANTINGS = dict(zip(PROXY_PLANTINGS, ("proxy_fit.json", "proxy_fit_flat.json"), strict=True))
COLUMNS = (
    "growth",
    "fill",
    "base",
    "reach",
    "depth_mae_m",
    "depth_mae_sd_m",
    "lane_width_mae_m",
    "lane_width_mae_sd_m",
)


@dataclass(frozen=True)
class ProxyParams:
    fill: float  # core radius / canopy width
    base: float  # leaf band bottom / plant height
    reach: float  # leaf band radius / half canopy width, leaf plane across the row

    def tuple(self) -> tuple[float, float, float]:
        return self.fill, self.base, self.reach


def parse_table(doc: Any, source: str = PLANTINGS["ridged"]) -> dict[str, FloatArray]:
    """The per-species tables of a proxy-fit document (``source``: its file, for errors),
    checked: the columns are ``COLUMNS`` and each species' rows rise in growth over [0, 1]."""
    if not isinstance(doc, dict) or tuple(doc.get("columns", ())) != COLUMNS:
        got = doc.get("columns") if isinstance(doc, dict) else doc
        raise InputError(f"{source} columns", got, f"allowed: {list(COLUMNS)}")
    species = doc.get("species")
    if not isinstance(species, dict) or not species:
        raise InputError(f"{source} species", species, "allowed: a mapping of species to rows")
    out = {}
    for name, rows in species.items():
        field = f"{source} species.{name}"
        try:
            t = np.asarray(rows, np.float64)
        except (TypeError, ValueError):
            t = np.empty(0)
        if t.ndim != 2 or t.shape[1] != len(COLUMNS) or not np.isfinite(t).all():
            raise InputError(field, rows, f"allowed: rows of {len(COLUMNS)} finite numbers")
        g = t[:, 0]
        if g[0] != 0.0 or g[-1] != 1.0 or np.any(np.diff(g) <= 0):
            raise InputError(
                f"{field} growth", g.tolist(), "allowed: rising from 0 to 1 (one row per stage)"
            )
        out[str(name)] = t
    return out


#: the ridge height of the lanes the ridged table was fitted on (the ``ridged`` preset's furrows;
#: the flat table's lanes have none)
RIDGED_FIT_HEIGHT = 0.12


def planting_of(furrows: FurrowSpec) -> str:
    """The table fitted nearer a field's ridge height: ``ridged`` from half the ridged fit's
    ridges up, ``flat`` below (roughness and a planting furrow of a few cm are flat planting)."""
    height = furrows.depth if furrows.enabled else 0.0
    return "ridged" if height >= 0.5 * RIDGED_FIT_HEIGHT else "flat"


def check_planting(planting: Any) -> str:
    if planting not in PLANTINGS:
        raise InputError("proxy fit planting", planting, f"allowed: {', '.join(PLANTINGS)}")
    return str(planting)


@cache  # one entry per valid call: a planting that is refused raises and is not kept
def fitted(planting: str = "ridged") -> dict[str, FloatArray]:
    """The table fitted on ``planting``'s lanes, per species."""
    text = resources.files(__package__).joinpath(PLANTINGS[check_planting(planting)]).read_text()
    return parse_table(json.loads(text), PLANTINGS[planting])


def _table(name: str, planting: str) -> FloatArray:
    tables = fitted(planting)
    if name not in tables:
        raise InputError(
            "species (proxy camera parameters)",
            name,
            f"fitted: {', '.join(sorted(tables))} (after adding a species run "
            "`python benchmarks/fit_proxy.py`)",
        )
    return tables[name]


def proxy_params(
    name: str, growth: Any, planting: str = "ridged"
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Fitted (fill, base, reach) of species ``name`` at ``growth`` (scalar or array), from the
    table fitted on ``planting``."""
    table = _table(name, planting)
    g = np.asarray(growth, np.float64)
    return (
        np.interp(g, table[:, 0], table[:, 1]),
        np.interp(g, table[:, 0], table[:, 2]),
        np.interp(g, table[:, 0], table[:, 3]),
    )


def fit_residuals(
    name: str, growth: float, planting: str = "ridged"
) -> tuple[float, float, float, float]:
    """The fit's (mean |Δz| per pixel, its SD over poses, mean |Δ lane width|, its SD), m,
    at ``growth`` (interpolated between stages), in the table fitted on ``planting``."""
    table = _table(name, planting)
    out = [float(np.interp(growth, table[:, 0], table[:, k])) for k in range(4, 8)]
    return out[0], out[1], out[2], out[3]
