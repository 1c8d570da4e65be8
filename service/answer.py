"""Answer a validated request from the result store or by computing it (then storing it).

Response: the result's own fields plus ``cached`` (bool) and ``cache_key``; header
``X-Cache: hit|miss``.  Computation runs in a worker thread (at most one per CPU) so the
event loop keeps answering cached lookups.  Single classify/trajectory queries get a
quick step budget in process; one that needs more (a long integration) is sent to the
Celery queue and answered 202 + ``Location: /v1/results/{key}``.  A computation still
running after ``RSF_INLINE_BUDGET_S`` seconds is answered the same way; it completes in
the background and lands in the store.  Identical requests arriving meanwhile join the
running computation instead of starting another.

No state another API process needs lives here: a deferred computation is recorded in
the job store (``queued``, then ``failed`` with its message, or its result in the result
store), so ``rsf api --workers N`` and several API hosts answer the same.  A request of
an API key that will compute (not cached) first takes a lease and a token from the key's
in-flight quota and fresh-computation bucket in the database, through the admission the
route passes in (:class:`service.admission.Admission`), or is answered 429; cached
answers never touch them.

Cached lookups are served from memory where possible: :class:`HotResults` holds recent
results (immutable per key), and :class:`FastHits` lets the rate-limit middleware answer
a repeated request (same path, content type and body bytes) from them before routing,
body validation and dependency resolution; both are per-process caches of immutable
facts, never state another process needs.
"""

from __future__ import annotations

import asyncio
import hashlib
import json
import logging
import weakref
from collections import OrderedDict
from collections.abc import Callable
from typing import Any

from fastapi import Request
from pydantic import BaseModel
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response
from starlette.types import Scope as AsgiScope

from rsfapp.adapter import ComputeError, NeedsQueue, numerics_version
from rsfapp.config import Settings, get_settings
from rsfapp.keys import cache_key, canonical
from rsfapp.metrics import CACHE_LOOKUPS
from rsfapp.queue import Queue
from rsfapp.store import JobState, Stores, stores_for
from rsfapp.store.keys import Scope
from rsfcore.params import ParameterError

from . import auth
from .admission import Admission
from .deps import Inflight, get_settings_dep, get_stores
from .errors import ProblemError

__all__ = ["FastHits", "HotResults", "answer", "body", "deferred", "hot_for"]
log = logging.getLogger("rsf.service")


class HotResults:
    """The most recently used results of this process, in memory (bounded LRU).

    A stored result never changes (its key includes the canonical request and the
    numerics version; the first write wins), so serving it from memory is exact and
    holds no state another process needs: a cached lookup then costs no database read
    and no thread hop.  Used from the event loop only (no lock).

    Args:
        max_entries: entries kept, >= 1.
        max_bytes: total result text kept [bytes], >= 1.
    """

    def __init__(self, max_entries: int = 4096, max_bytes: int = 32 << 20) -> None:
        self.max_entries, self.max_bytes = max_entries, max_bytes
        self._d: OrderedDict[str, str] = OrderedDict()
        self._bytes = 0
        self.hits = 0

    def get(self, key: str) -> str | None:
        """The result text of ``key`` if held (counts a hit)."""
        text = self._d.get(key)
        if text is not None:
            self._d.move_to_end(key)
            self.hits += 1
            CACHE_LOOKUPS.labels("hit").inc()
        return text

    def holds(self, key: str) -> bool:
        """True if ``key`` is held (counts nothing, changes no order)."""
        return key in self._d

    def put(self, key: str, text: str) -> None:
        """Hold ``text`` for ``key`` (results larger than an eighth of the budget are not
        held), forgetting the least recently used beyond the bounds."""
        if key in self._d or len(text) > self.max_bytes // 8:
            return
        self._d[key] = text
        self._bytes += len(text)
        while len(self._d) > self.max_entries or self._bytes > self.max_bytes:
            _k, old = self._d.popitem(last=False)
            self._bytes -= len(old)


_hot: weakref.WeakKeyDictionary[Any, HotResults] = weakref.WeakKeyDictionary()


def hot_for(stores: Stores) -> HotResults:
    """This process's hot results of the database of ``stores`` (hits are added to
    /v1/cache/stats)."""
    h = _hot.get(stores.db)
    if h is None:
        h = _hot[stores.db] = HotResults()
    return h


