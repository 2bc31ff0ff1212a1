"""``load`` on damaged, edited or crafted folders: one InputError naming the file and field;
and the API's other hostile inputs (a one-point route, ``save`` under a file)."""

import io
import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from scenario_gen import InputError, generate, load, save
from scenario_gen.routes import Route

from .helpers import small


@pytest.fixture(scope="module")
def good(tmp_path_factory: pytest.TempPathFactory) -> Path:
    scn = generate(small(layout={"weed_density": 0.2}), seed=3)
    return save(scn, tmp_path_factory.mktemp("good") / "scn", preview=False)


def _meta(fn: Callable[[dict], None]) -> Callable[[Path], None]:
    def edit(d: Path) -> None:
        meta = json.loads((d / "scenario.json").read_text())
        fn(meta)
        (d / "scenario.json").write_text(json.dumps(meta))

    return edit


def _npz(**change: object) -> Callable[[Path], None]:
    def edit(d: Path) -> None:
        with np.load(d / "terrain.npz") as z:
            arrays = {k: z[k] for k in z.files}
        for k, v in change.items():
            if v is None:
                del arrays[k]
            else:
                arrays[k] = v
        np.savez_compressed(d / "terrain.npz", **arrays)

    return edit


def _csv_cell(name: str, line: int, column: str, value: str) -> Callable[[Path], None]:
    def edit(d: Path) -> None:
        lines = (d / name).read_text().splitlines()
        head = lines[0].split(",")
        cells = lines[line - 1].split(",")
        cells[head.index(column)] = value
        lines[line - 1] = ",".join(cells)
        (d / name).write_text("\n".join(lines) + "\n")

    return edit


def _truncate(name: str, keep: float = 0.5) -> Callable[[Path], None]:
    def edit(d: Path) -> None:
        data = (d / name).read_bytes()
        (d / name).write_bytes(data[: int(len(data) * keep)])

    return edit


def _route_lines(n: int) -> Callable[[Path], None]:
    def edit(d: Path) -> None:
        lines = (d / "route.csv").read_text().splitlines()
        (d / "route.csv").write_text("\n".join(lines[: n + 1]) + "\n")

    return edit


def _keep_lines(name: str, n: int) -> Callable[[Path], None]:
    """``name`` cut after its header and ``n`` lines, at a line's end: it parses cleanly."""

    def edit(d: Path) -> None:
        lines = (d / name).read_text().splitlines()
        (d / name).write_text("\n".join(lines[: n + 1]) + "\n")

    return edit


def _symlink_out(name: str) -> Callable[[Path], None]:
    def edit(d: Path) -> None:
        outside = d.parent / f"outside-{name}"
        shutil.move(d / name, outside)
        (d / name).symlink_to(outside)

    return edit


def _pickled_npz(d: Path) -> None:
    with np.load(d / "terrain.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["heights"] = np.array([{"evil": 1}], dtype=object)
    np.savez(d / "terrain.npz", **arrays)


def _huge_npz_header(d: Path) -> None:
    # heights.npy whose header claims 100,000 x 100,000 samples (80 GB): no data follows
    import zipfile

    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        buf, {"descr": "<f8", "fortran_order": False, "shape": (100_000, 100_000)}
    )
    with np.load(d / "terrain.npz") as z:
        arrays = {k: z[k] for k in z.files if k != "heights"}
    np.savez(d / "terrain.npz", **arrays)
    with zipfile.ZipFile(d / "terrain.npz", "a") as zf:
        zf.writestr("heights.npy", buf.getvalue())


