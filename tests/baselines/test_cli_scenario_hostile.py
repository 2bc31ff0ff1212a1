"""`agrinav scenario` against hostile input: exit 2, one line, no traceback, nothing
written. Most cases run in-process (cheap); the memory cases run in a subprocess whose address
space is capped, so a bound that failed to hold would end in MemoryError, not a slow pass."""

import json
import os
import resource
import subprocess
import sys
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

from baselines.cli import main

D = 1 / 1200
WEST, NORTH = -84.2, 36.6
SITE = ["--set", "terrain.site=latlon", "--set", f"terrain.lat={NORTH - 30.5 * D}"]
SITE += ["--set", f"terrain.lon={WEST + 30.5 * D}"]
SMALL = ["--set", "field.width=10", "--set", "field.length=14", "--set", "layout.headland=2"]


def _tif(path: Path, elev: np.ndarray, crs: str, transform, nodata=None) -> Path:
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        height=elev.shape[0],
        width=elev.shape[1],
        count=1,
        dtype="float32",
        crs=crs,
        transform=transform,
        nodata=nodata,
    ) as ds:
        ds.write(elev.astype("float32"), 1)
    return path


def _slope() -> np.ndarray:
    gx, gy = np.meshgrid(np.arange(60), np.arange(60))
    return 300 + 0.5 * gx + 0.2 * gy


def _deep_geojson(d: Path) -> list[str]:
    p = d / "deep.geojson"
    p.write_text('{"type": "GeometryCollection", "geometries": [' * 10_000 + "]}" * 10_000)
    return ["--field", str(p)]


def _deep_geojson_lists(d: Path) -> list[str]:
    p = d / "deep2.geojson"
    p.write_text('{"type": "Polygon", "coordinates": ' + "[" * 10_000 + "]" * 10_000 + "}")
    return ["--field", str(p)]


def _mislabelled_dem(d: Path) -> list[str]:
    path = _tif(d / "mislabelled.tif", _slope(), "EPSG:32616", from_origin(WEST, NORTH, D, D))
    return ["--dem", str(path), *SITE]


def _absurd_dem(d: Path) -> list[str]:
    elev = _slope()
    elev[28, 33] = 20_000.0
    path = _tif(d / "absurd.tif", elev, "EPSG:4326", from_origin(WEST, NORTH, D, D), -9999)
    return ["--dem", str(path), *SITE]


def _binary_config(d: Path) -> list[str]:
    p = d / "config.yaml"
    p.write_bytes(bytes(range(256)) * 4)
    return ["--config", str(p)]


def _billion_laughs(d: Path) -> list[str]:
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, 10):
        prev, cur = chr(ord("a") + i - 1), chr(ord("a") + i)
        lines.append(f"{cur}: &{cur} [{', '.join([f'*{prev}'] * 9)}]")
    p = d / "laughs.yaml"
    p.write_text("\n".join(lines) + "\n")
    return ["--config", str(p)]


def _two_mesh_zip(d: Path) -> list[str]:
    p = d / "two.zip"
    with zipfile.ZipFile(p, "w") as zf:
        zf.writestr("a.obj", "v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n")
        zf.writestr("b.stl", "solid x\nendsolid x\n")
    return ["--set", f"crop.model={p}"]


def _far_plane(d: Path) -> list[str]:
    p = d / "iowa.geojson"
    lat, lon, dd = 42.03, -93.6, 0.0002
    ring = [[lon, lat], [lon + dd, lat], [lon + dd, lat + dd], [lon, lat + dd], [lon, lat]]
    p.write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    return ["--set", "terrain.source=plane", "--field", str(p), "--datum", "42.6,-5.57,830"]


def _existing_file(d: Path) -> list[str]:
    (d.parent / "work" / "out").write_text("mine")
    return ["--force"]


def _under_a_file(d: Path) -> list[str]:
    (d.parent / "work" / "blocker").write_text("mine")
    return []


def _file(d: Path, name: str, text: str, flag: str) -> list[str]:
    (d / name).write_text(text)
    return [flag, str(d / name)]


HUGE = "9" * 5000  # more digits than Python converts to an int


