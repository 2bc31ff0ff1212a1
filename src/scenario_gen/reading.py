"""Reading a scenario folder back, with every file checked (``load``).

A folder may be truncated, edited by hand or crafted: each file is bounded in size before it is
read, parsed defensively and checked field by field, and any defect is an ``InputError`` naming
the file, the field (or line and column) and what is allowed. Files must lie in the folder: a
symbolic link pointing out of it is refused, not followed. Format versions 1 to 4 are read;
version 1 has no ``row`` column in plants.csv, so rows are recovered as the nearest row line
(exact there, since jitter is bounded to half a row spacing).
"""

from __future__ import annotations

import csv
import math
import zipfile
import zlib
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np
from shapely import wkt
from shapely.errors import ShapelyError
from shapely.geometry import MultiPolygon, Polygon

from .bounds import (
    MAX_ENU_HEIGHT_M,
    MAX_ENU_OFFSET_M,
    MAX_GROUND_SPACING,
    MAX_OBSTACLES,
    MAX_PLANT_HEIGHT_M,
    MAX_PLANTS,
    MAX_ROUTE_WAYPOINTS,
    MAX_TERRAIN_SAMPLES,
    MIN_GROUND_SPACING,
)
from .crops import CATALOG, WEED_SPECIES
from .errors import InputError
from .geodesy import GeoFrame
from .io import (
    FORMAT,
    OBSTACLE_HEADER,
    PLANT_HEADER,
    PLANT_HEADER_V1,
    READABLE_VERSIONS,
    ROUTE_HEADER,
    ROUTE_HEADER_V2,
)
from .layout import RowFrame
from .model import Plants, Scenario
from .model_files import MAX_FILES as MAX_MODEL_FILES
from .model_shape import ProxyShape
from .models import MAX_TOTAL_BYTES as MAX_MODEL_BYTES
from .models import SCALE_RULES, UP_AXES, UserModel, sha256_file
from .obstacles import OBSTACLE_KINDS, Obstacles
from .routes import SEGMENTS, TURN_TAGS, Route
from .rowcurve import RowCurve
from .schema import parse_json
from .spec import ScenarioSpec
from .terrain import Terrain

MAX_JSON_BYTES = 64 * 2**20
MAX_CSV_ROW_BYTES = 400  # a plants.csv line is about 150 bytes
MAX_NPZ_BYTES = 16 * MAX_TERRAIN_SAMPLES


def _check_format(meta: dict[str, Any], path: Path) -> int:
    """The file's version, where it is of this format and a version this package reads."""
    if "format" not in meta:
        raise InputError(
            "scenario.json",
            str(path),
            f"has no 'format' key; allowed: a scenario folder written by agrinav scenario "
            f"(format {FORMAT!r})",
        )
    if meta["format"] != FORMAT:
        raise InputError("scenario.json: format", meta["format"], f"allowed: {FORMAT!r}")
    version = meta.get("format_version")
    if type(version) is not int or version not in READABLE_VERSIONS:
        raise InputError(
            "scenario.json: format_version",
            version,
            f"allowed: {', '.join(map(str, READABLE_VERSIONS))} (a newer agrinav reads newer "
            "versions)",
        )
    return int(version)


