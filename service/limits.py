"""Bounds applied before a request is parsed, and per-key admission (ASGI middleware).

:class:`Limits`, in this order, for every HTTP request:

1. headers larger than ``RSF_MAX_HEADER_BYTES`` in all -> 431;
2. a body larger than ``RSF_MAX_BODY_BYTES`` (``RSF_MAX_BODY_BYTES_BATCH`` for the batch
   and fit endpoints) -> 413.  A ``Content-Length`` above the limit is refused before a
   single body byte is read; a chunked body is counted as it streams and refused as
   soon as it passes the limit;
3. on the endpoints that may compute (single queries, batch, fit, figures): the
   request's :class:`service.admission.Admission`, kept in its ASGI scope and handed to
   the guard and the handlers as a dependency.  Per API key, at most
   ``concurrent_requests`` computing requests are in flight over every API process and
   host (leases in the database, :mod:`rsfapp.store.inflight`), and fresh computations
   are limited to ``fresh_per_s`` per second by a token bucket (burst
   ``max(1, fresh_per_s)``) shared by every API process and host: it lives in the
   database (:mod:`rsfapp.store.ratelimits`, one atomic statement per change).  A key
   whose bucket is empty gets 429 + ``Retry-After`` (seconds until one token is back)
   instead of a fresh computation;
4. a cached lookup of a single query seen before by this process is answered from
   memory without routing, validation or dependencies (:class:`service.answer.FastHits`),
   after the same authentication as every request.

Only fresh computations touch the bucket, and cached lookups never do:

* single queries (:data:`service.admission.SELF_ADMITTED`, answered by
  :func:`service.answer.answer`) take a token atomically once the answer is known not
  to be cached, just before computing (or joining an identical computation, or
  queueing), and are refused 429 if there is none;
* the other computing endpoints (batch, fits, figures, protocols) cannot tell before
  their work whether it will be fresh: :func:`service.auth.guard` refuses them 429 while
  the key's bucket is empty (one read), and this middleware charges one token after an
  answer that was computed (``X-Cache: miss``) or deferred (202); the level may go below
  zero, and the key waits until it is back to >= 1.

The in-flight count (``concurrent_requests``) counts the requests that compute, as a
lease each (:class:`service.admission.FreshGate`): one row in the database, taken
atomically only while the key holds fewer than its quota (else 429 + ``Retry-After:
1``), renewed every ``RSF_REQUEST_LEASE_S / 3`` while the request runs and deleted just
before the last part of its answer is sent (so the client's next request never finds
it), or when the request ends otherwise (a lease left by a process that died stops
counting after ``RSF_REQUEST_LEASE_S``):

* a single query takes its lease together with its token, once it is known to compute
  (or join a computation, or queue): a cached lookup takes none (it is answered in
  ~100 us from memory and cannot pile up, and a lease would cost two database writes on
  every lookup);
* the other computing endpoints take theirs in :func:`service.auth.guard`, before their
  work, and hold it for the whole request, cached or not (they cannot tell before).

Anonymous requests (loopback without keys, ``RSF_AUTH=off``) are not limited.

All refusals are ``application/problem+json``.

CORS (:func:`install`) is off unless ``RSF_CORS_ORIGINS`` lists allowed origins.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable
from typing import Any

from fastapi import FastAPI
from starlette.exceptions import HTTPException
from starlette.middleware.cors import CORSMiddleware
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from rsfapp.config import Settings, get_settings

from .admission import SELF_ADMITTED, Admission, is_computing
from .answer import FastHits
from .errors import problem

__all__ = ["Limits", "install"]
log = logging.getLogger("rsf.service")

_EXPOSED = [
    "Location",
    "Retry-After",
    "X-Cache",
    "X-Cache-Key",
    "X-Sweep-Status",
    "X-Sweep-Progress",
    "WWW-Authenticate",
]


def _is_batch(path: str) -> bool:
    # sweeps too: scattered points (up to RSF_SWEEP_MAX_SCATTERED) travel in the body
    return (
        path.endswith(("/batch", "/points")) or path.startswith("/v1/fit") or path == "/v1/sweeps"
    )


def _header(scope: Scope, name: bytes) -> bytes | None:
    for k, v in scope.get("headers", ()):
        if k == name:
            return bytes(v)
    return None


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
        await self._computing(scope, receive, _allow_fixed(scope, send), cl)

    async def _computing(
        self, scope: Scope, receive: Receive, send: Send, cl: bytes | None
    ) -> None:
        """A request to a computing endpoint: a cached lookup answered from memory, or
        the app, with the request's :class:`~service.admission.Admission` (made here,
        finished when the request ends)."""
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
        adm = Admission.begin(scope)

        async def watch(msg: Message) -> None:
            if msg["type"] == "http.response.start":
                seen["status"] = msg["status"]
                for k, v in msg.get("headers", ()):
                    k = k.lower()
                    if k == b"x-cache" and v == b"miss":
                        seen["fresh"] = True
                    elif k == b"content-type" and v == b"application/json":
                        seen["json"] = True
            elif msg["type"] == "http.response.body" and not msg.get("more_body", False):
                # before the client has the whole answer: its next request must find
                # the lease given back
                await adm.answered()
            await send(msg)

        try:
            await self.app(scope, receive, watch)
        finally:
            await adm.finish(bool(seen["fresh"]) or seen["status"] == 202)
        if (
            fast is not None
            and body is not None
            and seen["status"] == 200
            and seen["json"]
            and adm.cache_key is not None
            and adm.need is not None
        ):
            fast.remember(scope, body, adm.cache_key, adm.need)


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