def body(result_json: str, key: str, hit: bool) -> bytes:
    """The stored result JSON with ``cached`` and ``cache_key`` appended."""
    tail = f',"cached":{"true" if hit else "false"},"cache_key":"{key}"}}'
    return (result_json[:-1] + tail if result_json != "{}" else "{" + tail[1:]).encode()


class FastHits:
    """Cached lookups answered before routing (used by :class:`service.limits.Limits`).

    A single query's cache key is a pure function of its path, content type and body
    bytes (validation depends on nothing else) and of the numerics version, so once this
    process has validated a request and answered it 200, :meth:`remember` records
    ``(path, content type, sha256(body), numerics version) -> (cache key, scope the
    guard checked)`` in a bounded LRU.  :meth:`serve` answers the same request again
    from :class:`HotResults` after the same authorisation as the guard
    (:func:`service.auth.authorize`: key, scope, trajectory quota), and returns None
    (the app answers) for anything else: an unknown body, a result not in memory, any
    refusal, or an app whose settings or stores dependencies are overridden.
    The answer is byte for byte the one :func:`answer` gives for a hit.

    Args:
        max_entries: requests remembered, >= 1.
        max_body: largest body considered [bytes].
    """

    def __init__(self, max_entries: int = 8192, max_body: int = 4096) -> None:
        self.max_entries, self.max_body = max_entries, max_body
        self._keys: OrderedDict[tuple[str, bytes, bytes, str], tuple[str, Scope]] = OrderedDict()
        self._stores: tuple[Settings, Stores] | None = None
        #: answers served
        self.served = 0

    @staticmethod
    def _memo_key(scope: AsgiScope, data: bytes) -> tuple[str, bytes, bytes, str]:
        ct = b""
        for k, v in scope.get("headers", ()):
            if k == b"content-type":
                ct = bytes(v)
                break
        return (str(scope.get("path", "")), ct, hashlib.sha256(data).digest(), numerics_version())

    def usable(self, scope: AsgiScope) -> bool:
        """False when the app overrides a dependency this path resolves itself."""
        overrides = getattr(scope.get("app"), "dependency_overrides", None)
        return not overrides or not any(d in overrides for d in (get_settings_dep, get_stores))

    def remember(self, scope: AsgiScope, data: bytes, key: str, need: str) -> None:
        """Record that this request validated to cache key ``key`` and needs ``need``."""
        mk = self._memo_key(scope, data)
        self._keys[mk] = (key, Scope(need))
        self._keys.move_to_end(mk)
        while len(self._keys) > self.max_entries:
            self._keys.popitem(last=False)

    def _stores_of(self, settings: Settings) -> Stores:
        """The stores of ``settings`` (remembered for the settings object of the moment:
        :func:`~rsfapp.config.get_settings` makes a new one when RSF_* change)."""
        held = self._stores
        if held is None or held[0] is not settings:
            held = self._stores = (settings, stores_for(settings))
        return held[1]

    async def serve(self, scope: AsgiScope, data: bytes) -> Response | None:
        """The cached answer of this request (None: let the app answer it)."""
        known = self._keys.get(self._memo_key(scope, data))
        if known is None:
            return None
        key, need = known
        settings = get_settings()
        stores = self._stores_of(settings)
        hot = hot_for(stores)
        if not hot.holds(key):
            return None

        async def receive() -> dict[str, Any]:
            return {"type": "http.request", "body": data, "more_body": False}

        request = Request(scope, receive)
        try:
            creds = await auth.bearer(request)
            await auth.authorize(request, creds, settings, stores.keys, need)
        except Exception:  # noqa: BLE001 - refusals and database errors: the app answers
            return None
        text = hot.get(key)
        if text is None:  # forgotten meanwhile
            return None
        self.served += 1
        return Response(
            body(text, key, True), media_type="application/json", headers={"X-Cache": "hit"}
        )


def deferred(key: str, status: str = "running") -> Response:
    """202 with ``Location: /v1/results/{key}`` to poll."""
    loc = f"/v1/results/{key}"
    return Response(
        json.dumps({"status": status, "cache_key": key, "location": loc}),
        status_code=202,
        media_type="application/json",
        headers={"Location": loc, "Retry-After": "2", "X-Cache": "miss"},
    )


