"""Field polygons in from files: GeoJSON, GeoPackage, Shapefile and KML, in any declared CRS.

GeoJSON is read by our own parser (``schema.parse_json``: size, duplicate keys, nesting and
integer sizes bounded) and needs no GDAL: RFC 7946 lon/lat, or the CRS its ``crs`` member
names (what ``ogr2ogr -lco RFC7946=NO`` writes for a projected layer). GeoPackage, Shapefile
and KML go through GDAL via pyogrio (the ``gis`` extra, ≈100 MB with its own GDAL, imported
only here). Every file is checked before GDAL opens it: a local regular file of a known
suffix, whose first bytes are what that suffix promises (GDAL picks its driver by content),
at most ``MAX_FIELD_BYTES`` with its Shapefile sidecars, at most ``MAX_FIELD_FEATURES``
features read, at most ``MAX_SCAN_LAYERS`` layers searched.

Layers: ``field.layer`` names the layer; without it the file's only layer, or its only layer
holding polygons, is used, and a file with several is refused with their names. All Polygon
and MultiPolygon features of the layer are merged (polygons inside a GeometryCollection
included); other geometries are ignored; heights (Z) are dropped. Coordinates are
reprojected to WGS84 lon/lat with pyproj, by PROJ's best transformation for the field's area;
when its grid is missing, the best without it is taken if it is good to ``MAX_SHIFT_M``, and
otherwise the file is refused with the grid named, rather than placed approximately.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from pyproj import CRS
from shapely.geometry import GeometryCollection, MultiPolygon, Polygon, shape
from shapely.geometry.base import BaseGeometry
from shapely.validation import explain_validity

from .antimeridian import joined_across
from .errors import InputError
from .field import MAX_NESTING, geometries
from .geodesy import MAX_SHIFT_M, area_of, best_transformer
from .schema import parse_json

MAX_FIELD_BYTES = 64 * 2**20
MAX_FIELD_FEATURES = 100_000
#: layers searched for polygons when field.layer is not set (each KML folder is a re-read)
MAX_SCAN_LAYERS = 16
PATH_FIELD = "field.geojson"
LAYER_FIELD = "field.layer"
JSON_SUFFIXES = (".geojson", ".json")
#: suffix -> format name (the file's first bytes are checked against it: ``_check_magic``)
GDAL_SUFFIXES = {
    ".gpkg": "GeoPackage",
    ".shp": "Shapefile",
    ".kml": "KML",
}
SHAPEFILE_SIDECARS = (".shx", ".dbf", ".prj", ".cpg")
ACCEPTED = "GeoJSON (.geojson, .json), GeoPackage (.gpkg), Shapefile (.shp) or KML (.kml)"
GIS_EXTRA = "pip install 'agrinav-gym[gis]' (pyogrio)"
#: GeoJSON ``crs`` names accepted (GeoJSON 2008; what GDAL writes): EPSG codes and OGC CRS84
CRS_NAME = re.compile(
    r"^(?:urn:ogc:def:crs:(?:EPSG:[0-9.]*:\d{1,6}|OGC:1\.3:CRS(?:84|83|27))|EPSG:\d{1,6})$"
)


def read_field(path: str | Path, layer: str | None = None) -> BaseGeometry:
    """The field's (multi)polygon in WGS84 lon/lat from any accepted file; see the module."""
    p = _check_file(path)
    suffix = p.suffix.lower()
    if suffix in JSON_SUFFIXES:
        polys, crs = _geojson_polygons(p, layer)
    else:
        polys, crs = _gdal_polygons(p, suffix, layer)
    for poly in polys:
        _check_valid(poly, str(path))
    lonlat = joined_across([_to_lonlat(poly, crs, str(path)) for poly in polys])
    return shapely.union_all(lonlat) if len(lonlat) > 1 else lonlat[0]


def _check_file(path: str | Path) -> Path:
    p = Path(path)
    text = str(path)
    if text.startswith("/vsi") or "://" in text:
        raise InputError(PATH_FIELD, text, f"allowed: a local file, {ACCEPTED}")
    suffix = p.suffix.lower()
    if suffix not in JSON_SUFFIXES and suffix not in GDAL_SUFFIXES:
        raise InputError(PATH_FIELD, text, f"allowed: {ACCEPTED}")
    if not p.is_file():
        raise InputError(PATH_FIELD, text, f"allowed: an existing file, {ACCEPTED}")
    size = p.stat().st_size
    if suffix == ".shp":
        size += sum(q.stat().st_size for q in _sidecars(p))
    if size > MAX_FIELD_BYTES:
        raise InputError(
            PATH_FIELD, text, f"is {size:,} bytes; allowed: at most {MAX_FIELD_BYTES:,}"
        )
    return p