def _dup_geojson(d: Path) -> list[str]:
    ring = "[[-84.14, 36.55], [-84.139, 36.55], [-84.139, 36.551], [-84.14, 36.55]]"
    text = f'{{"type": "Polygon", "type": "Point", "coordinates": [{ring}]}}'
    return _file(d, "dup.geojson", text, "--field")


Case = tuple[str, Callable[[Path], list[str]], str, str]
CASES: list[Case] = [
    ("geojson 10,000 deep", _deep_geojson, "out", "field.geojson"),
    ("geojson coordinates 10,000 deep", _deep_geojson_lists, "out", "field.geojson"),
    ("dem crs mislabelled", _mislabelled_dem, "out", "terrain.path"),
    ("dem absurd values", _absurd_dem, "out", "terrain.path"),
    ("binary config", _binary_config, "out", "--config"),
    ("billion laughs", _billion_laughs, "out", "aliases"),
    (
        "billion laughs in --set",
        lambda d: ["--set", "layout=[&a [1,1], *a, *a]"],
        "out",
        "aliases",
    ),
    ("out is a file", _existing_file, "out", "exists and is not a directory"),
    ("out under a file", _under_a_file, "blocker/out", "is not a directory"),
    ("datum on embedded", lambda d: ["--datum", "36.5,-84.1,300"], "out", "terrain.datum"),
    (
        "set datum on embedded",
        lambda d: ["--set", "terrain.datum=[36.5, -84.1, 300]"],
        "out",
        "terrain.datum",
    ),
    ("plane far from datum", _far_plane, "out", "terrain.datum"),
    (
        "jitter over the spacing",
        lambda d: ["--set", "layout.jitter_lateral=0.5"],
        "out",
        "layout.jitter_lateral",
    ),
    ("zip with two meshes", _two_mesh_zip, "out", "crop.model"),
    ("lod 12", lambda d: ["--lod", "12"], "out", "terrain.lod"),
    ("lod 3", lambda d: ["--lod", "3"], "out", "terrain.lod"),
    ("rows that do not fit", lambda d: ["--set", "layout.rows=500"], "out", "layout.rows"),
    (
        "seed overflow in a bank",
        lambda d: ["--seed", str(2**63 - 1), "--count", "2"],
        "out",
        "--seed/--count",
    ),
    ("bank with bad input", lambda d: ["--count", "3", "--lod", "12"], "out", "terrain.lod"),
    ("huge integer in --set", lambda d: ["--set", f"layout.rows={HUGE}"], "out", "4300 digits"),
    (
        "an empty --datum",
        lambda d: ["--set", "terrain.source=plane", "--datum", ""],
        "out",
        "--datum",
    ),
    (
        "altitude 1e12 m",
        lambda d: ["--set", "terrain.source=plane", "--datum", "36.5,-84.1,1e12"],
        "out",
        "alt",
    ),
    ("a name with '--' (XML comments)", lambda d: ["--set", "name=a--b"], "out", "name"),
    ("a name over two lines (YAML)", lambda d: ["--set", 'name="a\\nb: 1"'], "out", "name"),
    (
        "huge integer in a config",
        lambda d: _file(d, "c.yaml", f"layout: {{rows: {HUGE}}}\n", "--config"),
        "out",
        "4300 digits",
    ),
    (
        "duplicate key in a config",
        lambda d: _file(d, "c.yaml", "layout:\n  rows: 3\n  rows: 4\n", "--config"),
        "out",
        "duplicate key 'rows'",
    ),
    ("duplicate key in a geojson", _dup_geojson, "out", "'type' twice"),
    (
        "huge integer in a geojson",
        lambda d: _file(d, "h.geojson", f'{{"type": "Polygon", "coordinates": {HUGE}}}', "--field"),
        "out",
        "digits",
    ),
    (
        "waypoint off the terrain",
        lambda d: _file(
            d,
            "w.yaml",
            "waypoints: [{latitude: 36.55, longitude: -84.14},"
            " {latitude: 37.5, longitude: -84.14}]\n",
            "--waypoints",
        ),
        "out",
        "off the terrain",
    ),
]


