"""Bounds applied before a request is parsed, and per-key rate limits (ASGI middleware).

:class:`Limits`, in this order, for every HTTP request:

1. headers larger than ``RSF_MAX_HEADER_BYTES`` in all -> 431;
2. a body larger than ``RSF_MAX_BODY_BYTES`` (``RSF_MAX_BODY_BYTES_BATCH`` for the batch
   and fit endpoints) -> 413.  A ``Content-Length`` above the limit is refused before a
   single body byte is read; a chunked body is counted as it streams and refused as
   soon as it passes the limit;
3. per API key, on the endpoints that may compute (single queries, batch, fit,
   figures): at most ``concurrent_requests`` computing requests in flight over every API
   process and host (leases in the database, :mod:`rsfapp.store.inflight`), and fresh
   computations limited to ``fresh_per_s`` per second by a token bucket (burst
   ``max(1, fresh_per_s)``) shared by every API process and host: it lives in the
   database (:mod:`rsfapp.store.ratelimits`, one atomic statement per change).  A key
   whose bucket is empty gets 429 + ``Retry-After`` (seconds until one token is back)
   instead of a fresh computation;
4. a cached lookup of a single query seen before by this process is answered from
   memory without routing, validation or dependencies (:class:`service.answer.FastHits`),
   after the same authentication as every request.

Only fresh computations touch the bucket, and cached lookups never do:

* single queries (:data:`SELF_ADMITTED`, answered by :func:`service.answer.answer`)
  take a token atomically once the answer is known not to be cached, just before
  computing (or joining an identical computation, or queueing), and are refused 429 if
  there is none;
* the other computing endpoints (batch, fits, figures, protocols) cannot tell before
  their work whether it will be fresh: :func:`service.auth.guard` refuses them 429 while
  the key's bucket is empty (one read), and the middleware charges one token after an
  answer that was computed (``X-Cache: miss``) or deferred (202); the level may go below
  zero, and the key waits until it is back to >= 1.

The in-flight count (``concurrent_requests``) counts the requests that compute, as a
lease each (:class:`FreshGate`): one row in the database, taken atomically only while
the key holds fewer than its quota (else 429 + ``Retry-After: 1``), renewed every
``RSF_REQUEST_LEASE_S / 3`` while the request runs and deleted just before the last part
of its answer is sent (so the client's next request never finds it), or in a
``finally`` when the request ends otherwise (a lease left by a process that died stops
counting after ``RSF_REQUEST_LEASE_S``):

* a single query (:data:`SELF_ADMITTED`) takes its lease together with its token, once
  it is known to compute (or join a computation, or queue): a cached lookup takes none
  (it is answered in ~100 us from memory and cannot pile up, and a lease would cost two
  database writes on every lookup);
* the other computing endpoints take theirs in :func:`service.auth.guard`, before their
  work, and hold it for the whole request, cached or not (they cannot tell before).

Anonymous requests (loopback without keys, ``RSF_AUTH=off``) are not limited.

All refusals are ``application/problem+json``.

CORS (:func:`install`) is off unless ``RSF_CORS_ORIGINS`` lists allowed origins.
"""

from __future__ import annotations

import asyncio
import hashlib
import logging
import math
import re
from collections.abc import Callable
from contextvars import ContextVar
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import anyio
from fastapi import FastAPI
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException
from starlette.middleware.cors import CORSMiddleware
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from rsfapp.config import Settings, get_settings
from rsfapp.db.engine import Database
from rsfapp.store.inflight import InflightStore
from rsfapp.store.ratelimits import RateLimitStore

from .errors import problem

if TYPE_CHECKING:
    from .answer import FastHits

__all__ = [
    "COMPUTING_PREFIXES",
    "FreshGate",
    "Limits",
    "QuotaError",
    "RequestState",
    "SELF_ADMITTED",
    "inflight_store_for",
    "install",
    "is_computing",
    "rate_store_for",
    "request_state",
]
log = logging.getLogger("rsf.service")