def _sidecars(shp: Path) -> list[Path]:
    out = []
    for ext in SHAPEFILE_SIDECARS:
        for q in (shp.with_suffix(ext), shp.with_suffix(ext.upper())):
            if q.is_file():
                out.append(q)
                break
    return out


def _check_valid(poly: BaseGeometry, where: str) -> None:
    if poly.is_empty:
        raise InputError(PATH_FIELD, where, "the polygon is empty")
    if not poly.is_valid:
        raise InputError(
            PATH_FIELD,
            where,
            f"the polygon is invalid ({explain_validity(poly)}); allowed: a "
            "simple polygon without self-intersections",
        )


def _to_lonlat(poly: BaseGeometry, crs: CRS | None, where: str) -> BaseGeometry:
    """``poly`` in WGS84 lon/lat; ``crs`` None: it already is (RFC 7946), which is checked."""
    if crs is None:
        out = poly
    else:
        xy = shapely.get_coordinates(poly)
        area = area_of(crs, xy[:, 0], xy[:, 1])
        tr = best_transformer(crs, CRS.from_epsg(4326), area, tolerance_m=MAX_SHIFT_M)
        if isinstance(tr, str):
            raise InputError(PATH_FIELD, where, f"cannot be reprojected to WGS84 lon/lat: {tr}")

        def tx(xy: np.ndarray) -> np.ndarray:
            with np.errstate(all="ignore"):
                lon, lat = tr.transform(xy[:, 0], xy[:, 1])
            return np.column_stack([lon, lat])

        out = shapely.transform(poly, tx)
    xy = shapely.get_coordinates(out)
    ok = (
        np.isfinite(xy).all() and (np.abs(xy[:, 0]) <= 180).all() and (np.abs(xy[:, 1]) <= 90).all()
    )
    if not ok:
        if crs is None:
            raise InputError(
                PATH_FIELD,
                f"bounds {poly.bounds}",
                "coordinates must be WGS84 longitude, latitude (RFC 7946); these look projected "
                '(a GeoJSON in another CRS must name it in a "crs" member, as ogr2ogr writes '
                "with -lco RFC7946=NO)",
            )
        raise InputError(
            PATH_FIELD,
            f"bounds {poly.bounds}",
            f"do not map to longitude, latitude from the file's CRS {crs.name}; allowed: the "
            "CRS the coordinates are in (is it mislabelled?)",
        )
    if crs is not None and not out.is_valid:  # a reprojection can fold a huge polygon
        raise InputError(
            PATH_FIELD, where, f"the polygon is invalid in lon/lat ({explain_validity(out)})"
        )
    return out


# ----------------------------------------------------------------------------- GeoJSON
def _geojson_polygons(p: Path, layer: str | None) -> tuple[list[BaseGeometry], CRS | None]:
    data = parse_json(p.read_bytes(), PATH_FIELD, str(p))
    if layer is not None:
        name = data.get("name") if isinstance(data, dict) else None
        if layer not in (name, p.stem):
            raise InputError(
                LAYER_FIELD,
                layer,
                f"a GeoJSON file holds one layer ({name or p.stem!r}); allowed: that or null",
            )
    geoms = [g for g in geometries(data, str(p)) if g.get("type") in ("Polygon", "MultiPolygon")]
    if not geoms:
        raise InputError(PATH_FIELD, str(p), "holds no Polygon or MultiPolygon geometry")
    try:
        polys = [shape(g) for g in geoms]
    except Exception as exc:  # shapely raises several types for malformed coordinates
        raise InputError(PATH_FIELD, str(p), f"has malformed coordinates ({exc})") from None
    return polys, _geojson_crs(data, str(p))


