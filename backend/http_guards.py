"""HTTP guards applied to every request: cross-site request forgery (Origin / Sec-Fetch-Site on
cookie-authenticated writes) and security headers (CSP, X-Frame-Options, nosniff).

Pure ASGI middleware: websockets pass through (the browser socket checks its Origin itself)."""

from __future__ import annotations

import json
from collections.abc import Iterable
from urllib.parse import urlsplit

from starlette.datastructures import Headers
from starlette.types import ASGIApp, Message, Receive, Scope, Send

UNSAFE_METHODS = frozenset({"POST", "PUT", "PATCH", "DELETE"})

#: The built frontend is one script and one stylesheet from /assets: nothing inline is needed.
#: connect-src 'self' covers the same-origin ws:/wss: socket (CSP level 3).
CONTENT_SECURITY_POLICY = (
    "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data: blob:; "
    "media-src 'self' blob:; connect-src 'self'; font-src 'self'; object-src 'none'; "
    "base-uri 'self'; form-action 'self'; frame-ancestors 'none'"
)
#: FastAPI's own /docs and /redoc pages load their script from a CDN and start it inline.
DOCS_PATHS = ("/docs", "/redoc")
SECURITY_HEADERS = (
    (b"x-frame-options", b"DENY"),
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"same-origin"),
)


def request_origin_allowed(headers: Headers, trusted_origins: Iterable[str]) -> tuple[bool, str]:
    """Whether a browser request comes from a page of this site; (allowed, reason if not).

    Sec-Fetch-Site decides when the browser sent it; otherwise Origin must name this host (or
    a trusted origin). A request with neither is not known to come from this site."""
    site = headers.get("sec-fetch-site")
    if site is not None:
        if site in ("same-origin", "none"):
            return True, ""
        return False, f"cross-site request refused (Sec-Fetch-Site: {site})"
    origin = headers.get("origin")
    if origin is None:
        return False, "request without Origin refused: send it from the Vigil page"
    if origin in trusted_origins:
        return True, ""
    host = headers.get("host", "")
    if origin != "null" and urlsplit(origin).netloc == host and host:
        return True, ""
    return False, f"cross-site request refused (Origin: {origin})"


def _has_bearer(headers: Headers) -> bool:
    scheme, _, value = headers.get("authorization", "").partition(" ")
    return scheme.lower() == "bearer" and bool(value)


class SecurityMiddleware:
    """Refuses cookie-authenticated cross-site writes with 403; adds the security headers."""

    def __init__(self, app: ASGIApp, cookie_name: str, trusted_origins: Iterable[str]) -> None:
        self.app = app
        self.cookie_name = cookie_name
        self.trusted_origins = frozenset(trusted_origins)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = Headers(scope=scope)
        if scope["method"] in UNSAFE_METHODS and not _has_bearer(headers):
            # A bearer token is never sent by the browser on its own; the cookie is. Writes that
            # would be authenticated by the cookie must come from this site.
            cookie = f"{self.cookie_name}=" in headers.get("cookie", "")
            cross_site = headers.get("sec-fetch-site") in ("cross-site", "same-site")
            if cookie or cross_site:
                allowed, reason = request_origin_allowed(headers, self.trusted_origins)
                if not allowed:
                    await _refuse(send, reason)
                    return
        path = scope.get("path", "")
        csp = not path.startswith(DOCS_PATHS)

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                extra = list(SECURITY_HEADERS)
                if csp:
                    extra.append((b"content-security-policy", CONTENT_SECURITY_POLICY.encode()))
                message["headers"] = [*message.get("headers", []), *extra]
            await send(message)

        await self.app(scope, receive, send_with_headers)


async def _refuse(send: Send, reason: str) -> None:
    body = json.dumps({"detail": reason}).encode()
    await send(
        {
            "type": "http.response.start",
            "status": 403,
            "headers": [
                (b"content-type", b"application/json"),
                (b"content-length", str(len(body)).encode()),
                *SECURITY_HEADERS,
            ],
        }
    )
    await send({"type": "http.response.body", "body": body})