def load(directory: str | Path) -> Scenario:
    """Read a scenario directory written by ``save``, checking every file."""
    d = Path(directory)
    if not d.is_dir():
        raise InputError("scenario", str(d), "is not a directory")
    meta_path = _member(d, "scenario.json", MAX_JSON_BYTES)
    meta = _json(meta_path)
    version = _check_format(meta, meta_path)
    spec = _spec(meta)
    seed = _get(meta, "seed", int)
    if not 0 <= seed < 2**63:
        raise InputError("scenario.json: seed", seed, "allowed: an integer in [0, 2**63)")
    datum = _get(meta, "datum", dict)
    lat, lon, alt = (float(_get(datum, k, float, f"datum.{k}")) for k in ("lat", "lon", "alt"))
    try:
        geo = GeoFrame(lat, lon, alt)
    except InputError as exc:
        raise InputError(f"scenario.json: {exc.field}", exc.value, exc.allowed) from None
    terrain = _terrain(_member(d, "terrain.npz", MAX_NPZ_BYTES), meta)
    rows = _rows(_get(meta, "rows", dict), version)
    field = _field(meta)
    plants = _plants(_member(d, "plants.csv", MAX_PLANTS * MAX_CSV_ROW_BYTES), rows, version)
    route = _route(_member(d, "route.csv", MAX_ROUTE_WAYPOINTS * MAX_CSV_ROW_BYTES), rows, version)
    _on_terrain(terrain, plants.x, plants.y, "plants.csv")
    _on_terrain(terrain, route.xy[:, 0], route.xy[:, 1], "route.csv")
    _counted(meta, plants, len(route))
    obstacles = Obstacles.empty()
    if version >= 4:
        obstacles = _obstacles(_member(d, "obstacles.csv", MAX_OBSTACLES * MAX_CSV_ROW_BYTES))
        _on_terrain(terrain, obstacles.x, obstacles.y, "obstacles.csv")
    info = meta.get("info", {})
    if not isinstance(info, dict):
        raise InputError("scenario.json: info", type(info).__name__, "allowed: a mapping")
    user_model = _user_model(d, meta.get("crop_model"), version)
    if user_model is not None:  # the folder's copy, wherever the folder now is
        spec = spec.replace({"crop.model": str(user_model.path)})
    return Scenario(
        spec, seed, geo, terrain, field, rows, plants, route, dict(info), user_model, obstacles
    )


def _on_terrain(terrain: Terrain, x: np.ndarray, y: np.ndarray, name: str) -> None:
    """Every point on the terrain grid (generation never places one off it)."""
    inside = terrain.contains(np.asarray(x), np.asarray(y))
    if not np.all(inside):
        i = int(np.argmin(inside))
        raise InputError(
            f"{name}: line {i + 2}",
            f"({float(x[i]):.6g}, {float(y[i]):.6g})",
            "allowed: points on the scenario's terrain (terrain.npz)",
        )


# ----------------------------------------------------------------------------- files
def _member(d: Path, name: str, max_bytes: int) -> Path:
    """``d/name``: a regular file inside ``d`` (no symlink out of it) of at most max_bytes."""
    p = d / name
    if p.is_symlink():
        target = p.resolve()
        if not target.is_relative_to(d.resolve()):
            raise InputError(
                name, str(p), f"is a symbolic link out of the scenario folder (to {target})"
            )
    if not p.is_file():
        what = "not a scenario directory" if name == "scenario.json" else "an incomplete scenario"
        raise InputError(name, str(p), f"is missing ({what})")
    size = p.stat().st_size
    if size > max_bytes:
        raise InputError(name, f"{size:,} bytes", f"allowed: at most {max_bytes:,} bytes")
    return p


def _json(path: Path) -> dict[str, Any]:
    data = parse_json(path.read_bytes(), path.name, str(path))
    if not isinstance(data, dict):
        raise InputError(path.name, type(data).__name__, "allowed: a JSON object")
    return data


def _get(obj: dict[str, Any], key: str, kind: type, name: str | None = None) -> Any:
    """``obj[key]`` of JSON type ``kind`` (float accepts int; finite numbers only)."""
    where = f"scenario.json: {name or key}"
    if key not in obj:
        raise InputError(where, None, "is missing")
    v = obj[key]
    ok = (
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        if kind is float
        else isinstance(v, int) and not isinstance(v, bool)
        if kind is int
        else isinstance(v, kind)
    )
    if not ok:
        allowed = {float: "a finite number", int: "an integer", str: "a string"}.get(
            kind, f"a JSON {'object' if kind is dict else 'array'}"
        )
        raise InputError(where, v, f"allowed: {allowed}")
    return v


def _numbers(obj: dict[str, Any], key: str, n: int | None = None) -> np.ndarray:
    v = _get(obj, key, list, f"rows.{key}")
    arr = np.asarray(
        [x if isinstance(x, (int, float)) and not isinstance(x, bool) else np.nan for x in v],
        dtype=np.float64,
    )
    if not np.isfinite(arr).all() or (n is not None and len(arr) != n):
        raise InputError(
            f"scenario.json: rows.{key}",
            v if len(v) < 8 else f"{len(v)} values",
            f"allowed: {n if n is not None else 'a list of'} finite numbers",
        )
    return arr