#: Paths whose answers may be computed (and so count as fresh computations).
COMPUTING_PREFIXES = (
    "/v1/classify",
    "/v1/trajectory",
    "/v1/critical",
    "/v1/analytic",
    "/v1/boundaries",
    "/v1/stiffness",
    "/v1/figures/",
    "/v1/fit",
)
#: Single-query paths answered by :func:`service.answer.answer`, which takes a token
#: itself just before a fresh computation (no read of the bucket before).
SELF_ADMITTED = frozenset(
    {
        "/v1/classify",
        "/v1/classify/points",
        "/v1/trajectory",
        "/v1/critical",
        "/v1/analytic/u",
        "/v1/boundaries",
        "/v1/stiffness",
    }
)
_EXPOSED = [
    "Location",
    "Retry-After",
    "X-Cache",
    "X-Cache-Key",
    "X-Sweep-Status",
    "X-Sweep-Progress",
    "WWW-Authenticate",
]


def is_computing(path: str) -> bool:
    """True for the endpoints subject to the fresh-computation quota."""
    return path.startswith(COMPUTING_PREFIXES) or path.endswith("/batch")


def _is_batch(path: str) -> bool:
    # sweeps too: scattered points (up to RSF_SWEEP_MAX_SCATTERED) travel in the body
    return (
        path.endswith(("/batch", "/points")) or path.startswith("/v1/fit") or path == "/v1/sweeps"
    )


class QuotaError(Exception):
    """429 answered as problem+json with ``Retry-After`` (handler in :mod:`service.auth`)."""

    def __init__(self, detail: str, retry_after: int) -> None:
        super().__init__(detail)
        self.detail, self.retry_after = detail, retry_after


_rate_stores: dict[int, RateLimitStore] = {}


def rate_store_for(db: Database) -> RateLimitStore:
    """The token buckets of ``db`` (one store per database and process)."""
    st = _rate_stores.get(id(db))
    if st is None or st.db is not db:
        st = _rate_stores[id(db)] = RateLimitStore(db)
    return st


_inflight_stores: dict[int, InflightStore] = {}


def inflight_store_for(db: Database) -> InflightStore:
    """The in-flight leases of ``db`` (one store per database and process)."""
    st = _inflight_stores.get(id(db))
    if st is None or st.db is not db:
        st = _inflight_stores[id(db)] = InflightStore(db)
    return st


