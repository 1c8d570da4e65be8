"""The paper's figures regenerated from rsfcore (via rsfplots), and the image cache.

``GET /v1/figures`` lists the figures (name, caption); ``GET /v1/figures/{name}`` renders
one as PNG or SVG.  Rendering takes up to seconds, so every rendered image is kept on disk
under ``<data dir>/images/<numerics version>/`` (written atomically: a temporary file
renamed into place, so concurrent API processes never read half an image) and identical
requests arriving while it renders join the running render.  The same cache serves the
``?format=png`` plots of trajectories, U fields and finished sweeps (see :func:`image`).
"""
from __future__ import annotations

import asyncio
import json
import os
import re
import tempfile
from pathlib import Path
from typing import Annotated, Any, Callable

from fastapi import APIRouter, Query
from fastapi import Path as PathParam
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from .. import compute
from ..compute import ComputeError, numerics_version
from ..errors import PROBLEM, ProblemError
from ..settings import get_settings

__all__ = ["router", "image", "image_response", "choice", "format_query", "MEDIA",
           "png_content"]

router = APIRouter(prefix="/v1/figures", tags=["figures"])

#: Media type of each image format.
MEDIA = {"png": "image/png", "svg": "image/svg+xml"}
QUALITIES = ("paper", "draft")

#: Renders in flight in this process, by image key.
_inflight: dict[str, asyncio.Task] = {}


# ------------------------------------------------------------------ query parameters
def format_query(allowed: tuple[str, ...], default: str, what: str) -> Any:
    """A documented ``format`` query parameter (enum in OpenAPI, checked by :func:`choice`)."""
    return Query(description=f"Response format: {' or '.join(repr(a) for a in allowed)} "
                             f"(default {default!r}). {what} Valid range: "
                             f"{' or '.join(repr(a) for a in allowed)}.",
                 json_schema_extra={"enum": list(allowed), "x-valid-range":
                                    " or ".join(repr(a) for a in allowed)})


def choice(value: str, allowed: tuple[str, ...], field: str) -> str:
    """``value`` (case-insensitive) if in ``allowed``, else a 422 naming ``field``."""
    v = str(value).strip().lower()
    if v not in allowed:
        valid = " or ".join(repr(a) for a in allowed)
        raise ProblemError(422, "Invalid input", f"{field}: {value!r} is not supported "
                           f"(valid range: {valid})", field=field, valid=valid)
    return v


def png_content(description: str, extra: dict[str, Any] | None = None,
                model: Any = None) -> dict[int, Any]:
    """OpenAPI ``responses`` entry: 200 as JSON (default; ``model`` documents it) or image/png."""
    entry: dict[str, Any] = {"description": description,
                             "content": {"application/json": {}, "image/png": {
                                 "schema": {"type": "string", "format": "binary"}}}}
    if model is not None:
        entry["model"] = model
    return {200: entry, **(extra or {})}


# ------------------------------------------------------------------ on-disk image cache
def _image_dir() -> Path:
    safe = re.sub(r"[^A-Za-z0-9._-]", "_", numerics_version()) or "dev"
    d = get_settings().data_path / "images" / safe
    d.mkdir(parents=True, exist_ok=True)
    return d


def _file(key: str) -> Path:
    if not re.fullmatch(r"[A-Za-z0-9._-]{1,200}", key) or ".." in key:
        raise ValueError(f"bad image key {key!r}")
    return _image_dir() / key


def _load(key: str) -> bytes | None:
    try:
        return _file(key).read_bytes()
    except FileNotFoundError:
        return None


def _save(key: str, data: bytes) -> None:
    target = _file(key)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


async def image(key: str, make: Callable[[], bytes], *, store: bool = True) -> tuple[bytes, bool]:
    """(bytes, from_cache): the image stored under ``key`` or ``make()`` rendered now.

    ``key`` names the file (it must already include everything the image depends on;
    the numerics version is the directory).  ``store=False`` renders without keeping the
    image (partial sweeps change every second).  A plot that fails is a 422 problem.
    """
    if store:
        data = await run_in_threadpool(_load, key)
        if data is not None:
            return data, True
    task = _inflight.get(key)
    if task is None:
        async def run() -> bytes:
            try:
                out = await run_in_threadpool(make)
            except ComputeError as exc:
                raise ProblemError(422, "Could not be plotted", str(exc)) from None
            if store:
                await run_in_threadpool(_save, key, out)
            return out
        task = asyncio.ensure_future(run())
        _inflight[key] = task

        def _done(t: asyncio.Task, k: str = key) -> None:
            _inflight.pop(k, None)
            if not t.cancelled():
                t.exception()  # retrieved here: every waiter may have gone away
        task.add_done_callback(_done)
    return await asyncio.shield(task), False