# ----------------------------------------------------------------------------- scenario.json
def _spec(meta: dict[str, Any]) -> ScenarioSpec:
    from .generate import check_spec

    try:
        spec = ScenarioSpec.from_dict(_get(meta, "spec", dict))
        check_spec(spec)  # the cross-field rules generation applied (an edited file skipped them)
        return spec
    except InputError as exc:
        raise InputError(f"scenario.json: spec.{exc.field}", exc.value, exc.allowed) from None


def _rows(r: dict[str, Any], version: int) -> RowFrame:
    angle = float(_get(r, "angle_rad", float, "rows.angle_rad"))
    origin = _numbers(r, "origin", 2)
    spacing = float(_get(r, "spacing", float, "rows.spacing"))
    if spacing <= 0:
        raise InputError("scenario.json: rows.spacing", spacing, "allowed: a number > 0")
    offsets = _numbers(r, "offsets")
    n = len(offsets)
    if n == 0 or (np.diff(offsets) <= 0).any():
        raise InputError(
            "scenario.json: rows.offsets", f"{n} values", "allowed: at least one, ascending"
        )
    starts, ends = _numbers(r, "starts", n), _numbers(r, "ends", n)
    if (starts > ends).any():
        raise InputError("scenario.json: rows.starts", "> ends", "allowed: starts <= ends")
    if version < 2:
        return RowFrame(angle, (origin[0], origin[1]), offsets, starts, ends, spacing)
    segs = _get(r, "segments", list, "rows.segments")
    try:
        arr = np.asarray(segs, dtype=np.float64).reshape(-1, 3)
    except (ValueError, TypeError):
        arr = np.full((1, 3), np.nan)
    row = arr[:, 0]
    if (
        len(arr) != len(segs)
        or not np.isfinite(arr).all()
        or (row != np.round(row)).any()
        or (row < 0).any()
        or (row >= n).any()
        or (arr[:, 1] > arr[:, 2]).any()
        or (np.diff(row) < 0).any()
    ):
        raise InputError(
            "scenario.json: rows.segments",
            f"{len(segs)} entries",
            f"allowed: [row 0..{n - 1}, start <= end] per segment, sorted by row",
        )
    return RowFrame(
        angle,
        (origin[0], origin[1]),
        offsets,
        starts,
        ends,
        spacing,
        row.astype(np.int64),
        np.ascontiguousarray(arr[:, 1:]),
        _curve(r.get("curve")) if version >= 3 else None,
    )


def _curve(c: Any) -> RowCurve | None:
    """The reference curve of curved or contour rows (null for straight rows)."""
    if c is None:
        return None
    where = "scenario.json: rows.curve"
    if not isinstance(c, dict):
        raise InputError(where, type(c).__name__, "allowed: null or a mapping")
    kind = c.get("kind")
    if kind not in ("curved", "contour"):
        raise InputError(f"{where}.kind", kind, "allowed: curved or contour")
    cols = {k: _numbers(c, k) for k in ("t", "x", "y", "theta")}
    n = len(cols["t"])
    if n < 2 or any(len(v) != n for v in cols.values()) or (np.diff(cols["t"]) <= 0).any():
        raise InputError(
            where,
            f"{n} points",
            "allowed: at least 2 points, as many t, x, y and theta, t ascending",
        )
    return RowCurve(kind, np.column_stack([cols["x"], cols["y"]]), cols["t"], cols["theta"])


def _field(meta: dict[str, Any]) -> Polygon | MultiPolygon:
    text = _get(meta, "field_enu_wkt", str)
    try:
        geom = wkt.loads(text)
    except (ShapelyError, ValueError, TypeError):
        geom = None
    if not isinstance(geom, (Polygon, MultiPolygon)) or geom.is_empty or not geom.is_valid:
        raise InputError(
            "scenario.json: field_enu_wkt", text[:40], "allowed: a valid Polygon/MultiPolygon WKT"
        )
    return geom