class FreshGate:
    """The fresh-computation bucket and the in-flight lease of one key, for one request
    (made by :func:`service.auth.guard` once the key is authenticated; the middleware
    releases the lease when the request ends).

    Args:
        store: the token buckets.
        key_id: SHA-256 of the key.
        rate: the key's quota ``fresh_per_s`` [1/s], > 0.
        slots: the in-flight leases (None: ``concurrent_requests`` not enforced).
        quota: the key's quota ``concurrent_requests``, >= 1.
        lease_s: lease length [s], > 0 (``RSF_REQUEST_LEASE_S``).
    """

    def __init__(
        self,
        store: RateLimitStore,
        key_id: str,
        rate: float,
        slots: InflightStore | None = None,
        quota: int = 1,
        lease_s: float = 30.0,
    ) -> None:
        self.store, self.key_id, self.rate = store, key_id, rate
        self.slots, self.quota, self.lease_s = slots, quota, lease_s
        #: True once this request took or was charged its token.
        self.taken = False
        #: the lease this request holds, if any
        self.lease_id: str | None = None
        self._renewer: asyncio.Task[None] | None = None

    async def hold(self) -> None:
        """Take a lease on one of the key's ``concurrent_requests`` (at most once per
        request; renewed until :meth:`release`).

        Raises:
            QuotaError: the key already has ``concurrent_requests`` leases (429 with
                ``Retry-After: 1``).
        """
        if self.slots is None or self.lease_id is not None:
            return
        lease = await run_in_threadpool(self.slots.acquire, self.key_id, self.quota, self.lease_s)
        if not lease.admitted:
            raise QuotaError(
                "too many requests of this key in flight (quota "
                f"concurrent_requests = {self.quota})",
                retry_after=1,
            )
        self.lease_id = lease.lease_id
        self._renewer = asyncio.get_running_loop().create_task(self._renew(lease.lease_id))

    async def _renew(self, lease_id: str | None) -> None:
        slots = self.slots
        assert slots is not None and lease_id is not None
        while True:
            await asyncio.sleep(self.lease_s / 3.0)
            try:
                if not await run_in_threadpool(slots.renew, lease_id, self.lease_s):
                    return  # expired (the database was out of reach for a whole lease)
            except Exception:  # noqa: BLE001 - try again at the next beat
                log.warning("could not renew the lease of a request in flight", exc_info=True)

    async def release(self) -> None:
        """Give the lease back (if one is held); never raises, and runs to the end even
        when the request is cancelled (a lease that could not be deleted expires)."""
        lease_id, self.lease_id = self.lease_id, None
        if self._renewer is not None:
            self._renewer.cancel()
            self._renewer = None
        if lease_id is None or self.slots is None:
            return
        with anyio.CancelScope(shield=True):
            try:
                await run_in_threadpool(self.slots.release, lease_id)
            except Exception:  # noqa: BLE001 - the lease expires by itself
                log.warning("could not release the lease of a request", exc_info=True)

    def _refusal(self, wait_s: float) -> QuotaError:
        return QuotaError(
            f"fresh computations of this key exceed its quota (fresh_per_s = {self.rate:g})",
            retry_after=max(1, math.ceil(wait_s)),
        )

    async def admit(self) -> None:
        """Take a lease (:meth:`hold`), then one token, before a fresh computation (each
        at most once per request); the lease is given back if there is no token.

        Raises:
            QuotaError: too many requests of the key in flight, or its bucket is empty
                (429 with ``Retry-After``).
        """
        if self.taken:
            return
        await self.hold()
        adm = await run_in_threadpool(self.store.take, self.key_id, self.rate)
        if not adm.admitted:
            await self.release()
            raise self._refusal(adm.wait_s)
        self.taken = True

    async def check(self) -> None:
        """Refuse (QuotaError) while the bucket is empty; reads only."""
        wait = await run_in_threadpool(self.store.wait_s, self.key_id, self.rate)
        if wait > 0:
            raise self._refusal(wait)

    async def charge(self) -> None:
        """Charge one token after a fresh answer (unless one was taken before)."""
        if not self.taken:
            self.taken = True
            await run_in_threadpool(self.store.charge, self.key_id, self.rate)


@dataclass
class RequestState:
    """What the layers of one request to a computing endpoint tell the middleware.

    Attributes:
        key_id: SHA-256 of the bearer token sent, if any.
        gate: the key's bucket and in-flight lease, set by :func:`service.auth.guard` once
            authenticated (the middleware releases the lease when the request ends).
        need: the scope the guard checked (value of :class:`rsfapp.store.keys.Scope`).
        cache_key: set by :func:`service.answer.answer` once the request is validated.
    """

    key_id: str | None = None
    gate: FreshGate | None = None
    need: str | None = None
    cache_key: str | None = None


_state: ContextVar[RequestState | None] = ContextVar("rsf_request_state", default=None)


def request_state() -> RequestState | None:
    """The :class:`RequestState` of the request being handled (None outside a computing
    endpoint)."""
    return _state.get()


def _header(scope: Scope, name: bytes) -> bytes | None:
    for k, v in scope.get("headers", ()):
        if k == name:
            return bytes(v)
    return None


def _key_id(scope: Scope) -> str | None:
    """SHA-256 of the bearer token, if any (the same id :mod:`service.auth` records)."""
    auth = _header(scope, b"authorization")
    if not auth:
        return None
    scheme, _, token = auth.partition(b" ")
    if scheme.lower() != b"bearer" or not token.strip():
        return None
    # as service.auth sees it: Starlette decodes headers as latin-1, hash_key encodes UTF-8
    return hashlib.sha256(token.strip().decode("latin-1").encode("utf-8")).hexdigest()