def image_response(data: bytes, fmt: str, hit: bool, *, final: bool = True,
                   headers: dict[str, str] | None = None) -> Response:
    """An image response with ``X-Cache`` and cache headers."""
    h = {"X-Cache": "hit" if hit else "miss",
         "Cache-Control": "public, max-age=3600" if final else "no-store"}
    h.update(headers or {})
    return Response(data, media_type=MEDIA[fmt], headers=h)


# ------------------------------------------------------------------ endpoints
@router.get("", summary="List the reproducible figures of the paper")
async def list_figures() -> Response:
    """Every figure of Ciardo & Viesca that shows computed results: ``name``, ``caption``
    (the paper's figure label and what the regenerated figure shows), ``label``, ``note``
    (deviations from the printed figure) and ``url``; plus the accepted formats and
    qualities of ``GET /v1/figures/{name}``."""
    try:
        figs = await run_in_threadpool(compute.figure_list)
    except ComputeError as exc:  # pragma: no cover - only without rsfplots
        raise ProblemError(503, "Unavailable", str(exc)) from None
    for f in figs:
        f["url"] = f"/v1/figures/{f['name']}"
    body = {"figures": figs, "formats": list(MEDIA), "qualities": list(QUALITIES),
            "numerics_version": numerics_version()}
    return Response(json.dumps(body), media_type="application/json")


def _unknown_figure(name: str, names: list[str]) -> Response:
    valid = "one of " + ", ".join(names)
    body = {"type": "about:blank", "title": "Not found", "status": 404,
            "detail": f"no figure named {name!r}; valid names: {', '.join(names)}",
            "field": "name", "valid": valid, "valid_names": names,
            "errors": [{"field": "name", "message": "unknown figure", "valid": valid}]}
    return Response(json.dumps(body), status_code=404, media_type=PROBLEM)


@router.get("/{name}", summary="Regenerate one figure of the paper",
            responses={200: {"description": "The figure (PNG or SVG).",
                             "content": {"image/png": {"schema": {"type": "string",
                                                                  "format": "binary"}},
                                         "image/svg+xml": {"schema": {"type": "string"}}}},
                       404: {"description": "Unknown figure; the problem+json lists the "
                                            "valid names (`valid_names`)."},
                       422: {"description": "Invalid format or quality (problem+json "
                                            "naming the field)."}})
async def get_figure(
        name: Annotated[str, PathParam(description="Figure name, as listed by "
                                                   "GET /v1/figures.", max_length=200)],
        format: Annotated[str, format_query(("png", "svg"), "png",  # noqa: A002
                                            "PNG raster or SVG vector image.")] = "png",
        quality: Annotated[str, Query(description="'paper' (fine grids, default) or 'draft' "
                                                  "(coarse grids, faster). Valid range: "
                                                  "'paper' or 'draft'.",
                                      json_schema_extra={"enum": list(QUALITIES)})] = "paper",
) -> Response:
    """The figure regenerated from rsfcore by rsfplots (matplotlib).  The first request
    of a (name, format, quality) renders it (seconds); later ones are read from the image
    cache (header ``X-Cache: hit|miss``), keyed also by the numerics version."""
    fmt = choice(format, tuple(MEDIA), "format")
    q = choice(quality, QUALITIES, "quality")
    try:
        names = await run_in_threadpool(compute.figure_names)
    except ComputeError as exc:  # pragma: no cover - only without rsfplots
        raise ProblemError(503, "Unavailable", str(exc)) from None
    if name not in names:
        return _unknown_figure(name, names)
    data, hit = await image(f"figure-{name}-{q}.{fmt}", lambda: compute.figure(name, fmt, q))
    return image_response(data, fmt, hit)
