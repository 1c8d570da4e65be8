"""A small researcher's dashboard served by the API: plain HTML, CSS and vanilla JS.

``GET /`` (and ``/ui``) serves ``service/static/index.html``; its stylesheet and script
are served from ``/static/<file>``.  There is no build step: the page talks to the JSON
and PNG endpoints of ``/v1`` with ``fetch``.  Nothing here appears in the OpenAPI schema.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter
from starlette.responses import FileResponse, Response

from ..errors import ProblemError
from ..files import file_in

__all__ = ["router", "STATIC"]

router = APIRouter(include_in_schema=False)
#: Directory of the page's files (read from the source tree).
STATIC = Path(__file__).resolve().parents[1] / "static"
_TYPES = {
    ".html": "text/html; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".js": "text/javascript; charset=utf-8",
    ".svg": "image/svg+xml",
    ".png": "image/png",
    ".ico": "image/x-icon",
}


def _serve(name: str, cache: str) -> Response:
    path = file_in(STATIC, name, _TYPES)
    if path is None:
        raise ProblemError(404, "Not found", f"no static file {name[:100]!r}")
    return FileResponse(path, media_type=_TYPES[path.suffix], headers={"Cache-Control": cache})


@router.get("/")
async def index() -> Response:
    """The dashboard page."""
    return _serve("index.html", "no-cache")


@router.get("/ui")
async def ui() -> Response:
    """The dashboard page (alias of ``/``)."""
    return _serve("index.html", "no-cache")


@router.get("/static/{name}")
async def static(name: str) -> Response:
    """A file of the page (stylesheet, script, icon)."""
    return _serve(name, "no-cache")
