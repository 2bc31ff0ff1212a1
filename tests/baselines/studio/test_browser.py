"""End to end in a real browser: draw, tune, generate, compare with the CLI, run, bad input.

One studio server and one Chromium page for the whole story (≈30-40 s on 2 cores): starting
either costs more than every step together.
"""

from __future__ import annotations

import json
import shlex
import statistics
import subprocess
import sys
from pathlib import Path

import pytest

from .browser import (
    ROOT,
    browser_page,
    counts,
    draw_polygon,
    field,
    field_text,
    open_section,
    outside_localhost,
    overlapping_hints,
    plants,
    require_browser,
    set_number,
    shot,
    shown,
    studio_server,
    wait_field,
    wait_for,
    wait_shown,
)

pytestmark = pytest.mark.browser

#: A pentagon over the middle of the map (fractions of its width and height).
PENTAGON = [(0.2, 0.2), (0.8, 0.15), (0.85, 0.8), (0.5, 0.88), (0.15, 0.75)]
BOWTIE = [(0.3, 0.3), (0.6, 0.6), (0.6, 0.3), (0.3, 0.6)]


def _cli(command: str, out: Path, cwd: Path) -> None:
    argv = shlex.split(command)
    assert argv[:2] == ["agrinav", "scenario"]
    i = argv.index("--out")
    argv[i + 1] = str(out)
    env_path = str(ROOT / "src")
    subprocess.run(
        [sys.executable, "-m", "baselines.cli", *argv[1:]],
        cwd=cwd,
        check=True,
        capture_output=True,
        env={"PYTHONPATH": env_path, "MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin"},
    )