async def _buffer(receive: Receive) -> tuple[list[Message], bytes | None]:
    """Read the whole body: (messages read, body; None if the client went away)."""
    msgs: list[Message] = []
    chunks: list[bytes] = []
    while True:
        msg = await receive()
        msgs.append(msg)
        if msg["type"] != "http.request":
            return msgs, None
        chunks.append(msg.get("body", b""))
        if not msg.get("more_body", False):
            return msgs, b"".join(chunks)


def _replay(msgs: list[Message], receive: Receive) -> Receive:
    """``receive`` that returns ``msgs`` first, then reads on."""
    pending = list(msgs)

    async def wrapped() -> Message:
        return pending.pop(0) if pending else await receive()

    return wrapped


class Limits:
    """The ASGI middleware described in the module docstring.

    Args:
        app: the wrapped application.
        settings: callable returning the current settings (read on every request).
        fast: cached lookups answered from memory (None: off).

    It keeps no state about keys: the leases and buckets are in the database.
    """

    def __init__(
        self,
        app: ASGIApp,
        settings: Callable[[], Settings] = get_settings,
        fast: FastHits | None = None,
    ) -> None:
        self.app, self.settings, self.fast = app, settings, fast

    async def _refuse(
        self,
        scope: Scope,
        receive: Receive,
        send: Send,
        status: int,
        title: str,
        detail: str,
        headers: dict[str, str] | None = None,
    ) -> None:
        await problem(status, title, detail, headers=headers)(scope, receive, send)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        s = self.settings()
        path: str = scope.get("path", "")
        hbytes = sum(len(k) + len(v) + 4 for k, v in scope.get("headers", ()))
        if hbytes > s.max_header_bytes:
            await self._refuse(
                scope,
                receive,
                send,
                431,
                "Request header fields too large",
                f"the request headers total {hbytes} bytes; the limit is {s.max_header_bytes}",
            )
            return
        limit = s.max_body_bytes_batch if _is_batch(path) else s.max_body_bytes
        cl = _header(scope, b"content-length")
        if cl is not None:
            if not cl.strip().isdigit():
                await self._refuse(
                    scope, receive, send, 400, "Bad request", "invalid Content-Length header"
                )
                return
            if int(cl) > limit:
                await self._refuse(
                    scope,
                    receive,
                    send,
                    413,
                    "Request body too large",
                    f"the body has {int(cl)} bytes; the limit of this endpoint is {limit} bytes",
                )
                return
        else:
            receive = _counting(receive, limit)

        if not is_computing(path):
            await self.app(scope, receive, _allow_fixed(scope, send))
            return
        await self._computing(scope, receive, _allow_fixed(scope, send), _key_id(scope), cl)

    async def _computing(
        self, scope: Scope, receive: Receive, send: Send, kid: str | None, cl: bytes | None
    ) -> None:
        """A request to a computing endpoint: a cached lookup answered from memory, or
        the app, with the fresh-computation bookkeeping of :class:`RequestState`."""
        fast = self.fast
        body: bytes | None = None
        if (
            fast is not None
            and cl is not None
            and int(cl) <= fast.max_body
            and scope.get("method") == "POST"
            and not scope.get("query_string")
            and scope.get("path") in SELF_ADMITTED
            and fast.usable(scope)
        ):
            msgs, body = await _buffer(receive)
            receive = _replay(msgs, receive)
            if body is not None:
                resp = await fast.serve(scope, body)
                if resp is not None:
                    await resp(scope, receive, send)
                    return
        seen: dict[str, Any] = {"status": 0, "fresh": False, "json": False}
        state = RequestState(key_id=kid)

        async def watch(msg: Message) -> None:
            if msg["type"] == "http.response.start":
                seen["status"] = msg["status"]
                for k, v in msg.get("headers", ()):
                    k = k.lower()
                    if k == b"x-cache" and v == b"miss":
                        seen["fresh"] = True
                    elif k == b"content-type" and v == b"application/json":
                        seen["json"] = True
            elif (
                msg["type"] == "http.response.body"
                and not msg.get("more_body", False)
                and state.gate is not None
            ):
                # before the client has the whole answer: its next request must find
                # the lease given back
                await state.gate.release()
            await send(msg)

        token = _state.set(state)
        try:
            await self.app(scope, receive, watch)
        finally:
            _state.reset(token)
            try:
                await self._after(scope, state, bool(seen["fresh"]) or seen["status"] == 202)
            finally:
                if state.gate is not None:
                    await state.gate.release()
        if (
            fast is not None
            and body is not None
            and seen["status"] == 200
            and seen["json"]
            and state.cache_key is not None
            and state.need is not None
        ):
            fast.remember(scope, body, state.cache_key, state.need)

    async def _after(self, scope: Scope, state: RequestState, fresh: bool) -> None:
        """Charge a fresh answer not admitted before."""
        p = scope.get("rsf.principal")
        kid = state.key_id
        if kid is None or p is None or getattr(p, "key_id", None) != kid:
            return  # not authenticated with this key: nothing to account
        if fresh and state.gate is not None and not state.gate.taken:
            try:
                await state.gate.charge()
            except Exception:  # noqa: BLE001 - the answer is sent; never fail it now
                log.warning("could not charge a fresh computation to its key", exc_info=True)


