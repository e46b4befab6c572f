"""Request bodies are capped at `Settings.max_upload_bytes` at the door: a declared
Content-Length above it is refused before a byte is read, and a body without one (chunked) is
counted as it arrives and refused the moment it passes the limit. Either way the answer is a
413 naming the limit; nothing past the limit is read into the application (a 200 MB import was
read whole, RSS 264 -> 854 MB, before its 422)."""

from __future__ import annotations

from starlette.datastructures import Headers
from starlette.exceptions import HTTPException
from starlette.responses import JSONResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from backend.settings import Settings


def _limit_text(limit: int) -> str:
    return f"{limit / 2**20:g} MiB" if limit >= 2**20 else f"{limit} bytes"


class BodyTooLarge(HTTPException):
    """Raised from `receive` inside the application; an HTTPException, so FastAPI's body
    parsing passes it on and the exception handler answers 413."""

    def __init__(self, limit: int) -> None:
        super().__init__(
            413,
            f"request body larger than {_limit_text(limit)} (the limit, VIGIL_MAX_UPLOAD_BYTES)",
        )


class BodySizeLimit:
    """Pure ASGI middleware; the limit is read per request (tests change the settings)."""

    def __init__(self, app: ASGIApp, settings: Settings) -> None:
        self.app = app
        self.settings = settings

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        limit = self.settings.max_upload_bytes
        declared = Headers(scope=scope).get("content-length")
        if declared is not None and declared.isdigit() and int(declared) > limit:
            await self._refuse(scope, receive, send, BodyTooLarge(limit))
            return
        received = 0
        started = False

        async def limited_receive() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    raise BodyTooLarge(limit)
            return message

        async def tracked_send(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, limited_receive, tracked_send)
        except BodyTooLarge as error:  # raised where no exception handler answered it
            if started:
                raise
            await self._refuse(scope, receive, send, error)

    @staticmethod
    async def _refuse(scope: Scope, receive: Receive, send: Send, error: BodyTooLarge) -> None:
        response = JSONResponse({"detail": error.detail}, status_code=error.status_code)
        await response(scope, receive, send)
