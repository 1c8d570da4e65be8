"""The paper's figures regenerated from rsfcore: the figure question's request model
(:class:`rsfapp.requests.figures.FigureRequest`) and adapter (:mod:`rsfapp.adapter.figures`),
drawn by rsfplots.

``GET /v1/figures`` lists the figures (name, caption); ``GET /v1/figures/{name}`` answers
one as PNG or SVG, or its data as JSON, kept in the image cache (:mod:`service.images`).
"""

from __future__ import annotations

import json
from typing import Annotated

from fastapi import APIRouter, Query
from fastapi import Path as PathParam
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from rsfapp.requests.figures import (
    DEFAULT_FIGURE_FORMAT,
    DEFAULT_FIGURE_QUALITY,
    FIGURE_FORMATS,
    FIGURE_QUALITIES,
    FIGURES,
    FigureRequest,
)

from .. import images
from ..errors import PROBLEM
from ..images import choice, format_query, image, image_response

__all__ = ["router"]

router = APIRouter(prefix="/v1/figures", tags=["figures"])


# ------------------------------------------------------------------ endpoints
@router.get("", summary="List the reproducible figures of the paper")
async def list_figures() -> Response:
    """Every figure of Ciardo & Viesca that shows computed results: ``name``, ``caption``
    (the paper's figure label and what the regenerated figure shows), ``label``, ``note``
    (deviations from the printed figure) and ``url``; plus the accepted formats and
    qualities of ``GET /v1/figures/{name}`` (:func:`rsfapp.adapter.figures.figure_list`,
    the same list as ``rsf figure --list --json``)."""
    from rsfapp.adapter.figures import figure_list

    body = await run_in_threadpool(figure_list)
    return Response(json.dumps(body), media_type="application/json")


def _figure_json(req: FigureRequest) -> bytes:
    from rsfapp.adapter import guard
    from rsfapp.adapter.figures import figure

    return json.dumps(guard(figure, req), allow_nan=False).encode()


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
            "description": "The figure (PNG or SVG), or the numbers it plots (JSON: the "
            "catalogue entry, the quality and the arrays, at most 400 points a curve).",
            "content": {
                "image/png": {"schema": {"type": "string", "format": "binary"}},
                "image/svg+xml": {"schema": {"type": "string"}},
                "application/json": {"schema": {"type": "object"}},
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
            FIGURE_FORMATS,
            DEFAULT_FIGURE_FORMAT,
            "PNG raster or SVG vector image, or the figure's data as JSON.",
        ),
    ] = DEFAULT_FIGURE_FORMAT,  # noqa: A002
    quality: Annotated[
        str,
        Query(
            description="'paper' (fine grids, default) or 'draft' "
            "(coarse grids, faster). Valid range: "
            "'paper' or 'draft'.",
            json_schema_extra={"enum": list(FIGURE_QUALITIES)},
        ),
    ] = DEFAULT_FIGURE_QUALITY,
) -> Response:
    """The figure's data computed from rsfcore by the figure adapter
    (:mod:`rsfapp.adapter.figures`) and drawn by rsfplots (matplotlib).  The first request
    of a (name, format, quality) computes it (seconds); later ones are read from the image
    cache (header ``X-Cache: hit|miss``), keyed also by the numerics version."""
    fmt = choice(format, FIGURE_FORMATS, "format")
    q = choice(quality, FIGURE_QUALITIES, "quality")
    if name not in FIGURES:
        return _unknown_figure(name, list(FIGURES))
    req = FigureRequest(name=name, quality=q)  # type: ignore[arg-type]
    key = f"figure-{name}-{q}.{fmt}"
    if fmt == "json":
        data, hit = await image(key, lambda: _figure_json(req))
        return Response(
            data,
            media_type="application/json",
            headers={"X-Cache": "hit" if hit else "miss", "Cache-Control": "public, max-age=3600"},
        )
    data, hit = await image(key, lambda: images.figure(req, fmt))
    return image_response(data, fmt, hit)