@pytest.mark.parametrize("make,out,needle", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_hostile_input_exits_2_with_one_line_and_writes_nothing(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    make: Callable[[Path], list[str]],
    out: str,
    needle: str,
) -> None:
    inputs = tmp_path / "in"
    inputs.mkdir()
    work = tmp_path / "work"
    work.mkdir()
    extra = make(inputs)
    before = sorted(os.listdir(work))
    rc = main(["scenario", "--out", str(work / out), *SMALL, "--no-preview", *extra])
    err = capsys.readouterr().err
    assert rc == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], err
    assert "Traceback" not in err
    assert sorted(os.listdir(work)) == before  # nothing created, not even a lock file


def _capped(args: list[str], tmp_path: Path) -> subprocess.CompletedProcess[str]:
    """The CLI in a process that may not map more than 3 GiB."""

    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))

    return subprocess.run(
        [sys.executable, "-m", "baselines.cli", "scenario", "--out", str(tmp_path / "out"), *args],
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=cap,
        env={**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"},
    )


def _sparse_20k(d: Path) -> Path:
    path = d / "big.tif"
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        height=20_000,
        width=20_000,
        count=1,
        dtype="int16",
        crs="EPSG:32616",
        transform=from_origin(730_000, 4_060_000, 1.0, 1.0),
        nodata=-9999,
        tiled=True,
        compress="deflate",
        SPARSE_OK=True,
    ):
        pass
    return path


@pytest.mark.parametrize(
    "args,needle",
    [
        (
            [
                "--set", "terrain.source=plane", "--set", "field.width=3000",
                "--set", "field.length=2500", "--set", "layout.row_spacing=0.75",
                "--set", "layout.plant_spacing=0.25", "--lod", "14",
                "--set", "furrows.enabled=false", "--set", "furrows.roughness=0",
            ],
            "would plant about 40,000,000 plants",
        ),
        (
            ["--set", "field.width=100", "--set", "field.length=110",
             "--set", "layout.weed_density=100"],
            "layout.weed_density",
        ),
        (
            [
                "--set", "terrain.source=plane", "--set", "field.width=800",
                "--set", "field.length=700", "--set", "layout.plant_spacing=50",
                "--set", "route.lanes=1000", "--set", "route.spacing=0.005", "--lod", "14",
                "--set", "furrows.enabled=false", "--set", "furrows.roughness=0",
            ],
            "route.lanes/spacing",
        ),
        (
            ["--set", "field.width=1000", "--set", "field.length=1000",
             "--set", "layout.plant_spacing=2"],
            "terrain samples",
        ),
        ("SPARSE", "400,000,000 pixels"),
    ],
    ids=["40M plants", "weeds", "1e8 waypoints", "80M terrain samples", "20k DEM"],
)  # fmt: skip
def test_memory_bounds_hold_under_a_3gib_cap(
    tmp_path: Path, args: list[str] | str, needle: str
) -> None:
    if args == "SPARSE":
        args = ["--dem", str(_sparse_20k(tmp_path))]
    proc = _capped([*args, "--no-preview"], tmp_path)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert len(lines) == 1 and needle in lines[0], proc.stderr[-2000:]
    assert not (tmp_path / "out").exists()


def test_out_in_a_read_only_folder(tmp_path: Path) -> None:
    ro = tmp_path / "ro"
    ro.mkdir()
    mounted = False
    if os.geteuid() != 0:
        ro.chmod(0o555)
    else:  # root ignores permission bits: a read-only file system stops it
        mount = ["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(ro)]
        if subprocess.run(mount, capture_output=True).returncode != 0:
            pytest.skip("running as root and unable to mount a read-only tmpfs")
        mounted = True
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "baselines.cli", "scenario", "--out", str(ro / "scn"), *SMALL],
            capture_output=True,
            text=True,
            timeout=120,
        )
        lines = proc.stderr.strip().splitlines()
        assert proc.returncode == 2, proc.stderr[-2000:]
        assert len(lines) == 1 and "not writable" in lines[0], proc.stderr[-2000:]
        assert list(ro.iterdir()) == []
    finally:
        if mounted:
            subprocess.run(["umount", str(ro)], check=True)
