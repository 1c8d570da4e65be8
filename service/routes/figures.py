"""The paper's figures regenerated from rsfcore (via rsfplots).

``GET /v1/figures`` lists the figures (name, caption); ``GET /v1/figures/{name}`` renders
one as PNG or SVG, kept in the image cache (:mod:`service.images`).
"""

from __future__ import annotations

import json
from typing import Annotated

from fastapi import APIRouter, Query
from fastapi import Path as PathParam
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from rsfapp.adapter import numerics_version

from .. import images
from ..errors import PROBLEM
from ..images import MEDIA, QUALITIES, choice, format_query, image, image_response

__all__ = ["router"]

router = APIRouter(prefix="/v1/figures", tags=["figures"])


# ------------------------------------------------------------------ endpoints
@router.get("", summary="List the reproducible figures of the paper")
async def list_figures() -> Response:
    """Every figure of Ciardo & Viesca that shows computed results: ``name``, ``caption``
    (the paper's figure label and what the regenerated figure shows), ``label``, ``note``
    (deviations from the printed figure) and ``url``; plus the accepted formats and
    qualities of ``GET /v1/figures/{name}``."""
    figs = await run_in_threadpool(images.figure_list)
    for f in figs:
        f["url"] = f"/v1/figures/{f['name']}"
    body = {
        "figures": figs,
        "formats": list(MEDIA),
        "qualities": list(QUALITIES),
        "numerics_version": numerics_version(),
    }
    return Response(json.dumps(body), media_type="application/json")


def _unknown_figure(name: str, names: list[str]) -> Response:
    valid = "one of " + ", ".join(names)
    body = {
        "type": "about:blank",
        "title": "Not found",
        "status": 404,
        "detail": f"no figure named {name!r}; valid names: {', '.join(names)}",
        "field": "name",
        "valid": valid,
        "valid_names": names,
        "errors": [{"field": "name", "message": "unknown figure", "valid": valid}],
    }
    return Response(json.dumps(body), status_code=404, media_type=PROBLEM)


@router.get(
    "/{name}",
    summary="Regenerate one figure of the paper",
    responses={
        200: {
            "description": "The figure (PNG or SVG).",
            "content": {
                "image/png": {"schema": {"type": "string", "format": "binary"}},
                "image/svg+xml": {"schema": {"type": "string"}},
            },
        },
        404: {
            "description": "Unknown figure; the problem+json lists the valid names (`valid_names`)."
        },
        422: {"description": "Invalid format or quality (problem+json naming the field)."},
    },
)
async def get_figure(
    name: Annotated[
        str, PathParam(description="Figure name, as listed by GET /v1/figures.", max_length=200)
    ],
    format: Annotated[
        str,
        format_query(
            ("png", "svg"),
            "png",  # noqa: A002
            "PNG raster or SVG vector image.",
        ),
    ] = "png",
    quality: Annotated[
        str,
        Query(
            description="'paper' (fine grids, default) or 'draft' "
            "(coarse grids, faster). Valid range: "
            "'paper' or 'draft'.",
            json_schema_extra={"enum": list(QUALITIES)},
        ),
    ] = "paper",
) -> Response:
    """The figure regenerated from rsfcore by rsfplots (matplotlib).  The first request
    of a (name, format, quality) renders it (seconds); later ones are read from the image
    cache (header ``X-Cache: hit|miss``), keyed also by the numerics version."""
    fmt = choice(format, tuple(MEDIA), "format")
    q = choice(quality, QUALITIES, "quality")
    names = await run_in_threadpool(images.figure_names)
    if name not in names:
        return _unknown_figure(name, names)
    data, hit = await image(f"figure-{name}-{q}.{fmt}", lambda: images.figure(name, fmt, q))
    return image_response(data, fmt, hit)