def _user_model(d: Path, rec: Any, version: int) -> UserModel | None:
    if rec is None or version < 2:
        return None
    if not isinstance(rec, dict):
        raise InputError("scenario.json: crop_model", type(rec).__name__, "allowed: an object")
    file = _get(rec, "file", str, "crop_model.file")
    parts = PurePosixPath(file).parts
    if len(parts) < 2 or parts[0] != "models" or any(q in ("..", ".") for q in parts):
        raise InputError(
            "scenario.json: crop_model.file", file, "allowed: models/<file> or models/<name>/<path>"
        )
    path = _member(d, file, MAX_MODEL_BYTES)
    digest = _get(rec, "sha256", str, "crop_model.sha256")
    if sha256_file(path) != digest:
        raise InputError(file, str(path), "does not match its SHA-256 in scenario.json")
    size = _numbers({"native_size": rec.get("native_size")}, "native_size", 3)
    mesh = str(_get(rec, "mesh", str, "crop_model.mesh"))
    files = _model_files(d, rec, parts, mesh)
    scale = rec.get("model_scale", "stage")
    if scale not in SCALE_RULES:
        raise InputError(
            "scenario.json: crop_model.model_scale", scale, f"allowed: {list(SCALE_RULES)}"
        )
    up = rec.get("model_up_axis", "auto")
    if up not in UP_AXES:
        raise InputError("scenario.json: crop_model.model_up_axis", up, f"allowed: {list(UP_AXES)}")
    return UserModel(
        path.resolve(),
        PurePosixPath(mesh).name if len(parts) > 2 else parts[1],
        digest,
        mesh,
        (float(size[0]), float(size[1]), float(size[2])),
        str(_get(rec, "source", str, "crop_model.source")),
        files,
        parts[1] if len(parts) > 2 else None,
        scale,
        _proxy_shape(rec.get("proxy")),
        up,
    )


def _model_files(
    d: Path, rec: dict[str, Any], parts: tuple[str, ...], mesh: str
) -> tuple[tuple[str, str], ...]:
    """The files a bundled model references (models/<name>/...), each present and unchanged."""
    items = rec.get("files", [])
    if len(parts) == 2:
        if items:
            raise InputError(
                "scenario.json: crop_model.files", items, "allowed: none for models/<file>"
            )
        return ()
    if "/".join(parts[2:]) != mesh:
        raise InputError("scenario.json: crop_model.mesh", mesh, f"allowed: {'/'.join(parts[2:])}")
    if not isinstance(items, list) or len(items) > MAX_MODEL_FILES:
        raise InputError(
            "scenario.json: crop_model.files", type(items).__name__,
            f"allowed: a list of at most {MAX_MODEL_FILES} {{path, sha256}} objects",
        )  # fmt: skip
    out = []
    for item in items:
        if not isinstance(item, dict):
            raise InputError("scenario.json: crop_model.files", item, "allowed: {path, sha256}")
        rel = _get(item, "path", str, "crop_model.files[].path")
        q = PurePosixPath(rel)
        if q.is_absolute() or not q.parts or any(x in ("..", ".") for x in q.parts):
            raise InputError(
                "scenario.json: crop_model.files[].path", rel, "allowed: a path in the bundle"
            )
        name = "/".join(parts[:2]) + "/" + rel
        member = _member(d, name, MAX_MODEL_BYTES)
        digest = _get(item, "sha256", str, "crop_model.files[].sha256")
        if sha256_file(member) != digest:
            raise InputError(name, str(member), "does not match its SHA-256 in scenario.json")
        out.append((rel, digest))
    return tuple(out)


def _proxy_shape(rec: Any) -> ProxyShape | None:
    if rec is None:
        return None  # scenarios saved before the shape was recorded: computed on use
    keys = ("core", "base", "reach_x", "reach_y")
    if not isinstance(rec, dict) or set(rec) != set(keys):
        raise InputError("scenario.json: crop_model.proxy", rec, f"allowed: an object of {keys}")
    vals = [rec[k] for k in keys]
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals) or not all(
        0.0 <= float(v) <= 100.0 for v in vals
    ):
        raise InputError("scenario.json: crop_model.proxy", rec, "allowed: numbers in [0, 100]")
    return ProxyShape(*(float(v) for v in vals))


