"""The API documentation pages (/docs: Swagger UI, /redoc: ReDoc) served with local
assets, so they work on a lab network without internet access.

The JavaScript and CSS come from the installed ``fastapi-offline`` package (its
``static/`` directory), served under ``/docs-assets/``; nothing is fetched from a CDN.
"""

from __future__ import annotations

from pathlib import Path

import fastapi_offline
from fastapi import APIRouter
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from starlette.responses import FileResponse, HTMLResponse, Response

from ..errors import ProblemError
from ..files import file_in

__all__ = ["ASSETS", "router"]

router = APIRouter(include_in_schema=False)
#: Directory holding swagger-ui-bundle.js, swagger-ui.css, redoc.standalone.js.
ASSETS = Path(fastapi_offline.__file__).resolve().parent / "static"
_TYPES = {
    ".js": "text/javascript; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".png": "image/png",
}
_TITLE = "rsf-stability service"


@router.get("/docs")
async def swagger() -> HTMLResponse:
    """Swagger UI on /openapi.json."""
    return get_swagger_ui_html(
        openapi_url="/openapi.json",
        title=f"{_TITLE} - Swagger UI",
        swagger_js_url="/docs-assets/swagger-ui-bundle.js",
        swagger_css_url="/docs-assets/swagger-ui.css",
        swagger_favicon_url="/docs-assets/favicon.png",
    )


@router.get("/redoc")
async def redoc() -> HTMLResponse:
    """ReDoc on /openapi.json."""
    return get_redoc_html(
        openapi_url="/openapi.json",
        title=f"{_TITLE} - ReDoc",
        redoc_js_url="/docs-assets/redoc.standalone.js",
        redoc_favicon_url="/docs-assets/favicon.png",
        with_google_fonts=False,
    )


@router.get("/docs-assets/{name}")
async def asset(name: str) -> Response:
    """One local asset of the documentation pages."""
    path = file_in(ASSETS, name, _TYPES)
    if path is None:
        raise ProblemError(404, "Not found", f"no documentation asset {name[:100]!r}")
    return FileResponse(
        path, media_type=_TYPES[path.suffix], headers={"Cache-Control": "public, max-age=86400"}
    )