def test_studio_end_to_end(tmp_path: Path) -> None:
    require_browser()
    requests: list[str] = []
    work = tmp_path / "work"  # the studio's workspace and outputs; screenshots stay outside
    work.mkdir()
    with studio_server(work) as url, browser_page(requests) as page:
        page.goto(url)
        page.wait_for_function("window.studio && window.studio.shown > 0")
        preset_count = plants(page)
        assert preset_count > 100
        # the terrain layers are images from this server, the readout follows the cursor
        page.wait_for_function("Object.keys(window.studio.overlays).length >= 2")
        box = page.locator(".leaflet-container").first.bounding_box()
        page.mouse.move(box["x"] + 0.5 * box["width"], box["y"] + 0.5 * box["height"])
        page.wait_for_function("/elevation \\d+\\.\\d+ m/.test(document.body.innerText)")
        shot(page, tmp_path, "start")

        # draw a field: the preview switches from the preset's rectangle to the polygon
        before = shown(page)
        draw_polygon(page, PENTAGON)
        wait_shown(page, before)
        drawn_count = plants(page)
        assert drawn_count != preset_count and drawn_count > 100
        shot(page, tmp_path, "drawn")

        # row spacing 1 -> 1.5 m: fewer plants, redrawn live; several changes timed
        for value in ("1.25", "1.5"):
            before = shown(page)
            set_number(page, "layout.row_spacing", value)
            wait_shown(page, before)
        wide_count = plants(page)
        assert wide_count < drawn_count
        ratio = drawn_count / wide_count
        assert 1.3 < ratio < 1.7, counts(page)  # rows scale with 1/spacing (edges aside)
        lat = page.evaluate("window.studio.latencies")
        assert len(lat) >= 3
        print(f"redraw latency ms: {[round(x) for x in lat]}, median {statistics.median(lat):.0f}")
        open_section(page, "route")
        # long hints (row_geometry's, turn's) wrap and push the next field down
        assert overlapping_hints(page) == []
        set_number(page, "route.lanes", "1")
        page.wait_for_timeout(300)

        # the output folder follows the scenario's name until a folder is typed
        out_value = "document.querySelector('[data-key=\"out\"]').value"
        field(page, "name").fill("north-plot")
        page.wait_for_function(f"{out_value} === {json.dumps(str(work / 'north-plot'))}")

        # out-of-range spacing: the error sits under that field and nothing is written
        set_number(page, "layout.row_spacing", "0.01")
        wait_field(page, "layout.row_spacing", "got 0.01")
        assert "allowed: a number in [0.05, 50]" in field_text(page, "layout.row_spacing")
        out = work / "scn"
        field(page, "out").fill(str(out))
        field(page, "name").fill("south-plot")
        page.wait_for_function(
            "document.querySelector('[data-key=\"command\"]').innerText.includes('south-plot')"
        )
        assert page.evaluate(out_value) == str(out)  # the folder typed stays
        field(page, "generate").click()
        page.wait_for_function("document.body.innerText.includes('nothing was written')")
        shot(page, tmp_path, "bad-spacing")
        assert not out.exists() and not Path(str(out) + ".field.geojson").exists()
        set_number(page, "layout.row_spacing", "1.5")
        wait_field(page, "layout.row_spacing", "got 0.01", present=False)

        # generate and save; the CLI's command, copied from the page, makes the same bytes
        field(page, "generate").click()
        page.wait_for_function("document.body.innerText.includes('saved ')", timeout=60_000)
        assert (out / "scenario.json").is_file()
        command = field(page, "command").locator("code").first.inner_text().strip()
        assert "--field" in command and "layout.row_spacing=1.5" in command
        _cli(command, work / "cli", work)
        for name in ("scenario.json", "plants.csv", "route.csv", "field.geojson"):
            assert (out / name).read_bytes() == (work / "cli" / name).read_bytes(), name
        saved = json.loads((out / "scenario.json").read_text())
        assert saved["counts"]["plants"] == wide_count
        shot(page, tmp_path, "generated")

        # run a policy on the saved scenario: trajectory figure and metrics; the field's edits
        # below are made after it
        field(page, "run").click()
        page.wait_for_selector('[data-key="trajectory"] img', timeout=90_000)
        field(page, "trajectory").scroll_into_view_if_needed()
        page.wait_for_function(  # the figure is served by the studio and decoded
            "(() => { const i = document.querySelector('[data-key=\"trajectory\"] img');"
            " return i && i.complete && i.naturalWidth > 500; })()"
        )
        metrics = field(page, "metrics").inner_text()
        assert "rmse" in metrics and "completion" in metrics
        assert (Path(str(out) + "-run-rpp") / "metrics.json").is_file()
        shot(page, tmp_path, "run")

        # a self-intersecting polygon: the error is shown at the field, generation refused
        before_files = sorted(p.name for p in work.iterdir())
        draw_polygon(page, BOWTIE)
        # room for a loaded 2-core CI machine (the whole test takes ≈ 30 s alone)
        wait_for(
            page,
            "document.querySelector('[data-error=\"field\"]').innerText.includes('Self-intersection')",
            work,
            timeout=90_000,
        )
        field(page, "out").fill(str(work / "bowtie"))
        field(page, "generate").click()
        page.wait_for_function("document.body.innerText.includes('nothing was written')")
        page.locator('[data-error="field"]').scroll_into_view_if_needed()
        shot(page, tmp_path, "self-intersection")
        assert sorted(p.name for p in work.iterdir()) == before_files

        # a GeoJSON field off the DEM: refused at the field, in the generator's words
        far = tmp_path / "far.geojson"  # outside the workspace
        ring = [[10.0, 50.0], [10.001, 50.0], [10.001, 50.001], [10.0, 50.001], [10.0, 50.0]]
        far.write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
        field(page, "upload-geojson").locator("input[type=file]").set_input_files(str(far))
        page.wait_for_function(
            "document.querySelector('[data-error=\"field\"]').innerText.includes('off the DEM')"
        )
        shot(page, tmp_path, "off-terrain")

        # a file the model upload does not take is refused by the browser: said where the
        # upload's own errors go, not passed over in silence
        fbx = tmp_path / "plant.fbx"
        fbx.write_bytes(b"Kaydara FBX Binary  \x00")
        field(page, "upload-model").locator("input[type=file]").set_input_files(str(fbx))
        page.wait_for_function(
            "document.querySelector('[data-key=\"crop.model\"]')"
            ".closest('.q-field').textContent.includes('allowed: .glb')"
        )
    leaked = outside_localhost(requests, url)
    assert requests and not leaked, leaked
