"""Field-studio benchmarks: live-preview cost and change-to-redraw latency.

1. Server side, in one process, median of ``--repeat`` runs: one parameter change on the
   ``default`` preset (≈2,200 plants): the session update, the layout preview and its JSON,
   side by side with a full ``generate`` of the same spec — why the preview skips the terrain.
2. In Debian's Chromium (Playwright), against a real ``agrinav studio`` server: time from the
   input event of a row-spacing change to the frame after the preview is redrawn (the page
   records it: ``window.studio.latencies``), for ≈2,200 plants and for a large field that is
   drawn decimated; plus the cold start (process start to first preview drawn).

Run: ``python benchmarks/bench_studio.py [--repeat N]``. Target: change -> redrawn < 200 ms for
2,000 plants.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = "/usr/bin/chromium"
FLAGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
    "--disable-sync",
]


def server_side(repeat: int) -> None:
    from baselines.studio.preview import SiteCache, layout_preview
    from baselines.studio.session import Session
    from scenario_gen import generate

    s, sites = Session(), SiteCache()
    layout_preview(s.spec(), 0, None, sites)  # opens (and caches) the site
    t_change, t_full, n = [], [], 0
    for k in range(repeat):
        value = 1.0 if k % 2 else 0.98
        t0 = time.perf_counter()
        s.set("layout.row_spacing", value)
        pv = layout_preview(s.spec(), 0, None, sites)
        json.dumps(pv.payload())
        t_change.append(1e3 * (time.perf_counter() - t0))
        n = pv.n_plants
        t0 = time.perf_counter()
        generate(s.spec(), 0)
        t_full.append(1e3 * (time.perf_counter() - t0))
    mc, mf = statistics.median(t_change), statistics.median(t_full)
    print(
        f"server, one change, {n} plants: preview + JSON {mc:.1f} ms (median of {repeat}); "
        f"full generate {mf:.1f} ms; ratio {mf / mc:.1f}x"
    )


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def browser_side(repeat: int) -> None:
    from playwright.sync_api import sync_playwright

    port = _free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")}
    env["PYTHONPATH"] = str(ROOT / "src")
    work = Path(tempfile.mkdtemp(prefix="bench-studio-"))
    t_start = time.perf_counter()
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "baselines.cli",
            "studio",
            "--port",
            str(port),
            "--workspace",
            str(work),
        ],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    url = f"http://127.0.0.1:{port}/"
    try:
        while True:
            try:
                urllib.request.urlopen(url + "studio/static/studio.js", timeout=2).read()
                break
            except OSError:
                time.sleep(0.05)
        t_ready = time.perf_counter() - t_start
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=FLAGS)
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.goto(url)
            page.wait_for_function("window.studio && window.studio.shown > 0", timeout=60_000)
            t_page = time.perf_counter() - t_start
            print(
                f"cold start: server answers {t_ready:.2f} s, first preview drawn {t_page:.2f} s "
                "after the process started"
            )
            page.wait_for_timeout(1500)  # let the terrain layers settle
            _changes(page, "layout.row_spacing", ["0.98", "1.0"], repeat, "default field")
            _open(page, "field")
            for key, value in (("field.width", "300"), ("field.length", "400")):
                _fill(page, key, value)
            _changes(
                page, "layout.row_spacing", ["1.02", "1.04"], max(3, repeat // 3), "large field"
            )
            browser.close()
    finally:
        proc.terminate()
        proc.wait()


def _open(page: object, section: str) -> None:
    page.locator(f'[data-section="{section}"] .q-item').first.click()  # type: ignore[attr-defined]
    page.wait_for_timeout(300)  # type: ignore[attr-defined]


def _fill(page: object, key: str, value: str) -> None:
    before = page.evaluate("window.studio.shown")  # type: ignore[attr-defined]
    page.locator(f'[data-key="{key}"]').fill(value)  # type: ignore[attr-defined]
    page.wait_for_function(f"window.studio.shown > {before}", timeout=60_000)  # type: ignore[attr-defined]


def _changes(page: object, key: str, values: list[str], repeat: int, what: str) -> None:
    page.evaluate("window.studio.latencies = []; window.studio.arrivals = []")  # type: ignore[attr-defined]
    for k in range(repeat):
        _fill(page, key, values[k % len(values)])
        page.wait_for_timeout(150)  # type: ignore[attr-defined]
    lat = sorted(page.evaluate("window.studio.latencies"))  # type: ignore[attr-defined]
    arr = page.evaluate("window.studio.arrivals")  # type: ignore[attr-defined]
    counts = page.locator('[data-key="counts"]').inner_text()  # type: ignore[attr-defined]
    p90 = lat[min(len(lat) - 1, int(0.9 * len(lat)))]
    print(
        f"browser, {what}: change -> redrawn median {statistics.median(lat):.0f} ms, "
        f"p90 {p90:.0f} ms, max {lat[-1]:.0f} ms over {len(lat)} changes; the preview data "
        f"was back from the server after {statistics.median(arr):.0f} ms (median)\n"
        f"    page says: {counts}"
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=15)
    args = ap.parse_args()
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"
    )
    server_side(args.repeat)
    browser_side(args.repeat)


if __name__ == "__main__":
    main()
