"""Only the studio's own page drives it: a rebinding page, a cross-site page, a tokenless
request and an oversized upload are refused by a real server; the page writes only inside its
workspace."""

from __future__ import annotations

import http.client
import os
from pathlib import Path
from urllib.parse import urlsplit

import pytest

from baselines.studio import actions
from baselines.studio.guard import MAX_BODY, cookie_name
from baselines.studio.session import Session
from scenario_gen.errors import InputError

from .browser import studio_server


def _request(
    url: str, path: str, headers: dict[str, str], method: str = "GET", body: bytes = b""
) -> tuple[int, dict[str, str], bytes]:
    """One raw request to the server at ``url`` with exactly ``headers`` (Host included)."""
    parts = urlsplit(url)
    conn = http.client.HTTPConnection(parts.hostname, parts.port, timeout=20)
    try:
        conn.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
        for k, v in headers.items():
            conn.putheader(k, v)
        conn.endheaders(body or None)
        r = conn.getresponse()
        return r.status, {k.lower(): v for k, v in r.getheaders()}, r.read()
    finally:
        conn.close()


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> object:
    try:
        import nicegui  # noqa: F401
    except ImportError:
        if os.environ.get("CI"):
            pytest.fail("the studio tests need nicegui (.ci/run installs it)")
        pytest.skip("nicegui is not installed")
    work = tmp_path_factory.mktemp("studio")
    with studio_server(work) as url:
        yield url


def test_the_printed_address_opens_the_page_and_sets_a_strict_cookie(server: str) -> None:
    parts = urlsplit(server)
    host = f"127.0.0.1:{parts.port}"
    status, headers, body = _request(server, f"/?{parts.query}", {"Host": host})
    assert status == 200 and b"AgriNav studio" in body
    # named for the port: a second studio's cookie on 127.0.0.1 does not replace this one's
    assert f"{cookie_name(parts.port)}=" in headers["set-cookie"]
    assert "SameSite=Strict" in headers["set-cookie"]
    assert headers["x-frame-options"] == "DENY"
    assert "frame-ancestors 'none'" in headers["content-security-policy"]
    cookie = headers["set-cookie"].split(";")[0]
    status, _, _ = _request(server, "/", {"Host": f"localhost:{parts.port}", "Cookie": cookie})
    assert status == 200  # the cookie stands for the token afterwards
    value = cookie.split("=", 1)[1]
    other = f"{cookie_name(parts.port + 1)}={value}"  # the name another port's studio sets
    status, _, _ = _request(server, "/", {"Host": f"localhost:{parts.port}", "Cookie": other})
    assert status == 403


def test_a_rebinding_page_is_refused(server: str) -> None:
    """DNS rebinding: evil.example resolves to 127.0.0.1, so the browser sends its own Host
    (and, being the evil page's own origin, it may even know the path and the token)."""
    parts = urlsplit(server)
    evil = f"evil.example:{parts.port}"
    for path in (f"/?{parts.query}", "/", "/studio/static/studio.js"):
        status, headers, body = _request(server, path, {"Host": evil, "Origin": f"http://{evil}"})
        assert status == 403 and b"Host" in body, path
        assert headers["x-frame-options"] == "DENY"
    # socket.io's handshake (how the page's events reach the server) likewise
    sio = f"/_nicegui_ws/socket.io/?EIO=4&transport=polling&{parts.query}"
    assert _request(server, sio, {"Host": evil})[0] == 403


def test_a_cross_site_page_and_a_tokenless_request_are_refused(server: str) -> None:
    parts = urlsplit(server)
    host = f"127.0.0.1:{parts.port}"
    status, _, body = _request(server, "/", {"Host": host})
    assert status == 403 and b"token" in body
    wrong = f"/?token={'x' * len(parts.query)}"
    assert _request(server, wrong, {"Host": host})[0] == 403
    sio = f"/_nicegui_ws/socket.io/?EIO=4&transport=polling&{parts.query}"
    status, _, _ = _request(server, sio, {"Host": host, "Origin": "https://evil.example"})
    assert status == 403
    assert _request(server, sio, {"Host": host, "Origin": "null"})[0] == 403


def test_an_oversized_or_unsized_upload_is_refused(server: str) -> None:
    parts = urlsplit(server)
    host = f"127.0.0.1:{parts.port}"
    path = f"/_nicegui/client/x/upload/1?{parts.query}"
    huge = {"Host": host, "Content-Length": str(MAX_BODY + 1)}
    assert _request(server, path, huge, "POST")[0] == 413
    absurd = {"Host": host, "Content-Length": "9" * 5000}  # uvicorn's parser may refuse it first
    assert _request(server, path, absurd, "POST")[0] in (400, 413)
    assert _request(server, path, {"Host": host}, "POST")[0] == 411


def test_the_page_writes_only_inside_its_workspace(tmp_path: Path) -> None:
    work = tmp_path / "work"
    work.mkdir()
    s = Session(seed=1)
    for out in (str(tmp_path / "elsewhere"), str(work), str(work / ".." / "up"), "/tmp/x"):
        with pytest.raises(InputError) as e:
            actions.generate_and_save(s, out, workspace=work)
        assert e.value.field == "out"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["work"]
    (work / "link").symlink_to(tmp_path)  # a link out of the workspace is outside too
    with pytest.raises(InputError):
        actions.generate_and_save(s, str(work / "link" / "scn"), workspace=work)


def test_the_uploaded_models_folder_is_no_output_folder(tmp_path: Path) -> None:
    """A scenario saved as <workspace>/models took it over, and overwriting it deleted every
    uploaded model."""
    work = tmp_path / "work"
    (work / actions.MODELS_DIR).mkdir(parents=True)
    kept = work / actions.MODELS_DIR / "plant.obj"
    kept.write_text("v 0 0 0\n")
    s = Session(seed=1)
    for out in (work / actions.MODELS_DIR, work / actions.MODELS_DIR / "scn"):
        with pytest.raises(InputError, match="uploaded crop models"):
            actions.generate_and_save(s, str(out), overwrite=True, workspace=work)
    assert kept.read_text() == "v 0 0 0\n"
    assert sorted(p.name for p in (work / actions.MODELS_DIR).iterdir()) == ["plant.obj"]