_allow_cache: dict[int, list[tuple[re.Pattern[str], set[str]]]] = {}


def _methods_by_path(app: Any) -> list[tuple[re.Pattern[str], set[str]]]:
    """(path regex, methods) of every path of ``app``'s OpenAPI schema (built once)."""
    table = _allow_cache.get(id(app))
    if table is None:
        table = []
        for path, item in app.openapi().get("paths", {}).items():
            rx = re.compile("^" + re.sub(r"\\\{[^}]+\\\}", "[^/]+", re.escape(path)) + "$")
            methods = {m.upper() for m in item if m in _HTTP_METHODS}
            table.append((rx, methods))
        _allow_cache[id(app)] = table
    return table


_HTTP_METHODS = ("get", "put", "post", "delete", "patch", "head", "options")


def _allow_fixed(scope: Scope, send: Send) -> Send:
    """``send`` that lists, in the ``Allow`` of a 405, every method of the path in the
    OpenAPI schema (Starlette lists only those of the first route matching the path)."""

    async def wrapped(msg: Message) -> None:
        if msg["type"] == "http.response.start" and msg["status"] == 405:
            app, path = scope.get("app"), scope.get("path", "")
            methods: set[str] = set()
            if hasattr(app, "openapi"):
                for rx, ms in _methods_by_path(app):
                    if rx.match(path):
                        methods |= ms
            if methods:
                hdrs = [(k, v) for k, v in msg.get("headers", ()) if k.lower() != b"allow"]
                hdrs.append((b"allow", ", ".join(sorted(methods)).encode()))
                msg = {**msg, "headers": hdrs}
        await send(msg)

    return wrapped


def _counting(receive: Receive, limit: int) -> Receive:
    """``receive`` that raises 413 as soon as more than ``limit`` body bytes arrived."""
    total = 0

    async def wrapped() -> Message:
        nonlocal total
        msg = await receive()
        if msg["type"] == "http.request":
            total += len(msg.get("body", b""))
            if total > limit:
                raise HTTPException(
                    413, f"the body exceeds the limit of this endpoint ({limit} bytes)"
                )
        return msg

    return wrapped


def install(app: FastAPI, settings: Settings | None = None) -> None:
    """Add :class:`Limits` and, if origins are configured, CORS (outermost) to ``app``."""
    from .answer import FastHits  # here: service.answer imports this module

    s = settings or get_settings()
    app.add_middleware(Limits, fast=FastHits())
    origins = s.cors_origin_list
    if origins:
        app.add_middleware(
            CORSMiddleware,
            allow_origins=origins,
            allow_methods=["GET", "POST", "DELETE"],
            allow_headers=["Authorization", "Content-Type"],
            expose_headers=_EXPOSED,
            max_age=600,
        )