async def _failed(stores: Stores, inflight: Inflight, key: str, msg: str) -> None:
    """Record a failure: in the job store (seen by every API process, for a request
    already answered 202) and in this process's recent failures."""
    inflight.fail(key, msg)
    try:
        await run_in_threadpool(stores.jobs.mark_failed, key, msg)
    except Exception:  # noqa: BLE001 - the client of this request still gets its 422
        log.warning("could not record the failure of %s", key)


async def _compute(
    kind: str,
    key: str,
    version: str,
    request: dict[str, Any],
    req: BaseModel,
    fn: Callable[[Any], dict[str, Any]],
    stores: Stores,
    queue: Queue,
    inflight: Inflight,
    queue_refusal: str | None = None,
) -> str | None:
    """Compute, store, return the result JSON text (None: sent to the queue);
    ProblemError on failure."""
    try:
        async with inflight.limiter:
            result = await run_in_threadpool(fn, req)
        text = canonical(result)
    except NeedsQueue:
        if queue_refusal is not None:  # not recorded: another key may queue it
            raise ProblemError(403, "Forbidden", queue_refusal) from None
        # a long integration: computed by a worker through the queue (result -> store)
        await run_in_threadpool(stores.jobs.mark_queued, key, kind)
        await run_in_threadpool(queue.send_single, kind, request, key, version)
        return None
    except ComputeError as exc:
        await _failed(stores, inflight, key, str(exc))
        raise ProblemError(422, "Could not be computed", str(exc)) from None
    except ParameterError as exc:
        await _failed(stores, inflight, key, str(exc))
        raise  # 422 naming the field (service.errors)
    except (TypeError, ValueError) as exc:  # non-JSON result: a bug, but never a 500
        await _failed(stores, inflight, key, str(exc))
        raise ProblemError(422, "Could not be computed", f"unserialisable result: {exc}") from None
    await run_in_threadpool(stores.results.put, key, kind, version, request, json.loads(text))
    hot_for(stores).put(key, text)
    return text


async def answer(
    kind: str,
    req: BaseModel,
    fn: Callable[[Any], dict[str, Any]],
    *,
    stores: Stores,
    queue: Queue,
    inflight: Inflight,
    settings: Settings,
    admission: Admission,
    queue_refusal: str | None = None,
) -> Response:
    """Cached answer to ``req`` of ``kind``, computing ``fn(req)`` on a miss.

    ``admission``: the request's admission; told the cache key, and asked for a lease
    and a token of the key before a fresh computation (429 if refused).
    ``queue_refusal``: when set, a query that outgrows the in-process step budget is not
    sent to the queue but answered 403 with that reason (keys without scope 'submit', or
    whose step budget quota is spent by the in-process attempt)."""
    request = req.model_dump(mode="json")
    version = numerics_version()
    key = cache_key(kind, request, version)
    admission.validated(key)
    hot = hot_for(stores)
    hit = hot.get(key)
    if hit is None:
        hit = await run_in_threadpool(stores.results.get_text, key)
        if hit is not None:
            hot.put(key, hit)
    if hit is not None:
        return Response(
            body(hit, key, True), media_type="application/json", headers={"X-Cache": "hit"}
        )
    queued = await run_in_threadpool(stores.jobs.status, key)
    if queued is not None:
        if queued.state is JobState.failed:
            raise ProblemError(422, "Could not be computed", queued.message)
        return deferred(key)
    await admission.admit()  # a fresh computation (or joining one): one token, or 429
    task = inflight.pending.get(key)
    if task is None:
        task = asyncio.ensure_future(
            _compute(kind, key, version, request, req, fn, stores, queue, inflight, queue_refusal)
        )
        inflight.pending[key] = task

        def _done(t: asyncio.Future[str | None], key: str = key) -> None:
            inflight.pending.pop(key, None)
            if (
                not t.cancelled()
                and t.exception() is not None
                and not isinstance(t.exception(), ProblemError)
            ):
                log.error("computation %s failed", key, exc_info=t.exception())

        task.add_done_callback(_done)
    try:
        text = await asyncio.wait_for(asyncio.shield(task), settings.inline_budget_s)
    except TimeoutError:
        # every API process answers GET /v1/results/{key} from the job store (202 while
        # queued, 422 once failed, the result once stored)
        await run_in_threadpool(stores.jobs.mark_queued, key, kind)
        return deferred(key)
    if text is None:
        return deferred(key)
    return Response(
        body(text, key, False), media_type="application/json", headers={"X-Cache": "miss"}
    )
