"""Images: rsfplots renders (under one lock), the on-disk image cache, and the HTTP
helpers of the ``format`` query parameter.

Plots come from rsfplots (matplotlib Agg, no pyplot), imported lazily so that an API
process that never draws does not load matplotlib.  Matplotlib's shared state (font
cache, mathtext parser) is not guaranteed thread-safe, so every render holds one
process-wide lock.  Rendering takes up to seconds, so every rendered image is kept on
disk under ``<data dir>/images/<numerics version>/`` (written atomically: a temporary
file renamed into place, so concurrent API processes never read half an image) and
identical requests arriving while it renders join the running render.
"""

from __future__ import annotations

import asyncio
import importlib
import math
import os
import re
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from fastapi import Query
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from rsfapp.adapter import ComputeError, guard, numerics_version
from rsfapp.config import get_settings
from rsfapp.requests.figures import FigureRequest

from .errors import ProblemError

__all__ = [
    "MEDIA",
    "analytic_u_png",
    "choice",
    "diagram_png",
    "figure",
    "format_query",
    "image",
    "image_response",
    "png_content",
    "render_locked",
    "trajectory_png",
]

#: Media type of each image format.
MEDIA = {"png": "image/png", "svg": "image/svg+xml"}

#: Renders in flight in this process, by image key.
_inflight: dict[str, asyncio.Future[bytes]] = {}


# ------------------------------------------------------------------ query parameters
def format_query(allowed: tuple[str, ...], default: str, what: str) -> Any:
    """A documented ``format`` query parameter (enum in OpenAPI, checked by :func:`choice`)."""
    return Query(
        description=f"Response format: {' or '.join(repr(a) for a in allowed)} "
        f"(default {default!r}). {what} Valid range: "
        f"{' or '.join(repr(a) for a in allowed)}.",
        json_schema_extra={
            "enum": list(allowed),
            "x-valid-range": " or ".join(repr(a) for a in allowed),
        },
    )


def choice(value: str, allowed: tuple[str, ...], field: str) -> str:
    """``value`` (case-insensitive) if in ``allowed``, else a 422 naming ``field``."""
    v = str(value).strip().lower()
    if v not in allowed:
        valid = " or ".join(repr(a) for a in allowed)
        raise ProblemError(
            422,
            "Invalid input",
            f"{field}: {value!r} is not supported (valid range: {valid})",
            field=field,
            valid=valid,
        )
    return v


def png_content(
    description: str, extra: dict[int | str, Any] | None = None, model: Any = None
) -> dict[int | str, Any]:
    """OpenAPI ``responses`` entry: 200 as JSON (default; ``model`` documents it) or image/png."""
    entry: dict[str, Any] = {
        "description": description,
        "content": {
            "application/json": {},
            "image/png": {"schema": {"type": "string", "format": "binary"}},
        },
    }
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

        def _done(t: asyncio.Future[bytes], k: str = key) -> None:
            _inflight.pop(k, None)
            if not t.cancelled():
                t.exception()  # retrieved here: every waiter may have gone away

        task.add_done_callback(_done)
    return await asyncio.shield(task), False


def image_response(
    data: bytes, fmt: str, hit: bool, *, final: bool = True, headers: dict[str, str] | None = None
) -> Response:
    """An image response with ``X-Cache`` and cache headers."""
    h = {
        "X-Cache": "hit" if hit else "miss",
        "Cache-Control": "public, max-age=3600" if final else "no-store",
    }
    h.update(headers or {})
    return Response(data, media_type=MEDIA[fmt], headers=h)


# ------------------------------------------------------------------ rendering

_render_lock = threading.Lock()


def _plots() -> Any:
    """rsfplots, imported on first use (it loads matplotlib)."""
    return importlib.import_module("rsfplots")


def render_locked(fn: Callable[..., bytes], *args: Any, **kwargs: Any) -> bytes:
    """Call the plotting function ``fn`` under the render lock, with :func:`guard`."""
    with _render_lock:
        try:
            return bytes(guard(fn, *args, **kwargs))
        except ComputeError:
            raise
        except Exception as exc:  # noqa: BLE001 - a plot that fails is a 422, never a 500
            raise ComputeError(f"could not be plotted: {type(exc).__name__}: {exc}") from exc


def trajectory_png(result: dict[str, Any]) -> bytes:
    """Phase plane (phi, psi) and phi(T) of a trajectory answer (JSON dict) as PNG."""
    return render_locked(_plots().plot_trajectory, result, "png")


def analytic_u_png(result: dict[str, Any]) -> bytes:
    """Contours of U (red: U = 0) of a grid answer of ``analytic_u`` as PNG."""
    if result.get("shape") is None:
        raise ProblemError(
            422,
            "Invalid input",
            "format: png needs U on a grid (give 'grid', not 'points')",
            field="format",
            valid="'json' (points or grid) or 'png' (grid only)",
        )
    title = f"U ({result.get('function')}): U = const., red: U = 0"
    return render_locked(_plots().plot_u_field, result, title=title, fmt="png")


def figure(req: FigureRequest, fmt: str) -> bytes:
    """Paper figure ``req`` as png/svg bytes: its data from the figure adapter
    (:func:`rsfapp.adapter.figures.figure_arrays`, computed outside the render lock), drawn
    by rsfplots under the lock."""
    from rsfapp.adapter.figures import figure_arrays

    data = guard(figure_arrays, req)
    return render_locked(_plots().render_figure, data, fmt)


def diagram_png(diagram: dict[str, Any]) -> bytes:
    """A sweep diagram (:func:`rsfapp.adapter.sweep_diagram`) as PNG; missing or failed points are blank."""
    d = dict(diagram)
    if d["outcome"] is not None:
        d["outcome"] = [[math.nan if v is None else v for v in row] for row in d["outcome"]]
    return render_locked(_plots().plot_diagram, d, "png")
