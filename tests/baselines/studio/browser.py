"""Driving the studio in Debian's Chromium through Playwright: server, browser, helpers."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

CHROMIUM = "/usr/bin/chromium"
FLAGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
    "--disable-sync",
]
ROOT = Path(__file__).resolve().parents[3]


def require_browser() -> None:
    """Skip when the browser stack is missing; in CI (CI=true) that is a failure instead."""
    missing = []
    for module in ("playwright", "nicegui"):
        try:
            __import__(module)
        except ImportError:
            missing.append(f"python package {module}")
    if not Path(CHROMIUM).exists():
        missing.append(f"{CHROMIUM} (apt-get install chromium)")
    if missing:
        why = "browser tests need " + ", ".join(missing)
        if os.environ.get("CI"):
            pytest.fail(why + " (.ci/run installs them)")
        pytest.skip(why)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextmanager
def studio_server(workspace: Path, *args: str) -> Iterator[str]:
    """``agrinav studio`` in a subprocess; yields its URL, stops it afterwards."""
    port = free_port()
    # Not PYTEST_*: NiceGUI switches to its own test mode when it sees them.
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")}
    env.update({"PYTHONPATH": str(ROOT / "src"), "MPLBACKEND": "Agg"})
    log = open(workspace / "studio.log", "w")  # closed in the finally below
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "baselines.cli",
            "studio",
            "--port",
            str(port),
            "--workspace",
            str(workspace),
            *args,
        ],
        cwd=workspace,
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    base = f"http://127.0.0.1:{port}/"
    try:
        deadline = time.monotonic() + 60
        url = ""
        while True:
            if proc.poll() is not None:
                raise RuntimeError((workspace / "studio.log").read_text())
            url = url or printed_url(workspace / "studio.log")
            try:
                if url:  # the printed address carries the token; the static file needs it too
                    token = url.split("?token=")[1]
                    urllib.request.urlopen(
                        f"{base}studio/static/studio.js?token={token}", timeout=2
                    ).read()
                    break
            except OSError:
                pass
            if time.monotonic() > deadline:
                log_text = (workspace / "studio.log").read_text()
                raise RuntimeError(f"the studio did not answer: {log_text}")
            time.sleep(0.1)
        yield url
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        log.close()


#: leaflet-draw's vertex handles of the shape being drawn
VERTICES_JS = "document.querySelectorAll('.leaflet-marker-pane .leaflet-editing-icon').length"


def wait_for(page: Any, js: str, workspace: Path, timeout: float = 30_000) -> None:
    """``page.wait_for_function`` that fails with the page's and the server's state."""
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    try:
        page.wait_for_function(js, timeout=timeout)
    except PlaywrightTimeout:
        state = page.evaluate(
            f"""() => ({{
              field_error: document.querySelector('[data-error="field"]')?.innerText,
              drawn: window.studio.drawn.getLayers().length,
              vertices: {VERTICES_JS},
              counts: document.querySelector('[data-key="counts"]')?.innerText,
            }})"""
        )
        log = (workspace / "studio.log").read_text()[-3000:]
        pytest.fail(f"waited {timeout / 1000:.0f} s for {js}\npage: {state}\nstudio.log:\n{log}")


def printed_url(log: Path) -> str:
    """The address ``agrinav studio`` printed (with its access token), or ''."""
    for line in log.read_text().splitlines():
        if line.startswith("AgriNav studio on "):
            return line.split()[3]
    return ""


@contextmanager
def browser_page(requests: list[str]) -> Iterator[Any]:
    """A Chromium page that records the URL of every request it makes."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=FLAGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.on("request", lambda r: requests.append(r.url))
            page.set_default_timeout(30_000)
            yield page
        finally:
            browser.close()


def outside_localhost(urls: list[str], port_url: str) -> list[str]:
    local = ("http://127.0.0.1:", "ws://127.0.0.1:", "data:", "blob:", "about:")
    return [u for u in urls if not u.startswith(local)]


def shot(page: Any, tmp: Path, name: str) -> None:
    """Screenshot into the test's tmp dir and, with AGRINAV_SCREENSHOTS set, docs/images."""
    path = tmp / f"studio-{name}.png"
    page.screenshot(path=str(path))
    if os.environ.get("AGRINAV_SCREENSHOTS"):
        out = ROOT / "docs" / "images"
        out.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, out / path.name)


def field(page: Any, key: str) -> Any:
    """The element of a generated widget (its ``data-key`` is the dotted spec key)."""
    return page.locator(f'[data-key="{key}"]').first


