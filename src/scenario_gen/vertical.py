"""Height references: what the scenario's altitudes are measured from, for every DEM read and
every height an export writes.

The scenario's frame is a tangent plane on the WGS84 ellipsoid, so its heights are meant as
ellipsoidal. A plane or a mesh takes ``terrain.datum``'s altitude as ellipsoidal. A DEM's values
are what its file declares:

- a compound CRS (horizontal + vertical, e.g. EGM96 height EPSG:5773 or NAVD88 EPSG:5703):
  orthometric heights, converted to ellipsoidal ones with pyproj when PROJ has a geoid grid
  for the area locally (the best one it has) and its network access is off
  (``geodesy.best_transformer``); otherwise kept and labelled orthometric, the grid or the
  reason named. Vertical units (US feet) become metres
  either way;
- a 3-D geographic CRS (EPSG:4979): ellipsoidal;
- a 2-D CRS (most GeoTIFFs): the vertical datum is not declared, so the heights are used as
  they are and labelled so — usually orthometric (SRTM: EGM96, USGS: NAVD88).

Used as if ellipsoidal, orthometric heights shift every altitude by the geoid undulation N
(−30 m in Tennessee, +50 m in Spain), constant over a field to millimetres, so the terrain's
shape and every ENU coordinate are unaffected; only absolute altitudes (GeoTIFF values, plant
``alt``, ``<elevation>``) carry N, and the exports say which they are. The scenario records the
reference in ``info["heights"]``.
"""

from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from pyproj import CRS, Transformer
from pyproj.crs import CompoundCRS
from pyproj.transformer import AreaOfInterest

from .arrays import FloatArray
from .geodesy import best_transformer

ELLIPSOIDAL = "ellipsoidal"
ORTHOMETRIC = "orthometric"
UNDECLARED = "undeclared"
UNRECORDED = "unrecorded"  # a scenario saved before heights were recorded


@dataclass(frozen=True)
class Heights:
    """The reference of a scenario's (or a DEM's) heights."""

    reference: str  # ELLIPSOIDAL, ORTHOMETRIC, UNDECLARED or UNRECORDED
    datum: str = ""  # "WGS 84", "EGM96 height", ...
    crs: str = ""  # the declared vertical CRS ("EPSG:5773"), where there is one
    note: str = ""  # how they came to be: converted with which operation, or why not

    def label(self) -> str:
        """One line for READMEs, band descriptions and layer descriptions."""
        if self.reference == ELLIPSOIDAL:
            return "ellipsoidal (WGS 84)" + (f"; {self.note}" if self.note else "")
        if self.reference == ORTHOMETRIC:
            return f"orthometric ({self.datum}), used as ellipsoidal" + (
                f"; {self.note}" if self.note else ""
            )
        if self.reference == UNRECORDED:
            return (
                "not recorded by the version that generated this scenario (regenerate it to "
                "have them labelled; a DEM's are usually orthometric, used as ellipsoidal)"
            )
        return (
            "the DEM's own heights, used as ellipsoidal: its vertical datum is not declared "
            "(usually orthometric, above a geoid)" + (f"; {self.note}" if self.note else "")
        )

    def to_dict(self) -> dict[str, str]:
        return asdict(self)


#: a DEM whose file declares no vertical datum
NOT_DECLARED = Heights(UNDECLARED)
#: terrain.datum's altitude (a plane or a mesh)
DATUM_HEIGHTS = Heights(ELLIPSOIDAL, "WGS 84", "", "terrain.datum's altitude is ellipsoidal")


def of_scenario(info: dict[str, Any]) -> Heights:
    """The heights a scenario's ``info`` records (UNRECORDED for a scenario from before)."""
    h = info.get("heights")
    if isinstance(h, dict) and h.get("reference") in (ELLIPSOIDAL, ORTHOMETRIC, UNDECLARED):
        return Heights(
            str(h["reference"]),
            str(h.get("datum", "")),
            str(h.get("crs", "")),
            str(h.get("note", "")),
        )
    return Heights(UNRECORDED)


