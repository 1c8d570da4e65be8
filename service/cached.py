"""Answer a validated request from the cache or by computing it (then caching it).

Response: the result's own fields plus ``cached`` (bool) and ``cache_key``; header
``X-Cache: hit|miss``.  Computation runs in a worker thread (at most one per CPU) so the
event loop keeps answering cached lookups.  Single classify/trajectory queries get a
quick step budget in process; one that needs more (a long integration) is sent to the
Celery queue (:mod:`worker.jobs`) and answered 202 + ``Location: /v1/results/{key}``.  A computation still running after
``RSF_INLINE_BUDGET_S`` seconds (a long integration: some stiff corners of parameter
space take tens of seconds) is answered with 202 and a ``Location: /v1/results/{key}``
to poll; it completes in the background and lands in the cache.  Identical requests
arriving meanwhile join the running computation instead of starting another.
"""
from __future__ import annotations

import asyncio
import json
import logging
import os
from typing import Any, Callable

import anyio
from pydantic import BaseModel
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response

from worker import cache, jobs

from .compute import ComputeError, NeedsQueue, numerics_version
from .errors import ProblemError
from .settings import get_settings

__all__ = ["answer", "pending", "failed"]
log = logging.getLogger("rsf.service")
_limiter: anyio.CapacityLimiter | None = None
#: Computations in flight in this process, by cache key.
pending: dict[str, asyncio.Task] = {}
#: Recent computation failures by key (message), for GET /v1/results/{key}.
failed: dict[str, str] = {}


def _limit() -> anyio.CapacityLimiter:
    global _limiter
    if _limiter is None:
        _limiter = anyio.CapacityLimiter(max(2, os.cpu_count() or 2))
    return _limiter


def body(result_json: str, key: str, hit: bool) -> bytes:
    """The stored result JSON with ``cached`` and ``cache_key`` appended."""
    tail = f',"cached":{"true" if hit else "false"},"cache_key":"{key}"}}'
    return (result_json[:-1] + tail if result_json != "{}" else "{" + tail[1:]).encode()


def _fail(key: str, msg: str) -> None:
    failed[key] = msg
    while len(failed) > 1000:  # bounded memory: forget the oldest
        failed.pop(next(iter(failed)))


async def _compute(kind: str, key: str, version: str, request: dict[str, Any], req: BaseModel,
                   fn: Callable[[Any], dict[str, Any]]) -> str | None:
    """Compute, store, return the result JSON text (None: sent to the queue);
    ProblemError on failure."""
    try:
        async with _limit():
            result = await run_in_threadpool(fn, req)
        text = cache.canonical(result)
    except NeedsQueue:
        # a long integration: computed by a worker through the queue (result -> cache)
        from worker.celery_app import send_single

        await run_in_threadpool(jobs.mark_queued, key, kind)
        await run_in_threadpool(send_single, kind, request, key, version)
        return None
    except ComputeError as exc:
        _fail(key, str(exc))
        raise ProblemError(422, "Could not be computed", str(exc)) from None
    except (TypeError, ValueError) as exc:  # non-JSON result: a bug, but never a 500
        _fail(key, str(exc))
        raise ProblemError(422, "Could not be computed", f"unserialisable result: {exc}") \
            from None
    await run_in_threadpool(cache.put, key, kind, version, request, json.loads(text))
    return text


def _deferred(key: str) -> Response:
    loc = f"/v1/results/{key}"
    return Response(json.dumps({"status": "running", "cache_key": key, "location": loc}),
                    status_code=202, media_type="application/json",
                    headers={"Location": loc, "Retry-After": "2", "X-Cache": "miss"})


async def answer(kind: str, req: BaseModel, fn: Callable[[Any], dict[str, Any]]) -> Response:
    """Cached answer to ``req`` of ``kind``, computing ``fn(req)`` on a miss."""
    request = req.model_dump(mode="json")
    version = numerics_version()
    key = cache.cache_key(kind, request, version)
    hit = cache.get(key)
    if hit is not None:
        return Response(body(cache.canonical(hit), key, True), media_type="application/json",
                        headers={"X-Cache": "hit"})
    queued = await run_in_threadpool(jobs.status, key)
    if queued is not None:
        if queued[0] == "failed":
            raise ProblemError(422, "Could not be computed", queued[1])
        return _deferred(key)
    task = pending.get(key)
    if task is None:
        task = asyncio.ensure_future(_compute(kind, key, version, request, req, fn))
        pending[key] = task

        def _done(t: asyncio.Task, key: str = key) -> None:
            pending.pop(key, None)
            if not t.cancelled() and t.exception() is not None and \
                    not isinstance(t.exception(), ProblemError):
                log.error("computation %s failed", key, exc_info=t.exception())
        task.add_done_callback(_done)
    try:
        text = await asyncio.wait_for(asyncio.shield(task), get_settings().inline_budget_s)
    except asyncio.TimeoutError:
        return _deferred(key)
    if text is None:
        return _deferred(key)
    return Response(body(text, key, False), media_type="application/json",
                    headers={"X-Cache": "miss"})
