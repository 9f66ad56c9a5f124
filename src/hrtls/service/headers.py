"""Security headers on every HTTP response (ASGI middleware).

The dashboard's Content-Security-Policy allows its own scripts, styles, images and sockets
only, plus the base map's tile server when the deployment names one; the interactive API docs
(``/api/v1/docs``, whose page loads its assets from a CDN) get the other headers only.
"""

from __future__ import annotations

from typing import Any
from urllib.parse import urlsplit

ASGIApp = Any


def content_security_policy(basemap_url: str | None) -> str:
    """The dashboard's policy; ``basemap_url``'s origin may serve images."""
    img = "'self' data: blob:"
    if basemap_url is not None:
        parts = urlsplit(basemap_url.replace("{z}", "0").replace("{x}", "0").replace("{y}", "0"))
        img += f" {parts.scheme}://{parts.netloc}"
    return ("default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
            f"img-src {img}; connect-src 'self'; font-src 'self'; object-src 'none'; "
            "base-uri 'none'; form-action 'self'; frame-ancestors 'none'")


class SecurityHeaders:
    """Add ``nosniff``, no framing, no referrer and the CSP to each response."""

    def __init__(self, app: ASGIApp, *, csp: str, docs_prefix: str) -> None:
        self.app = app
        self.docs_prefix = docs_prefix
        common = [(b"x-content-type-options", b"nosniff"), (b"x-frame-options", b"DENY"),
                  (b"referrer-policy", b"no-referrer")]
        self.with_csp = [*common, (b"content-security-policy", csp.encode())]
        self.without_csp = common

    async def __call__(self, scope: dict[str, Any], receive: Any, send: Any) -> None:
        """Pass the request on; extend the response's headers."""
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        extra = (self.without_csp if str(scope.get("path", "")).startswith(self.docs_prefix)
                 else self.with_csp)

        async def send_with_headers(message: dict[str, Any]) -> None:
            if message["type"] == "http.response.start":
                message = {**message, "headers": [*message.get("headers", []), *extra]}
            await send(message)

        await self.app(scope, receive, send_with_headers)