# ----------------------------------------------------------------------------- terrain.npz
def _terrain(path: Path, meta: dict[str, Any]) -> Terrain:
    name = path.name
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = {"heights", "x0", "y0", "spacing", "lod"} - set(z.files)
            if missing:
                raise InputError(f"{name}: {sorted(missing)[0]}", None, "is missing")
            _check_npy_shape(path, "heights.npy")
            heights, x0, y0 = z["heights"], z["x0"], z["y0"]
            spacing, lod = z["spacing"], z["lod"]
    except InputError:
        raise
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError, KeyError) as exc:
        raise InputError(name, str(path), f"is not a readable npz ({exc}); truncated?") from None
    if heights.ndim != 2 or min(heights.shape) < 2 or heights.dtype.kind not in "fi":
        raise InputError(
            f"{name}: heights", f"{heights.dtype} {heights.shape}", "allowed: a 2-D grid >= 2x2"
        )
    if not np.isfinite(heights).all():
        raise InputError(f"{name}: heights", "NaN or inf", "allowed: finite heights")
    scalars = {}
    for key, v in (("x0", x0), ("y0", y0), ("spacing", spacing), ("lod", lod)):
        if v.shape != () or v.dtype.kind not in "fi" or not np.isfinite(v):
            raise InputError(f"{name}: {key}", repr(v)[:40], "allowed: one finite number")
        scalars[key] = float(v)
    if not MIN_GROUND_SPACING <= scalars["spacing"] <= MAX_GROUND_SPACING:
        raise InputError(
            f"{name}: spacing",
            scalars["spacing"],
            f"allowed: a grid spacing of {MIN_GROUND_SPACING} to {MAX_GROUND_SPACING:g} m",
        )
    for key in ("x0", "y0"):
        if abs(scalars[key]) > MAX_ENU_OFFSET_M:
            raise InputError(
                f"{name}: {key}",
                scalars[key],
                f"allowed: within {MAX_ENU_OFFSET_M:,.0f} m of the datum",
            )
    if np.abs(heights).max() > MAX_ENU_HEIGHT_M:
        raise InputError(
            f"{name}: heights",
            float(np.abs(heights).max()),
            f"allowed: within {MAX_ENU_HEIGHT_M:,.0f} m of the datum's height",
        )
    lod_v = scalars["lod"]
    if lod_v != int(lod_v) or not -1 <= lod_v <= 22:
        raise InputError(f"{name}: lod", lod_v, "allowed: an integer -1 (none) .. 22")
    t = meta.get("terrain")
    if isinstance(t, dict) and t.get("shape") != list(heights.shape):
        raise InputError(
            f"{name}: heights",
            list(heights.shape),
            f"does not match scenario.json terrain.shape {t.get('shape')}",
        )
    return Terrain(
        heights.astype(np.float64),
        scalars["x0"],
        scalars["y0"],
        scalars["spacing"],
        None if lod_v < 0 else int(lod_v),
    )


def _check_npy_shape(path: Path, member: str) -> None:
    """Refuse an array bigger than the terrain bound from its header, before reading it."""
    with zipfile.ZipFile(path) as zf, zf.open(member) as f:
        version = np.lib.format.read_magic(f)
        header = (
            np.lib.format.read_array_header_1_0(f)
            if version == (1, 0)
            else np.lib.format.read_array_header_2_0(f)
        )
    shape = header[0]
    if math.prod(shape) > MAX_TERRAIN_SAMPLES:
        raise InputError(
            f"{path.name}: heights",
            shape,
            f"allowed: at most {MAX_TERRAIN_SAMPLES:,} samples",
        )


# ----------------------------------------------------------------------------- CSV files
def _csv(path: Path, headers: list[list[str]]) -> tuple[list[str], dict[str, np.ndarray]]:
    """Columns of a CSV file whose header is one of ``headers``; every line checked."""
    try:
        with open(path, newline="", encoding="utf-8") as f:
            reader = csv.reader(f)
            head = next(reader, None)
            if head not in headers:
                raise InputError(
                    f"{path.name}: header",
                    head,
                    f"allowed: {' or '.join(','.join(h) for h in headers)}",
                )
            assert head is not None
            rows = list(reader)
    except (UnicodeDecodeError, csv.Error) as exc:
        raise InputError(path.name, str(path), f"is not a readable CSV file ({exc})") from None
    for i, r in enumerate(rows):
        if len(r) != len(head):
            raise InputError(
                f"{path.name}: line {i + 2}",
                f"{len(r)} fields",
                f"allowed: {len(head)} fields ({','.join(head)}); truncated?",
            )
    cols = (
        [np.asarray(c) for c in zip(*rows, strict=True)]
        if rows
        else [np.empty(0, str) for _ in head]
    )
    return head, dict(zip(head, cols, strict=True))


