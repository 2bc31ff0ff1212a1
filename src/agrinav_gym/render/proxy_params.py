"""The proxy camera's plant parameters, read from the table the offline fit writes.

``proxy_fit.json`` (beside this module) holds, per species and catalog stage, the core's
``fill``, the leaf band's ``base`` and ``reach`` (see ``PlantField``) and the fit's residuals,
which are the tolerances of the proxy-against-mesh test. ``agrinav_gym.tools.proxy_fit`` makes
it (``python benchmarks/fit_proxy.py``); the runtime only reads it. Between stages the
parameters are interpolated linearly in growth.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from typing import Any

import numpy as np

from scenario_gen.arrays import FloatArray
from scenario_gen.errors import InputError

ParamsFn = Callable[[str, Any], tuple[Any, Any, Any]]

TABLE_FILE = "proxy_fit.json"
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


def parse_table(doc: Any) -> dict[str, FloatArray]:
    """The per-species tables of a ``proxy_fit.json`` document, checked: the columns are
    ``COLUMNS`` and each species' rows rise in growth over [0, 1]."""
    if not isinstance(doc, dict) or tuple(doc.get("columns", ())) != COLUMNS:
        got = doc.get("columns") if isinstance(doc, dict) else doc
        raise InputError(f"{TABLE_FILE} columns", got, f"allowed: {list(COLUMNS)}")
    species = doc.get("species")
    if not isinstance(species, dict) or not species:
        raise InputError(f"{TABLE_FILE} species", species, "allowed: a mapping of species to rows")
    out = {}
    for name, rows in species.items():
        field = f"{TABLE_FILE} species.{name}"
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


@lru_cache(maxsize=1)
def fitted() -> dict[str, FloatArray]:
    text = resources.files(__package__).joinpath(TABLE_FILE).read_text()
    return parse_table(json.loads(text))


def _table(name: str) -> FloatArray:
    tables = fitted()
    if name not in tables:
        raise InputError(
            "species (proxy camera parameters)",
            name,
            f"fitted: {', '.join(sorted(tables))} (after adding a species run "
            "`python benchmarks/fit_proxy.py`)",
        )
    return tables[name]


def proxy_params(name: str, growth: Any) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Fitted (fill, base, reach) of species ``name`` at ``growth`` (scalar or array)."""
    table = _table(name)
    g = np.asarray(growth, np.float64)
    return (
        np.interp(g, table[:, 0], table[:, 1]),
        np.interp(g, table[:, 0], table[:, 2]),
        np.interp(g, table[:, 0], table[:, 3]),
    )


def fit_residuals(name: str, growth: float) -> tuple[float, float, float, float]:
    """The fit's (mean |Δz| per pixel, its SD over poses, mean |Δ lane width|, its SD), m,
    at ``growth`` (interpolated between stages)."""
    table = _table(name)
    out = [float(np.interp(growth, table[:, 0], table[:, k])) for k in range(4, 8)]
    return out[0], out[1], out[2], out[3]