def _huge_height(d: Path) -> None:
    with np.load(d / "terrain.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["heights"] = arrays["heights"].copy()
    arrays["heights"][0, 0] = 1e300
    np.savez_compressed(d / "terrain.npz", **arrays)


def _deep_json(d: Path) -> None:
    (d / "scenario.json").write_text("[" * 100_000 + "]" * 100_000)


CASES: list[tuple[str, Callable[[Path], None], str]] = [
    ("truncated scenario.json", _truncate("scenario.json"), "scenario.json"),
    ("scenario.json is a list", lambda d: (d / "scenario.json").write_text("[]"), "scenario.json"),
    ("scenario.json 100k deep", _deep_json, "scenario.json"),
    (
        "binary scenario.json",
        lambda d: (d / "scenario.json").write_bytes(b"\xff\xfe\0"),
        "scenario.json",
    ),
    ("no seed", _meta(lambda m: m.pop("seed")), "scenario.json: seed"),
    ("seed a string", _meta(lambda m: m.update(seed="7")), "scenario.json: seed"),
    ("format 99", _meta(lambda m: m.update(format_version=99)), "scenario.json: format_version"),
    (
        "format true",
        _meta(lambda m: m.update(format_version=True)),
        "scenario.json: format_version",
    ),
    ("no format", _meta(lambda m: m.pop("format")), "scenario.json"),
    ("other format", _meta(lambda m: m.update(format="geojson")), "scenario.json: format"),
    (
        "bad spec value",
        _meta(lambda m: m["spec"]["layout"].update(row_spacing=-1)),
        "scenario.json: spec.layout.row_spacing",
    ),
    (
        "unknown spec key",
        _meta(lambda m: m["spec"]["layout"].update(rowz=3)),
        "scenario.json: spec.layout.rowz",
    ),
    ("datum lat 200", _meta(lambda m: m["datum"].update(lat=200.0)), "scenario.json: datum.lat"),
    ("datum alt NaN", _meta(lambda m: m["datum"].update(alt="nan")), "scenario.json: datum.alt"),
    ("row spacing 0", _meta(lambda m: m["rows"].update(spacing=0)), "scenario.json: rows.spacing"),
    (
        "offsets descending",
        _meta(lambda m: m["rows"].update(offsets=m["rows"]["offsets"][::-1])),
        "scenario.json: rows.offsets",
    ),
    (
        "starts short",
        _meta(lambda m: m["rows"].update(starts=m["rows"]["starts"][:-1])),
        "scenario.json: rows.starts",
    ),
    (
        "segment row out of range",
        _meta(lambda m: m["rows"]["segments"].append([999, 0.0, 1.0])),
        "scenario.json: rows.segments",
    ),
    (
        "field wkt garbage",
        _meta(lambda m: m.update(field_enu_wkt="POLYGON((0 0, 1")),
        "scenario.json: field_enu_wkt",
    ),
    (
        "model file escapes",
        _meta(lambda m: m.update(crop_model={"file": "models/../../etc/passwd", "sha256": "x"})),
        "scenario.json: crop_model.file",
    ),
    ("scenario.json symlink out", _symlink_out("scenario.json"), "scenario.json"),
    ("truncated terrain.npz", _truncate("terrain.npz"), "terrain.npz"),
    ("terrain.npz not a zip", lambda d: (d / "terrain.npz").write_text("hello"), "terrain.npz"),
    ("zero grid spacing", _npz(spacing=np.float64(0.0)), "terrain.npz: spacing"),
    ("NaN spacing", _npz(spacing=np.float64(np.nan)), "terrain.npz: spacing"),
    ("NaN heights", _npz(heights=np.full((5, 5), np.nan)), "terrain.npz: heights"),
    ("1-D heights", _npz(heights=np.zeros(7)), "terrain.npz: heights"),
    ("shape mismatch", _npz(heights=np.zeros((4, 4))), "terrain.npz: heights"),
    ("no lod", _npz(lod=None), "terrain.npz: lod"),
    ("lod 40", _npz(lod=np.int64(40)), "terrain.npz: lod"),
    ("pickled object heights", _pickled_npz, "terrain.npz"),
    ("huge heights header", _huge_npz_header, "terrain.npz: heights"),
    ("no plants.csv", lambda d: (d / "plants.csv").unlink(), "plants.csv"),
    ("plants.csv symlink out", _symlink_out("plants.csv"), "plants.csv"),
    ("NaN plant", _csv_cell("plants.csv", 5, "x", "nan"), "plants.csv: line 5, column x"),
    ("text in a number", _csv_cell("plants.csv", 3, "z", "abc"), "plants.csv: line 3, column z"),
    (
        "unknown species",
        _csv_cell("plants.csv", 4, "species", "banana"),
        "plants.csv: line 4, column species",
    ),
    ("stage 9", _csv_cell("plants.csv", 6, "stage", "9"), "plants.csv: line 6"),
    ("height 0", _csv_cell("plants.csv", 6, "height", "0"), "plants.csv: line 6"),
    (
        "row out of range",
        _csv_cell("plants.csv", 2, "row", "500"),
        "plants.csv: line 2, column row",
    ),
    ("row fractional", _csv_cell("plants.csv", 2, "row", "1.5"), "plants.csv: line 2, column row"),
    ("truncated plants.csv", _truncate("plants.csv", 0.61), "plants.csv: line"),
    (
        "plants.csv header",
        lambda d: (d / "plants.csv").write_text("id,x\n1,2\n"),
        "plants.csv: header",
    ),
    (
        "binary plants.csv",
        lambda d: (d / "plants.csv").write_bytes(b"\xff\xfe\x00\x01"),
        "plants.csv",
    ),
    ("plants.csv cut at a line's end", _keep_lines("plants.csv", 10), "plants.csv"),
    ("route.csv cut at a line's end", _keep_lines("route.csv", 20), "route.csv"),
    ("one-point route", _route_lines(1), "route.csv"),
    ("empty route", _route_lines(0), "route.csv"),
    (
        "bad route segment",
        _csv_cell("route.csv", 2, "segment", "lake"),
        "route.csv: line 2, column segment",
    ),
    ("inf route z", _csv_cell("route.csv", 9, "z", "inf"), "route.csv: line 9, column z"),
    # values generation never writes: accepted once, they crashed or ran for ever later
    ("grid spacing 1e-300", _npz(spacing=np.float64(1e-300)), "terrain.npz: spacing"),
    ("grid spacing 1e6", _npz(spacing=np.float64(1e6)), "terrain.npz: spacing"),
    ("origin 1e300", _npz(x0=np.float64(1e300)), "terrain.npz: x0"),
    ("a height of 1e300", _huge_height, "terrain.npz: heights"),
    ("plant 1e300 m tall", _csv_cell("plants.csv", 4, "height", "1e300"), "plants.csv: line 4"),
    ("plant at 1e15 m", _csv_cell("plants.csv", 3, "x", "1e15"), "plants.csv: line 3"),
    ("route point at 1e12 m", _csv_cell("route.csv", 5, "x", "1e12"), "route.csv: line 5"),
    (
        "a name that breaks exports",
        _meta(lambda m: m["spec"].update(name="x\nwaypoints: []")),
        "scenario.json: spec.name",
    ),
]


@pytest.mark.parametrize("edit,field", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_damaged_folder_is_refused_naming_file_and_field(
    good: Path, tmp_path: Path, edit: Callable[[Path], None], field: str
) -> None:
    d = tmp_path / "scn"
    shutil.copytree(good, d)
    edit(d)
    with pytest.raises(InputError) as info:
        load(d)
    assert info.value.field.startswith(field), (info.value.field, str(info.value))


def test_symlinks_inside_the_folder_are_fine(good: Path, tmp_path: Path) -> None:
    d = tmp_path / "scn"
    shutil.copytree(good, d)
    (d / "data").mkdir()
    shutil.move(d / "plants.csv", d / "data" / "plants.csv")
    (d / "plants.csv").symlink_to(Path("data") / "plants.csv")
    assert len(load(d).plants) == len(load(good).plants)


@pytest.mark.parametrize("n", [0, 1])
def test_a_route_needs_two_waypoints(n: int) -> None:
    with pytest.raises(InputError) as info:
        Route(np.zeros((n, 3)), np.full(n, "furrow"), np.zeros(n, np.int64))
    assert info.value.field == "route" and "at least 2 waypoints" in str(info.value)


def test_route_rejects_nan_and_unknown_tags() -> None:
    with pytest.raises(InputError, match="finite"):
        Route(np.array([[0, 0, 0], [1, np.nan, 0]]), np.full(2, "furrow"), np.zeros(2, np.int64))
    with pytest.raises(InputError, match="route.segment"):
        Route(np.zeros((2, 3)), np.array(["furrow", "lake"]), np.zeros(2, np.int64))


def test_save_under_a_file_or_onto_a_file_is_refused(good: Path, tmp_path: Path) -> None:
    scn = load(good)
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    with pytest.raises(InputError) as info:
        save(scn, blocker / "scn")
    assert info.value.field == "out" and "not a directory" in str(info.value)
    with pytest.raises(InputError, match="exists and is not a directory"):
        save(scn, blocker, overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]


def test_a_json_file_of_another_kind_is_named_as_such(tmp_path: Path) -> None:
    """A folder whose scenario.json is some other JSON: the message says what is missing,
    not "got (None, None)"."""
    d = tmp_path / "other"
    d.mkdir()
    (d / "scenario.json").write_text('{"name": "x"}')
    with pytest.raises(InputError, match="has no 'format' key; allowed: a scenario folder"):
        load(d)