def split_crs(crs: CRS) -> tuple[CRS, CRS | None, bool]:
    """(horizontal CRS, vertical CRS or None, whether the heights are ellipsoidal: a 3-D
    geographic CRS)."""
    if crs.is_compound:
        subs = crs.sub_crs_list
        vert = next((c for c in subs if c.is_vertical), None)
        horiz = next((c for c in subs if not c.is_vertical), subs[0])
        return horiz, vert, False
    if crs.is_geographic and len(crs.axis_info) == 3:
        return crs.to_2d(), None, True
    return crs, None, False


def unit_factor(vert: CRS | None) -> float:
    """Metres per unit of the vertical axis (1 without a vertical CRS)."""
    if vert is None or not vert.axis_info:
        return 1.0
    return float(vert.axis_info[0].unit_conversion_factor or 1.0)


def in_metres(vert: CRS) -> CRS:
    """``vert`` with its axis in metres, upwards (its datum and geoid model kept): how a
    scenario's heights, always metres, are described. NAVD88 height (ftUS) EPSG:6360 gives
    NAVD88 height EPSG:5703; a datum with no metre CRS of its own gets one built on it."""
    from pyproj.crs import VerticalCRS

    axis = vert.axis_info[0] if vert.axis_info else None
    if axis is None or (axis.unit_conversion_factor == 1.0 and axis.direction == "up"):
        return vert
    geoid = vert.to_json_dict().get("geoid_model", {}).get("name")
    # EPSG names a datum's metre CRS as its other units' without the unit ("NAVD88 height
    # (ftUS)", "NAVD88 depth": "NAVD88 height"), which is how PROJ finds it
    name = re.sub(r"\s*\([^)]*\)\s*$", "", vert.name).replace(" depth", " height")
    built = VerticalCRS(name=name, datum=vert.datum, geoid_model=geoid)
    found = built.list_authority(min_confidence=100)
    if found:
        return CRS.from_authority(found[0].auth_name, found[0].code)
    return VerticalCRS(name=f"{name} (metre)", datum=vert.datum, geoid_model=geoid)


def to_ellipsoidal(
    horiz: CRS, vert: CRS, area: AreaOfInterest | None
) -> tuple[Transformer | None, Heights]:
    """The transformation from (horizontal x, y, orthometric height) to WGS84 ellipsoidal
    height over ``area``, local grids only, and the heights it gives; (None, orthometric
    Heights naming why) when there is none."""
    # kept, the heights are in metres whatever the file's unit: recorded as such
    metric = in_metres(vert)
    name = metric.name
    code = metric.to_string() if metric.to_epsg() else metric.to_wkt()
    compound = CompoundCRS(f"{horiz.name} + {vert.name}", [horiz, vert])
    tr = best_transformer(
        compound, CRS.from_epsg(4979), area, tolerance_m=math.inf, local_only=True
    )
    if isinstance(tr, str):
        return None, Heights(ORTHOMETRIC, name, code, f"not converted: {tr}")
    if "ballpark" in tr.description.lower():
        why = f"not converted: PROJ knows no transformation from {name} to ellipsoidal heights"
        return None, Heights(ORTHOMETRIC, name, code, why)
    note = f"converted from {vert.name} ({vert.to_string()}) with PROJ: {tr.description}"
    return tr, Heights(ELLIPSOIDAL, "WGS 84", "", note)


def geoid_separation(tr: Transformer, x: FloatArray, y: FloatArray) -> FloatArray:
    """Ellipsoidal height of orthometric height 0 at horizontal (x, y): the geoid undulation N
    (in metres, whatever the vertical unit)."""
    xa, ya = np.broadcast_arrays(np.asarray(x, np.float64), np.asarray(y, np.float64))
    _, _, h = tr.transform(xa, ya, np.zeros_like(xa))
    return np.asarray(h, np.float64)