def _geojson_crs(data: Any, where: str) -> CRS | None:
    """The CRS a GeoJSON ``crs`` member names (None: RFC 7946 lon/lat)."""
    member = data.get("crs") if isinstance(data, dict) else None
    if member is None:
        return None
    props = member.get("properties") if isinstance(member, dict) else None
    name = props.get("name") if isinstance(props, dict) else None
    if not (isinstance(member, dict) and member.get("type") == "name" and isinstance(name, str)):
        raise InputError(
            PATH_FIELD,
            where,
            'has a "crs" member that is not {"type": "name", "properties": {"name": ...}}; '
            "allowed: a named CRS (linked CRSs are not fetched)",
        )
    if not CRS_NAME.match(name):
        raise InputError(
            PATH_FIELD,
            f"crs {name[:60]!r}",
            "allowed: urn:ogc:def:crs:EPSG::<code>, urn:ogc:def:crs:OGC:1.3:CRS84 or EPSG:<code>",
        )
    try:
        crs = CRS.from_user_input(name)
    except Exception as exc:  # pyproj.exceptions.CRSError for an unknown code
        raise InputError(
            PATH_FIELD, f"crs {name!r}", f"is not a CRS pyproj knows ({exc})"
        ) from None
    return _horizontal(crs, where)


def _horizontal(crs: CRS, where: str = "") -> CRS:
    """The horizontal part of a compound CRS (the field is 2-D), refused unless it places
    points on the Earth: a local or engineering grid (a CAD or survey export), a vertical CRS,
    or GDAL's stand-ins for a missing one ("Undefined geographic/Cartesian SRS", a GeoPackage's
    srs_id 0 and -1) have no way to longitude and latitude."""
    if crs.is_compound:
        crs = crs.sub_crs_list[0]
    if not (crs.is_geographic or crs.is_projected) or crs.name.lower().startswith("undefined"):
        raise InputError(
            PATH_FIELD,
            where,
            f"declares the {crs.type_name} {crs.name!r}, not one that gives a longitude and "
            "latitude; allowed: a file that names its geographic or projected CRS",
        )
    return crs


# ----------------------------------------------------------------------------- GDAL formats
#: how far into a KML file its root element is looked for (comments may come first)
KML_SNIFF_BYTES = 65536


def _check_magic(p: Path, suffix: str) -> None:
    with open(p, "rb") as f:
        head = f.read(KML_SNIFF_BYTES)
    fmt = GDAL_SUFFIXES[suffix]
    if suffix == ".gpkg":
        ok = head.startswith(b"SQLite format 3\x00")
    elif suffix == ".shp":
        ok = len(head) >= 100 and head[:4] == b"\x00\x00\x27\x0a"
    else:
        # past an XML declaration and comments, in UTF-8 or UTF-16
        utf16 = head[:2] in (b"\xff\xfe", b"\xfe\xff")
        text = head.decode("utf-16", errors="ignore") if utf16 else head
        ok = (b"<kml" in text) if isinstance(text, bytes) else ("<kml" in text)
    if not ok:
        raise InputError(PATH_FIELD, str(p), f"is not a {fmt} file (its first bytes say so)")


def _pyogrio(p: Path) -> Any:
    try:
        import pyogrio
    except ImportError:
        raise InputError(
            PATH_FIELD,
            str(p),
            f"reading {GDAL_SUFFIXES[p.suffix.lower()]} needs pyogrio: {GIS_EXTRA}; GeoJSON "
            "needs nothing more",
        ) from None
    return pyogrio


def _polygonal(kind: Any) -> bool:
    """An OGR layer geometry type that holds polygons."""
    return isinstance(kind, str) and ("Polygon" in kind or "Surface" in kind)


def _maybe_polygonal(kind: Any) -> bool:
    """An OGR layer geometry type that may hold polygons (a KML folder is "Unknown")."""
    return isinstance(kind, str) and (kind.startswith("Unknown") or "Geometry" in kind)


