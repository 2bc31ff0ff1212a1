"""Who may drive the studio: only the page it served, in the browser of the person who ran it.

A local server is reachable by every web page the user opens: a foreign page can post to it,
open its websocket, frame it, or (DNS rebinding) make its own host name resolve to 127.0.0.1
and read the answers. ``Guard`` is an ASGI middleware in front of every route (pages, static
files, uploads and NiceGUI's socket.io), and it refuses a request

- whose ``Host`` is not one this server was started on (defeats DNS rebinding),
- whose ``Origin``, when the browser sends one, is not the page's own (cross-site posts and
  websockets),
- that carries neither the per-launch token (``?token=``, in the address ``agrinav studio``
  prints) nor the cookie a tokened request sets (``SameSite=Strict``: other sites never send
  it; the page's assets and socket.io use it),
- or, for a body, that is larger than ``max_body`` bytes or does not say its length.

Answers carry ``X-Frame-Options: DENY`` and ``frame-ancestors 'none'`` so no page can frame
the studio.
"""

from __future__ import annotations

import secrets
from collections.abc import Awaitable, Callable, Iterable, MutableMapping
from typing import Any
from urllib.parse import parse_qs

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]

COOKIE = "agrinav_studio"


def cookie_name(port: int) -> str:
    """The access cookie of the studio on ``port``: browsers keep cookies per host, not per
    port, so two studios open at once would overwrite one name and lock each other out."""
    return f"{COOKIE}_{port}"


#: A crop model zip of the size the bounds allow, with room for the form's envelope.
MAX_BODY = 64 * 1024 * 1024
LOCAL_HOSTS = ("127.0.0.1", "localhost", "[::1]")
SECURITY_HEADERS = (
    (b"x-frame-options", b"DENY"),
    (b"content-security-policy", b"frame-ancestors 'none'"),
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"no-referrer"),
)


def new_token() -> str:
    return secrets.token_urlsafe(24)


def allowed_hosts(port: int, extra: Iterable[str] = ()) -> frozenset[str]:
    """``Host`` header values this server answers: the loopback names with the port."""
    names = {*LOCAL_HOSTS, *extra}
    return frozenset(f"{n}:{port}" for n in names)


def allowed_origins(port: int, extra: Iterable[str] = ()) -> list[str]:
    return sorted(f"http://{h}" for h in allowed_hosts(port, extra))


class Guard:
    """The ASGI middleware described in the module docstring."""

    def __init__(
        self,
        app: ASGIApp,
        token: str,
        hosts: frozenset[str],
        max_body: int = MAX_BODY,
        port: int | None = None,
    ) -> None:
        self.app, self.token, self.hosts, self.max_body = app, token, hosts, max_body
        self.origins = frozenset(f"http://{h}" for h in hosts)
        self.cookie = cookie_name(port) if port is not None else COOKIE

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        kind = scope["type"]
        if kind not in ("http", "websocket"):
            await self.app(scope, receive, send)  # lifespan
            return
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope["headers"]}
        query = parse_qs(scope.get("query_string", b"").decode("latin-1"))
        why = self.refusal(scope, headers, query)
        if why is not None:
            await _refuse(kind, receive, send, *why)
            return
        if kind == "websocket":
            await self.app(scope, receive, send)
            return
        extra = list(SECURITY_HEADERS)
        if _matches(query.get("token", []), self.token):
            # The tokened visit: later requests (assets, socket.io) carry the cookie instead.
            extra.append(_hdr(f"{self.cookie}={self.token}; Path=/; HttpOnly; SameSite=Strict"))
        await self.app(scope, receive, _with_headers(send, extra))

    def refusal(
        self, scope: Scope, headers: dict[str, str], query: dict[str, list[str]]
    ) -> tuple[int, str] | None:
        """(status, reason) for a request that must not reach the app, else None."""
        if headers.get("host", "").lower() not in self.hosts:
            return 403, "unknown Host: the studio answers only on the address it printed"
        origin = headers.get("origin")
        if origin is not None and origin.lower() not in self.origins:
            return 403, "cross-origin request refused"
        if not (
            _matches(query.get("token", []), self.token)
            or _matches(_cookies(headers.get("cookie", "")).get(self.cookie, []), self.token)
        ):
            return 403, "open the address `agrinav studio` printed: it carries the access token"
        if scope["type"] == "http" and scope.get("method") in ("POST", "PUT", "PATCH"):
            length = headers.get("content-length")
            if length is None or not length.isdigit():
                return 411, "a request body must state its length"
            if len(length) > 18 or int(length) > self.max_body:
                return 413, f"upload larger than {self.max_body // 2**20} MiB refused"
        return None


def _matches(values: list[str], token: str) -> bool:
    return any(secrets.compare_digest(v.encode(), token.encode()) for v in values)


def _cookies(header: str) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for part in header.split(";"):
        name, sep, value = part.strip().partition("=")
        if sep:
            out.setdefault(name, []).append(value)
    return out


def _hdr(cookie: str) -> tuple[bytes, bytes]:
    return (b"set-cookie", cookie.encode("latin-1"))


def _with_headers(send: Send, extra: list[tuple[bytes, bytes]]) -> Send:
    async def wrapped(message: Message) -> None:
        if message["type"] == "http.response.start":
            message["headers"] = [*message.get("headers", []), *extra]
        await send(message)

    return wrapped


async def _respond(send: Send, status: int, body: bytes) -> None:
    headers = [(b"content-type", b"text/plain; charset=utf-8"), *SECURITY_HEADERS]
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})


async def _refuse(kind: str, receive: Receive, send: Send, status: int, reason: str) -> None:
    if kind == "websocket":
        await receive()  # the websocket.connect event; closing before accept answers 403
        await send({"type": "websocket.close", "code": 1008, "reason": reason})
    else:
        await _respond(send, status, f"{status}: {reason}\n".encode())
