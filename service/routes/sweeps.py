"""Sweep endpoints: submit (202 + Location), list, status, paged points, stability
diagram (JSON or PNG, also while the sweep runs), cancel.

A sweep's id is derived from its canonical spec and the numerics version, so submitting
the same sweep twice returns the same sweep (``X-Cache: hit``) instead of recomputing.
"""
from __future__ import annotations

import json
import logging
from typing import Annotated

from fastapi import APIRouter, Path, Query
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from rsfapp import adapter
from rsfapp.adapter import numerics_version
from rsfapp.grid import expand
from rsfapp.keys import cache_key
from rsfapp.queue import Queue
from rsfapp.requests import SweepRequest
from rsfapp.store import SweepStore

from .. import images
from ..deps import QueueDep, SettingsDep, StoresDep
from ..errors import ProblemError
from ..images import choice, format_query, image, image_response, png_content

router = APIRouter(prefix="/v1/sweeps", tags=["sweeps"])
log = logging.getLogger("rsf.service")
SweepId = Annotated[str, Path(pattern=r"^[0-9a-f]{32}$", description="Sweep id (32 hex).")]
_R = {422: {"description": "Invalid input (problem+json naming the field and its range)."}}
_N = {404: {"description": "Unknown sweep (problem+json)."}}

#: Expected seconds of work per point, for the default chunk size.  Measured: outcome
#: ~60 us; critical sizes 10 us .. 0.4 s (closed form / separatrix / bisection).
_COST_S = {"critical": 0.02, "outcome": 1e-4}
#: Default chunking splits a sweep in at least this many chunks (parallel workers).
_MIN_CHUNKS = 8


def _json(obj: object, status: int = 200, headers: dict[str, str] | None = None) -> Response:
    return Response(json.dumps(obj), status_code=status, media_type="application/json",
                    headers=headers)


def _unknown(sweep_id: str) -> ProblemError:
    return ProblemError(404, "Not found", f"no sweep with id {sweep_id}")


def _enqueue(queue: Queue, sweep_id: str, chunk_ids: list[int]) -> str | None:
    try:
        for c in chunk_ids:
            queue.send_chunk(sweep_id, c)
    except Exception as exc:  # noqa: BLE001 - chunks stay queued; a worker start requeues
        log.exception("could not enqueue sweep %s", sweep_id)
        return f"broker unavailable ({type(exc).__name__}); queued chunks are sent when " \
               "a worker starts"
    return None


@router.post("", status_code=202, responses={**_R, 200: {"description": "Already done."}},
             summary="Submit a sweep")
