"""Answer a validated request from the cache or by computing it (then caching it).

Response: the result's own fields plus ``cached`` (bool) and ``cache_key``; header
``X-Cache: hit|miss``.  Computation runs in a worker thread (bounded by a limiter) so
the event loop keeps answering cached lookups.
"""
from __future__ import annotations

import json
import os
from typing import Any, Callable

import anyio
from pydantic import BaseModel
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from worker import cache

from .compute import ComputeError, numerics_version
from .errors import ProblemError

__all__ = ["answer"]
_limiter: anyio.CapacityLimiter | None = None


def _limit() -> anyio.CapacityLimiter:
    global _limiter
    if _limiter is None:
        _limiter = anyio.CapacityLimiter(max(2, os.cpu_count() or 2))
    return _limiter


def _body(result_json: str, key: str, hit: bool) -> bytes:
    tail = f',"cached":{"true" if hit else "false"},"cache_key":"{key}"}}'
    return (result_json[:-1] + tail if result_json != "{}" else "{" + tail[1:]).encode()


async def answer(kind: str, req: BaseModel, fn: Callable[[Any], dict[str, Any]]) -> Response:
    """Cached answer to ``req`` of ``kind``, computing ``fn(req)`` on a miss."""
    request = req.model_dump(mode="json")
    version = numerics_version()
    key = cache.cache_key(kind, request, version)
    hit = cache.get(key)
    if hit is not None:
        return Response(_body(cache.canonical(hit), key, True), media_type="application/json",
                        headers={"X-Cache": "hit"})
    async with _limit():
        try:
            result = await run_in_threadpool(fn, req)
        except ComputeError as exc:
            raise ProblemError(422, "Could not be computed", str(exc)) from None
    try:
        text = cache.canonical(result)
    except (TypeError, ValueError) as exc:  # non-JSON result: a bug, but never a 500 here
        raise ProblemError(422, "Could not be computed", f"unserialisable result: {exc}") \
            from None
    await run_in_threadpool(cache.put, key, kind, version, request, json.loads(text))
    return Response(_body(text, key, False), media_type="application/json",
                    headers={"X-Cache": "miss"})
