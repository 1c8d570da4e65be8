"""Fits of lab records: ``POST /v1/fits`` (queued) and ``GET /v1/fits/{key}``.

POST takes a :class:`rsfapp.requests.fits.FitRequest` (the record as CSV or JSON text plus
options).  The record is parsed at once (a malformed record is a 422 naming the problem);
the fit itself runs on a Celery worker (task ``worker.tasks.fit_record``): the answer is
202 with ``Location: /v1/fits/{key}``.  The key is the hash of the record's content
(rsfcore.fit.Record.digest) and the options, so the same record with the same options is
fitted once: later requests get the stored answer (200, ``X-Cache: hit``).

GET answers 202 (``{"status": "queued"}``, or ``"running"`` with ``progress``: the stage
the worker is at) while the fit runs, 200 with the fit when done
(``?format=png``: data, fit and per-step residuals; ``?format=csv``: t_s, v_lp_m_s, mu,
model, residuals, step [, used]), 422 if the fit could not be computed, 404 for an
unknown key.  A fit's ``status`` is ok only when nothing is wrong: suspect (unit slips),
rejected (by the law comparison), ill_conditioned, not_converged, failed say why in
``message``.
"""

from __future__ import annotations

import json
import re
from typing import Annotated, Any

from fastapi import APIRouter, Path
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from rsfapp.adapter import fits as fits_adapter
from rsfapp.adapter import numerics_version
from rsfapp.keys import cache_key
from rsfapp.requests.fits import FitRequest
from rsfapp.store import JobState

from .. import images
from ..answer import body
from ..context import CtxDep
from ..errors import ProblemError
from ..images import choice, format_query, image, image_response
from ..tables import csv_table

__all__ = ["router"]

router = APIRouter(prefix="/v1/fits", tags=["fits"])
_KEY = re.compile(r"^[0-9a-f]{64}$")
_FORMATS = ("json", "png", "csv")


def _queued(key: str, progress: str = "") -> Response:
    """202: ``status`` 'queued' (waiting for a worker) or 'running' with ``progress``
    (the stage the worker is at)."""
    loc = f"/v1/fits/{key}"
    status = "running" if progress else "queued"
    return Response(
        json.dumps(
            {"status": status, "progress": progress or None, "cache_key": key, "location": loc}
        ),
        status_code=202,
        media_type="application/json",
        headers={"Location": loc, "Retry-After": "1", "X-Cache": "miss"},
    )


@router.post(
    "",
    status_code=202,
    summary="Fit a lab record (queued)",
    responses={
        202: {"description": "Queued: poll the Location (GET /v1/fits/{key})."},
        200: {"description": "This record with these options was fitted before: the fit."},
        422: {
            "description": "Invalid options or a record that cannot be read (problem+json "
            "naming the field)."
        },
    },
)
async def submit_fit(req: FitRequest, ctx: CtxDep) -> Response:
    """Fit mu0, a, b, Dc (and eps, machine stiffness, a friction trend) to a lab record by
    bounded non-linear least squares on the compiled forward model; compare the evolution
    laws (AIC/BIC); answer the stability consequences in SI with uncertainty.  The
    stiffness is k_Pa_per_m with sigma_Pa, or k_friction_per_m [1/m]; with neither it is
    fitted.  Any lab CSV is read with ``columns`` (units), a units row and ``decimal``."""
    summary = await run_in_threadpool(fits_adapter.fit_key_request, req)
    version = numerics_version()
    key = cache_key("fit", summary, version)
    hit = await run_in_threadpool(ctx.stores.results.get_text, key)
    if hit is not None:
        return Response(
            body(hit, key, True),
            media_type="application/json",
            headers={"X-Cache": "hit", "Location": f"/v1/fits/{key}"},
        )
    st = await run_in_threadpool(ctx.stores.jobs.status, key)
    if st is not None and st.state is JobState.failed:
        raise ProblemError(422, "Could not be computed", st.message)
    if st is None:
        await run_in_threadpool(ctx.stores.jobs.mark_queued, key, "fit")
        await run_in_threadpool(ctx.queue.send_fit, req.model_dump(mode="json"), key, version)
    return _queued(key)


@router.get(
    "/{key}",
    summary="A fit: result or state",
    responses={
        200: {
            "description": "The fit (JSON), or its plot (PNG) or series (CSV).",
            "content": {"application/json": {}, "image/png": {}, "text/csv": {}},
        },
        202: {"description": "Still queued or running."},
        404: {"description": "No fit with this key."},
        422: {"description": "The fit could not be computed."},
    },
)
async def get_fit(
    key: Annotated[str, Path(description="The key of POST /v1/fits.", pattern="^[0-9a-f]{64}$")],
    ctx: CtxDep,
    format: Annotated[
        str,
        format_query(  # noqa: A002
            _FORMATS,
            "json",
            "'png': data, fit and per-step residuals; 'csv': the "
            "series (t_s, v_lp_m_s, mu, model, residuals, step, used).",
        ),
    ] = "json",
) -> Response:
    """The fit's answer: params, stderr, correlation, misfit, law comparison, stability
    (kappa/kappa_crit, critical velocity and load-point jumps in SI, with spread)."""
    fmt = choice(format, _FORMATS, "format")
    if not _KEY.match(key):
        raise ProblemError(
            422,
            "Invalid input",
            "key: 64 hex digits expected",
            field="key",
            valid="64 lowercase hex digits",
        )
    text = await run_in_threadpool(ctx.stores.results.get_text, key)
    if text is None:
        st = await run_in_threadpool(ctx.stores.jobs.status, key)
        if st is None:
            raise ProblemError(404, "Not found", f"no fit with key {key}")
        if st.state is JobState.failed:
            raise ProblemError(422, "Could not be computed", st.message)
        return _queued(key, st.message)
    if fmt == "json":
        return Response(
            body(text, key, True), media_type="application/json", headers={"X-Cache": "hit"}
        )
    result: dict[str, Any] = json.loads(text)
    if fmt == "csv":
        return Response(
            csv_table(fits_adapter.fit_table(result)),
            media_type="text/csv",
            headers={"Content-Disposition": 'attachment; filename="fit.csv"'},
        )
    data, hit = await image(f"fit-{key}.png", lambda: _plot(result))
    return image_response(data, "png", hit)


def _plot(result: dict[str, Any]) -> bytes:
    from rsfplots.lab import plot_fit

    return images.render_locked(plot_fit, result, "png")
