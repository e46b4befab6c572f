"""Labelling workspace API: videos with progress, segments, review, export/import, agreement,
RGB frames and the model lane. Thin: the work is in backend.labelling."""

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse

from backend.api.labelling import agreement, exchange, media, segments, videos
from backend.labelling.errors import LabellingError

__all__ = ["ROUTERS", "install"]

#: In this order in the OpenAPI document (as when they were one module).
ROUTERS = (videos.router, segments.router, exchange.router, agreement.router, media.router)


def install(app: FastAPI) -> None:
    """Start-up wiring: the routes, and 4xx for labelling errors (the frame cache, model lane
    and 3D viewer are services: backend.services.Labelling)."""

    @app.exception_handler(LabellingError)
    def labelling_error(request: Request, error: LabellingError) -> JSONResponse:
        return JSONResponse({**error.extra, "detail": str(error)}, status_code=error.status_code)

    for router in ROUTERS:
        app.include_router(router)
