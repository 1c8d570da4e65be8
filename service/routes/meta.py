"""Health and cache statistics."""

from __future__ import annotations

import json
from typing import Annotated

from fastapi import APIRouter, Path
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from rsfapp.adapter import numerics_version
from rsfapp.health import health_report
from rsfapp.store import JobState

from ..answer import body, hot_for
from ..deps import InflightDep, SettingsDep, StoresDep
from ..errors import ProblemError

router = APIRouter(tags=["meta"])


@router.get(
    "/health",
    summary="Deployment health: database, broker, workers",
    responses={
        503: {
            "description": "A part is down or damaged; ``reasons`` says "
            "which and ``Retry-After`` when to ask again."
        }
    },
)
async def health(stores: StoresDep, settings: SettingsDep) -> Response:
    """``status`` 'ok' (200) or 'degraded' (503 + ``Retry-After``, ``reasons``): the
    database is reachable and sound (schema version, SQLite page check), the broker is
    reachable; plus the live workers (count, hosts, processes), the queue length, the
    numerics version and the number of cached results.  No live worker is a
    ``warning`` (queued work waits), not a degradation."""
    rep = await run_in_threadpool(health_report, stores.db, settings)
    rep["numerics_version"] = numerics_version()
    if rep["database"]["ok"]:
        try:
            rep["cache_entries"] = (await run_in_threadpool(stores.results.stats))["entries"]
        except Exception as exc:  # noqa: BLE001 - reported, never raised
            rep["status"] = "degraded"
            rep["reasons"].append(f"results table unreadable: {exc}")
    ok = rep["status"] == "ok"
    return Response(
        json.dumps(rep),
        status_code=200 if ok else 503,
        media_type="application/json",
        headers=None if ok else {"Retry-After": str(settings.retry_after_s)},
    )


@router.get("/health/live", summary="Liveness only (no I/O)", include_in_schema=False)
async def live() -> Response:
    """200 while this API process answers; checks nothing else (for proxies and as
    the trivial endpoint of bench/load_service.py).  Outside the schema, hence open
    without an API key and without touching the database."""
    return Response(b'{"status":"ok"}', media_type="application/json")


@router.get("/v1/cache/stats", summary="Cache statistics")
async def stats(stores: StoresDep) -> Response:
    """Entries (total and per kind) and this API process's hits, misses and hit ratio
    (hits from the store plus those served from memory, :class:`service.answer.HotResults`)."""
    st = await run_in_threadpool(stores.results.stats)
    st["hits"] += hot_for(stores).hits
    n = st["hits"] + st["misses"]
    st["hit_ratio"] = st["hits"] / n if n else None
    st["numerics_version"] = numerics_version()
    return Response(json.dumps(st), media_type="application/json")


@router.get(
    "/v1/results/{key}",
    summary="A deferred (long) computation's result",
    responses={
        202: {"description": "Still running."},
        404: {"description": "Unknown key (problem+json)."},
        422: {"description": "The computation failed (problem+json)."},
    },
)
async def result(
    key: Annotated[str, Path(pattern=r"^[0-9a-f]{64}$", description="cache_key (64 hex)")],
    stores: StoresDep,
    inflight: InflightDep,
) -> Response:
    """The cached result for ``key`` (as the original endpoint answers it), 202 while it
    is still being computed (in this API process or, for a long integration, by a
    worker through the queue), 422 if it failed, else 404."""
    hit = await run_in_threadpool(stores.results.get_text, key)
    if hit is not None:
        return Response(
            body(hit, key, True), media_type="application/json", headers={"X-Cache": "hit"}
        )
    if key in inflight.pending:
        return Response(
            json.dumps({"status": "running", "cache_key": key}),
            status_code=202,
            media_type="application/json",
            headers={"Retry-After": "2"},
        )
    if key in inflight.failed:
        raise ProblemError(422, "Could not be computed", inflight.failed[key])
    queued = await run_in_threadpool(stores.jobs.status, key)
    if queued is not None:
        if queued.state is JobState.failed:
            raise ProblemError(422, "Could not be computed", queued.message)
        return Response(
            json.dumps({"status": "queued", "cache_key": key}),
            status_code=202,
            media_type="application/json",
            headers={"Retry-After": "2"},
        )
    raise ProblemError(404, "Not found", f"no result with key {key}")