def set_number(page: Any, key: str, value: str) -> None:
    field(page, key).fill(value)  # Quasar puts data-* attributes on the native <input>


def field_text(page: Any, key: str) -> str:
    """The text of a form field: label, value, hint or error message."""
    return str(
        page.evaluate(
            f"document.querySelector('[data-key=\"{key}\"]').closest('.q-field').innerText"
        )
    )


def wait_field(page: Any, key: str, text: str, present: bool = True) -> None:
    sel = f"document.querySelector('[data-key=\"{key}\"]').closest('.q-field').innerText"
    page.wait_for_function(f"{'' if present else '!'}{sel}.includes({text!r})")


def counts(page: Any) -> str:
    return str(field(page, "counts").inner_text())


def plants(page: Any) -> int:
    return int(counts(page).split(" plants")[0].replace(",", ""))


def wait_shown(page: Any, before: int) -> None:
    page.wait_for_function(f"window.studio.shown > {before}")


def shown(page: Any) -> int:
    return int(page.evaluate("window.studio.shown"))


def draw_polygon(page: Any, fractions: list[tuple[float, float]]) -> None:
    """Draw a polygon with leaflet-draw by clicking its vertices, then the first again.

    Each click waits for its vertex to appear, then for leaflet-draw's own 50 ms re-arm timer
    (``_enableNewMarkers``): a mouse-down that arrives before that timer has run is dropped
    without a trace, which a loaded machine makes possible when the timer runs late.
    """
    container = page.locator(".leaflet-container").first
    container.scroll_into_view_if_needed()
    drawn = int(page.evaluate("window.studio.drawn.getLayers().length"))
    page.locator(".leaflet-draw-draw-polygon").click()
    # measured after the button's click, which scrolls the page when the button is out of
    # view (after a policy run the page sits at the trajectory figure): a box taken before
    # it put the clicks beside the map
    box = container.bounding_box()
    pts = [(box["x"] + fx * box["width"], box["y"] + fy * box["height"]) for fx, fy in fractions]
    for i, (x, y) in enumerate(pts):
        page.mouse.click(x, y)
        page.wait_for_function(f"{VERTICES_JS} === {i + 1}")
        # a timer queued after leaflet-draw's fires after it (timers run in due-time order)
        page.evaluate("new Promise((resolve) => setTimeout(resolve, 60))")
    page.mouse.click(*pts[0])
    # the shape is created (its handles gone) and in the studio's editable group
    page.wait_for_function(
        f"{VERTICES_JS} === 0 && window.studio.drawn.getLayers().length === {drawn + 1}"
    )


#: pairs of consecutive visible form fields in one column where the first's hint runs over the
#: second (label, next label, pixels)
OVERLAPS_JS = """() => {
  const out = [];
  const fields = [...document.querySelectorAll('.q-field')].filter(f => f.offsetParent !== null);
  for (let i = 0; i + 1 < fields.length; i++) {
    const hint = fields[i].querySelector('.q-field__bottom');
    if (!hint) continue;
    const a = hint.getBoundingClientRect(), b = fields[i + 1].getBoundingClientRect();
    if (Math.abs(a.left - b.left) > 40 || b.top <= a.top) continue;
    if (a.bottom > b.top + 1) {
      const label = (f) => f.innerText.split('\\n')[0];
      out.push([label(fields[i]), label(fields[i + 1]), Math.round(a.bottom - b.top)]);
    }
  }
  return out;
}"""


def overlapping_hints(page: Any) -> list[Any]:
    return list(page.evaluate(OVERLAPS_JS))


def open_section(page: Any, section: str) -> None:
    """Expand a collapsed section of the form and wait until its slide-open has ended."""
    sel = f'[data-section="{section}"]'
    page.evaluate("(sel) => { delete document.querySelector(sel).dataset.lastHeight; }", sel)
    page.locator(f"{sel} .q-item").first.click()
    # Quasar's QSlideTransition animates the height through an inline style that it removes
    # at the end; fields below move until then, so geometry read earlier (the hint overlap
    # check) sees a half-open section
    page.wait_for_function(
        """(sel) => {
          const el = document.querySelector(sel);
          const h = el.getBoundingClientRect().height;
          const all = [...el.querySelectorAll('*')];
          const busy = all.some((e) => e.style.transition.includes('height'));
          const same = el.dataset.lastHeight === String(h);
          el.dataset.lastHeight = String(h);
          return same && !busy;
        }""",
        arg=sel,
        polling=150,
    )