def _floats(path: Path, c: dict[str, np.ndarray], key: str) -> np.ndarray:
    col = c[key]
    try:
        out = col.astype(np.float64)
    except ValueError:
        out = np.array([_float_or_nan(v) for v in col], dtype=np.float64)
    _refuse_first(path, ~np.isfinite(out), key, col, "allowed: a finite number")
    return out


def _refuse_first(
    path: Path, bad: np.ndarray, column: str, values: np.ndarray, allowed: str
) -> None:
    """Refuse the file at its first ``bad`` line, naming the line, the column, the line's
    value there and what is allowed."""
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"{path.name}: line {i + 2}, column {column}", str(values[i]), allowed)


def _float_or_nan(v: str) -> float:
    try:
        return float(v)
    except ValueError:
        return math.nan


def _counted(meta: dict[str, Any], plants: Plants, waypoints: int) -> None:
    """The CSVs hold as many lines as scenario.json counted: a file cut at a line's end (a
    copy that stopped, a hand edit) parses cleanly, and would load as a smaller field."""
    counts = meta.get("counts")
    if not isinstance(counts, dict):
        return
    crops = int((~plants.is_weed).sum())
    for name, got, want in (
        ("plants.csv", (crops, len(plants) - crops), (counts.get("plants"), counts.get("weeds"))),
        ("route.csv", (waypoints,), (counts.get("route_waypoints"),)),
    ):
        if all(isinstance(w, int) for w in want) and tuple(want) != got:
            raise InputError(
                name,
                f"{sum(got)} lines",
                f"scenario.json counts {sum(w for w in want if isinstance(w, int))}; allowed: "
                "the file as saved (truncated or edited?)",
            )


def _plants(path: Path, rows: RowFrame, version: int) -> Plants:
    head, c = _csv(path, [PLANT_HEADER_V1] if version < 2 else [PLANT_HEADER])
    if len(c["x"]) > MAX_PLANTS:
        raise InputError(path.name, f"{len(c['x']):,} plants", f"allowed: at most {MAX_PLANTS:,}")
    f = {k: _floats(path, c, k) for k in ("x", "y", "z", "roll", "pitch", "yaw", "height", "stage")}
    species = c["species"].astype(str)
    unknown = ~np.isin(species, list(CATALOG))
    _refuse_first(path, unknown, "species", species, f"allowed: one of {', '.join(CATALOG)}")
    stages = np.array([CATALOG[s].stages for s in species], dtype=np.float64)
    bad = (
        (f["height"] <= 0)
        | (f["height"] > MAX_PLANT_HEIGHT_M)
        | (f["stage"] < 1)
        | (f["stage"] > stages)
    )
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(
            f"{path.name}: line {i + 2}",
            f"height {f['height'][i]}, stage {f['stage'][i]}",
            f"allowed: height in (0, {MAX_PLANT_HEIGHT_M:g}] m and stage 1..{int(stages[i])} "
            f"for {species[i]}",
        )
    weed = species == WEED_SPECIES
    if "row" in head:
        row = _floats(path, c, "row")
        bad = (row != np.round(row)) | (row < -1) | (row >= len(rows.offsets)) | ((row < 0) != weed)
        allowed = f"allowed: 0..{len(rows.offsets) - 1} for a crop, -1 for a weed"
        _refuse_first(path, bad, "row", c["row"], allowed)
        row_idx = row.astype(np.int64)
    else:  # format 1: jitter within half a row spacing makes the nearest row exact
        _, s = rows.to_rows(f["x"], f["y"])
        row_idx = np.where(weed, -1, _nearest(s, rows.offsets)).astype(np.int64)
    return Plants(
        f["x"],
        f["y"],
        f["z"],
        f["roll"],
        f["pitch"],
        f["yaw"],
        f["height"],
        species,
        f["stage"],
        row_idx,
    )