def _gdal_polygons(
    p: Path, suffix: str, layer: str | None
) -> tuple[list[BaseGeometry], CRS | None]:
    _check_magic(p, suffix)
    pyogrio = _pyogrio(p)
    from pyogrio.errors import DataLayerError, DataSourceError, FieldError, GeometryError

    errors = (DataSourceError, DataLayerError, FieldError, GeometryError, OSError)
    try:
        layers = [(str(n), t) for n, t in pyogrio.list_layers(str(p))]
    except errors as exc:
        raise InputError(PATH_FIELD, str(p), f"cannot be read ({exc})") from None
    names = [n for n, _ in layers]
    if layer is not None:
        if layer not in names:
            raise InputError(
                LAYER_FIELD, layer, f"allowed: a layer of {p.name}: {', '.join(names) or 'none'}"
            )
        chosen = layer
        read = _read_layer(pyogrio, p, chosen, errors, LAYER_FIELD)
    elif len(layers) == 1:
        chosen = names[0]
        read = _read_layer(pyogrio, p, chosen, errors, PATH_FIELD)
    elif len(layers) > MAX_SCAN_LAYERS:
        raise InputError(
            LAYER_FIELD,
            None,
            f"{p.name} has {len(layers)} layers, more than the {MAX_SCAN_LAYERS} searched for "
            "polygons; allowed: the name of the one holding the field",
        )
    else:
        found: dict[str, tuple[list[BaseGeometry], CRS | None]] = {}
        for name, kind in layers:
            if _polygonal(kind):
                found[name] = ([], None)  # read once chosen
            elif _maybe_polygonal(kind):
                polys, crs = _read_layer(pyogrio, p, name, errors, None)
                if polys:
                    found[name] = (polys, crs)
        if not found:
            raise InputError(
                PATH_FIELD,
                str(p),
                f"has no layer holding Polygon or MultiPolygon geometry (layers: "
                f"{', '.join(names) or 'none'})",
            )
        if len(found) > 1:
            raise InputError(
                LAYER_FIELD,
                None,
                f"{p.name} has {len(found)} polygon layers ({', '.join(found)}); allowed: "
                "the name of the one holding the field",
            )
        chosen = next(iter(found))
        if not found[chosen][0]:
            found[chosen] = _read_layer(pyogrio, p, chosen, errors, PATH_FIELD)
        read = found[chosen]
    return read


def _read_layer(
    pyogrio: Any,
    p: Path,
    layer: str,
    errors: tuple[type[BaseException], ...],
    refuse_as: str | None,
) -> tuple[list[BaseGeometry], CRS | None]:
    """The polygons of one layer and its CRS; none found is refused as ``refuse_as`` (the
    field to name), or returned empty when None."""
    where = f"{p.name}, layer {layer!r}"
    try:
        with warnings.catch_warnings():
            # GDAL passes an unclosed ring on with this warning; it is closed below, as a
            # GeoJSON's is (shapely's ``shape``)
            warnings.filterwarnings("ignore", "Non closed ring detected", RuntimeWarning)
            meta, _, wkb, _ = pyogrio.raw.read(
                str(p), layer=layer, columns=[], force_2d=True, max_features=MAX_FIELD_FEATURES + 1
            )
    except errors as exc:
        raise InputError(PATH_FIELD, where, f"cannot be read ({exc})") from None
    if wkb is None:
        wkb = np.empty(0, dtype=object)
    if len(wkb) > MAX_FIELD_FEATURES:
        raise InputError(
            PATH_FIELD, where, f"holds over {MAX_FIELD_FEATURES:,} features; allowed: at most that"
        )
    try:
        geoms = shapely.from_wkb(
            np.asarray([g for g in wkb if g is not None], dtype=object), on_invalid="fix"
        )
    except Exception as exc:  # shapely.errors.GEOSException: curves, corrupt WKB
        raise InputError(
            PATH_FIELD,
            where,
            f"holds a geometry shapely cannot read ({exc}); allowed: Polygon/MultiPolygon "
            "(curved polygons: linearise them, e.g. ogr2ogr -nlt MULTIPOLYGON)",
        ) from None
    polys = _polygons_of(list(geoms))
    if not polys:
        if refuse_as is not None:
            raise InputError(
                refuse_as,
                layer if refuse_as == LAYER_FIELD else where,
                f"layer {layer!r} of {p.name} holds no Polygon or MultiPolygon geometry; "
                "allowed: a layer holding the field's polygons",
            )
        return [], None
    if not meta.get("crs"):
        raise InputError(
            PATH_FIELD,
            where,
            "declares no CRS (a Shapefile without its .prj?); allowed: a file that names its CRS",
        )
    try:
        crs = CRS.from_user_input(meta["crs"])
    except Exception as exc:  # pyproj.exceptions.CRSError
        raise InputError(PATH_FIELD, where, f"has a CRS pyproj cannot read ({exc})") from None
    return polys, _horizontal(crs, where)


def _polygons_of(geoms: list[BaseGeometry]) -> list[BaseGeometry]:
    """The Polygon/MultiPolygon members, collections opened (nesting bounded)."""
    out: list[BaseGeometry] = []
    stack = [(g, 0) for g in reversed(geoms)]
    while stack:
        g, depth = stack.pop()
        if isinstance(g, (Polygon, MultiPolygon)):
            if not g.is_empty:
                out.append(g)
        elif isinstance(g, GeometryCollection):
            if depth >= MAX_NESTING:
                raise InputError(
                    PATH_FIELD, g.geom_type, f"nests collections over {MAX_NESTING} levels deep"
                )
            stack += [(m, depth + 1) for m in reversed(list(g.geoms))]
    return out
