"""Health and cache statistics."""
from __future__ import annotations

import json

from fastapi import APIRouter
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from worker import cache

from ..compute import numerics_version

router = APIRouter(tags=["meta"])


@router.get("/health", summary="Liveness and database check")
async def health() -> Response:
    """{"status": "ok", "numerics_version": ...} once the cache database answers."""
    st = await run_in_threadpool(cache.stats)
    return Response(json.dumps({"status": "ok", "numerics_version": numerics_version(),
                                "cache_entries": st["entries"]}),
                    media_type="application/json")


@router.get("/v1/cache/stats", summary="Cache statistics")
async def stats() -> Response:
    """Entries (total and per kind) and this API process's hits, misses and hit ratio."""
    st = await run_in_threadpool(cache.stats)
    st["numerics_version"] = numerics_version()
    return Response(json.dumps(st), media_type="application/json")