#: m: no obstacle is larger than this in any direction (a boulder; a fallen stalk of the
#: tallest plant)
MAX_OBSTACLE_SIZE_M = MAX_PLANT_HEIGHT_M


def _obstacles(path: Path) -> Obstacles:
    _, c = _csv(path, [OBSTACLE_HEADER])
    n = len(c["x"])
    if n > MAX_OBSTACLES:
        raise InputError(path.name, f"{n:,} obstacles", f"allowed: at most {MAX_OBSTACLES:,}")
    keys = ("x", "y", "z", "roll", "pitch", "yaw", "length", "width", "height", "shape")
    f = {k: _floats(path, c, k) for k in keys}
    kind = c["kind"].astype(str)
    unknown = ~np.isin(kind, OBSTACLE_KINDS)
    _refuse_first(path, unknown, "kind", kind, f"allowed: one of {', '.join(OBSTACLE_KINDS)}")
    for k in ("length", "width", "height"):
        bad = (f[k] <= 0) | (f[k] > MAX_OBSTACLE_SIZE_M)
        _refuse_first(path, bad, k, c[k], f"allowed: a size in (0, {MAX_OBSTACLE_SIZE_M:g}] m")
    for k in ("roll", "pitch", "yaw"):
        _refuse_first(path, np.abs(f[k]) > 2 * math.pi, k, c[k], "allowed: radians within ±2π")
    shape = f["shape"]
    bad = (shape != np.round(shape)) | (shape < 0) | (shape >= 2**31)
    _refuse_first(path, bad, "shape", c["shape"], "allowed: an integer in [0, 2**31)")
    return Obstacles(
        kind=kind.astype("<U6"),
        x=f["x"],
        y=f["y"],
        z=f["z"],
        roll=f["roll"],
        pitch=f["pitch"],
        yaw=f["yaw"],
        length=f["length"],
        width=f["width"],
        height=f["height"],
        shape=shape.astype(np.int64),
    )


def _nearest(values: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Index of the nearest of the ascending ``grid`` values (the lower one on a tie)."""
    if len(grid) < 2:
        return np.zeros(len(values), np.int64)
    i = np.clip(np.searchsorted(grid, values), 1, len(grid) - 1)
    near_left = values - grid[i - 1] <= grid[i] - values
    return np.where(near_left, i - 1, i).astype(np.int64)


def _route(path: Path, rows: RowFrame, version: int) -> Route:
    _, c = _csv(path, [ROUTE_HEADER_V2] if version < 3 else [ROUTE_HEADER])
    n = len(c["x"])
    if n > MAX_ROUTE_WAYPOINTS:
        raise InputError(path.name, f"{n:,} waypoints", f"allowed: at most {MAX_ROUTE_WAYPOINTS:,}")
    if n < 2:
        raise InputError(path.name, f"{n} waypoint(s)", "allowed: a route of at least 2")
    xyz = np.column_stack([_floats(path, c, k) for k in ("x", "y", "z")])
    segment = c["segment"].astype(str)
    bad = ~np.isin(segment, SEGMENTS)
    _refuse_first(path, bad, "segment", segment, f"allowed: one of {', '.join(SEGMENTS)}")
    turn, direction = np.full(n, "", "<U11"), np.ones(n, np.int8)
    if version >= 3:
        turn = c["turn"].astype(str)
        bad = ~np.isin(turn, TURN_TAGS)
        allowed = f"allowed: empty or one of {', '.join(TURN_TAGS[1:])}"
        _refuse_first(path, bad, "turn", turn, allowed)
        d = c["direction"].astype(str)
        _refuse_first(path, ~np.isin(d, ("1", "-1")), "direction", d, "allowed: 1 or -1")
        direction = d.astype(np.int8)
    lanes = 0.5 * (rows.offsets[:-1] + rows.offsets[1:])
    _, s = rows.to_rows(xyz[:, 0], xyz[:, 1])
    lane = _nearest(s, lanes) if len(lanes) else np.full(n, -1, np.int64)
    return Route(
        xyz, segment, np.where(segment == "furrow", lane, -1).astype(np.int64), turn, direction
    )