async def submit(req: SweepRequest, stores: StoresDep, queue: QueueDep,
                 s: SettingsDep) -> Response:
    """Start a 2-D sweep over two of {kappa_ratio, eps, ba, size}; answers 202 with a
    Location to poll. Per point: the critical size (kind, critical_size) or, when a size
    is given or swept, the outcome. Identical submissions return the same sweep."""
    sweeps = stores.sweeps
    spec = expand(req, s.sweep_max_points)
    n_total = len(spec["x"]["values"]) * len(spec["y"]["values"])
    version = numerics_version()
    sweep_id = cache_key("sweep", spec, version)[:32]
    size_given = spec["fixed"]["size"] is not None or "size" in (req.x.name, req.y.name)
    per = _COST_S["outcome" if size_given else "critical"]
    chunk = req.chunk_points or max(1, min(10_000, int(s.chunk_seconds / per),
                                           -(-n_total // _MIN_CHUNKS)))
    created, todo = await run_in_threadpool(sweeps.create, sweep_id, spec, n_total, chunk,
                                            version)
    warning = await run_in_threadpool(_enqueue, queue, sweep_id, todo) if todo else None
    st = await run_in_threadpool(sweeps.status, sweep_id)
    if st is None:  # pragma: no cover - created just above
        raise _unknown(sweep_id)
    st.pop("failures", None)
    if warning:
        st["warning"] = warning
    loc = f"/v1/sweeps/{sweep_id}"
    code = 200 if st["status"] == "done" else 202
    return _json(st, code, {"Location": loc, "X-Cache": "miss" if created else "hit"})


@router.get("", summary="List sweeps")
async def list_all(stores: StoresDep, limit: Annotated[int, Query(ge=1, le=1000)] = 100,
                   offset: Annotated[int, Query(ge=0, le=10**9)] = 0) -> Response:
    """Sweeps, newest first, with status and progress."""
    return _json({"sweeps": await run_in_threadpool(stores.sweeps.list_sweeps, limit,
                                                      offset)})


@router.get("/{sweep_id}", responses=_N, summary="Sweep status")
async def get_status(sweep_id: SweepId, stores: StoresDep) -> Response:
    """status (queued|running|done|cancelled), n_done, n_total, n_failed, eta_s [s],
    failures (first 100, with messages)."""
    st = await run_in_threadpool(stores.sweeps.status, sweep_id)
    if st is None:
        raise _unknown(sweep_id)
    return _json(st)


@router.get("/{sweep_id}/points", responses=_N, summary="Sweep points (paged)")
async def get_points(sweep_id: SweepId, stores: StoresDep,
                     offset: Annotated[int, Query(ge=0, le=10**9)] = 0,
                     limit: Annotated[int, Query(ge=1, le=10_000)] = 1000) -> Response:
    """Stored points ordered by flat index idx = i*n_y + j, available while running.
    Each point: idx, i, j, x, y, kind, critical_size, outcome, rel_accuracy, error."""
    st = await run_in_threadpool(stores.sweeps.status, sweep_id)
    if st is None:
        raise _unknown(sweep_id)
    pts = await run_in_threadpool(stores.sweeps.page_points, sweep_id, offset, limit)
    nxt = offset + len(pts) if len(pts) == limit else None
    return _json({"id": sweep_id, "status": st["status"], "n_done": st["n_done"],
                  "n_total": st["n_total"], "offset": offset, "limit": limit,
                  "next_offset": nxt, "points": pts})


_JSON_OR_PNG = ("json", "png")
_PAGE = 10_000


def _all_points(sweeps: SweepStore, sweep_id: str) -> list[dict[str, object]]:
    out: list[dict[str, object]] = []
    while True:
        page = sweeps.page_points(sweep_id, len(out), _PAGE)
        out += page
        if len(page) < _PAGE:
            return out


@router.get("/{sweep_id}/diagram", summary="Stability diagram of a sweep (JSON or PNG)",
            responses={**_N, **png_content(
                "The sweep assembled on its grid (JSON), or with format=png the stability "
                "diagram image (critical size, or stable/unstable when a size is given).",
                {422: {"description": "Invalid format (problem+json naming the field)."}})})
async def get_diagram(sweep_id: SweepId, stores: StoresDep,
                      format: Annotated[str, format_query(  # noqa: A002
                          _JSON_OR_PNG, "json", "'png': the stability diagram image.")]
                      = "json") -> Response:
    """The finished or partial sweep as a stability diagram on its (x, y) grid, laid out
    like ``rsfcore.diagram.DiagramResult.to_dict()``: ``critical_size[i][j]`` at (x[i], y[j])
    (null where infinite or not yet computed), ``kind`` 0 zero / 1 finite / 2 infinite,
    ``outcome`` 0 stable / 1 unstable when the sweep classifies a size, ``present[i][j]``
    (computed without error), with status, n_done, n_total, n_failed.
    ``?format=png``: the image, points not computed yet (or failed) left blank; headers
    ``X-Sweep-Status`` and ``X-Sweep-Progress: n_done/n_total``.  Images of finished
    sweeps are cached."""
    fmt = choice(format, _JSON_OR_PNG, "format")
    st = await run_in_threadpool(stores.sweeps.status, sweep_id)
    if st is None:
        raise _unknown(sweep_id)
    pts = await run_in_threadpool(_all_points, stores.sweeps, sweep_id)
    d = adapter.sweep_diagram(st, pts)
    if fmt == "json":
        return _json(d)
    final = d["status"] in ("done", "cancelled")
    key = f"sweep-{sweep_id}-{d['status']}-{d['n_done']}-{d['n_failed']}.png"
    data, hit = await image(key, lambda: images.diagram_png(d), store=final)
    return image_response(data, "png", hit, final=final, headers={
        "X-Sweep-Status": d["status"], "X-Sweep-Progress": f"{d['n_done']}/{d['n_total']}"})


@router.delete("/{sweep_id}", responses=_N, summary="Cancel a sweep")
async def cancel(sweep_id: SweepId, stores: StoresDep) -> Response:
    """Cancel: queued chunks are dropped, running chunks stop at their next point."""
    new = await run_in_threadpool(stores.sweeps.cancel, sweep_id)
    if new is None:
        raise _unknown(sweep_id)
    return _json(await run_in_threadpool(stores.sweeps.status, sweep_id))
