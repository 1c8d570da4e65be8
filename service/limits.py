"""Bounds applied before a request is parsed, and per-key rate limits (ASGI middleware).

:class:`Limits`, in this order, for every HTTP request:

1. headers larger than ``RSF_MAX_HEADER_BYTES`` in all -> 431;
2. a body larger than ``RSF_MAX_BODY_BYTES`` (``RSF_MAX_BODY_BYTES_BATCH`` for the batch
   and fit endpoints) -> 413.  A ``Content-Length`` above the limit is refused before a
   single body byte is read; a chunked body is counted as it streams and refused as
   soon as it passes the limit;
3. per API key, on the endpoints that may compute (single queries, batch, fit,
   figures): at most ``concurrent_requests`` in flight, and fresh computations limited
   to ``fresh_per_s`` per second by a token bucket (burst ``max(1, fresh_per_s)``).  A
   request is charged after its answer, when the answer was computed rather than read
   from the cache (``X-Cache: miss``) or deferred (202); a key whose bucket is empty gets
   429 + ``Retry-After`` (seconds until one token is back) on those endpoints until it
   refills.  Cached lookups of other keys, and every other endpoint, are never slowed
   by it.  Anonymous requests (loopback without keys, ``RSF_AUTH=off``) are not limited.

All refusals are ``application/problem+json``.  The buckets live in this API process
(one uvicorn process per deployment in the shipped configurations).

CORS (:func:`install`) is off unless ``RSF_CORS_ORIGINS`` lists allowed origins.
"""

from __future__ import annotations

import hashlib
import math
import re
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from fastapi import FastAPI
from starlette.exceptions import HTTPException
from starlette.middleware.cors import CORSMiddleware
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from rsfapp.config import Settings, get_settings
from rsfapp.store.keys import Quotas

from .errors import problem

__all__ = ["Bucket", "COMPUTING_PREFIXES", "Limits", "install", "is_computing"]

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


@dataclass
class Bucket:
    """Token bucket of one key: ``quotas.fresh_per_s`` tokens per second, capacity
    max(1, rate).

    ``tokens`` may go negative (charges are made after the answer); the key is refused
    until it is back to >= 1.
    """

    quotas: Quotas
    tokens: float = math.nan  # nan: start full
    stamp: float = field(default_factory=time.monotonic)

    def __post_init__(self) -> None:
        if math.isnan(self.tokens):
            self.tokens = self.capacity

    @property
    def rate(self) -> float:
        """Fresh computations per second [1/s]."""
        return self.quotas.fresh_per_s

    @property
    def capacity(self) -> float:
        """Largest burst (tokens)."""
        return max(1.0, self.rate)

    def level(self, now: float | None = None) -> float:
        """Tokens now (refilled since the last update)."""
        t = time.monotonic() if now is None else now
        self.tokens = min(self.capacity, self.tokens + (t - self.stamp) * self.rate)
        self.stamp = t
        return self.tokens

    def wait_s(self, now: float | None = None) -> float:
        """Seconds until one token is available (0 if available now)."""
        lv = self.level(now)
        return 0.0 if lv >= 1.0 else (1.0 - lv) / self.rate

    def charge(self, n: float = 1.0) -> None:
        """Take ``n`` tokens (may go below zero)."""
        self.level()
        self.tokens -= n


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


class Limits:
    """The ASGI middleware described in the module docstring.

    Args:
        app: the wrapped application.
        settings: callable returning the current settings (read on every request).
        max_keys: rate-limit buckets kept (least recently used are forgotten).
    """

    def __init__(
        self, app: ASGIApp, settings: Callable[[], Settings] = get_settings, max_keys: int = 10_000
    ) -> None:
        self.app, self.settings, self.max_keys = app, settings, max_keys
        self.buckets: OrderedDict[str, Bucket] = OrderedDict()
        self.inflight: dict[str, int] = {}

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

        kid = _key_id(scope) if is_computing(path) else None
        if kid is not None:
            b = self.buckets.get(kid)
            if b is not None:
                quotas = b.quotas
                if self.inflight.get(kid, 0) >= quotas.concurrent_requests:
                    await self._refuse(
                        scope,
                        receive,
                        send,
                        429,
                        "Too many requests",
                        "too many requests of this key in flight (quota "
                        f"concurrent_requests = {quotas.concurrent_requests})",
                        {"Retry-After": "1"},
                    )
                    return
                wait = b.wait_s()
                if wait > 0:
                    await self._refuse(
                        scope,
                        receive,
                        send,
                        429,
                        "Too many requests",
                        "fresh computations of this key exceed its quota "
                        f"(fresh_per_s = {b.rate:g})",
                        {"Retry-After": str(max(1, math.ceil(wait)))},
                    )
                    return
            await self._tracked(kid, scope, receive, _allow_fixed(scope, send))
            return
        await self.app(scope, receive, _allow_fixed(scope, send))

    async def _tracked(self, kid: str, scope: Scope, receive: Receive, send: Send) -> None:
        seen: dict[str, Any] = {"status": 0, "fresh": False}

        async def watch(msg: Message) -> None:
            if msg["type"] == "http.response.start":
                seen["status"] = msg["status"]
                for k, v in msg.get("headers", ()):
                    if k.lower() == b"x-cache" and v == b"miss":
                        seen["fresh"] = True
            await send(msg)

        self.inflight[kid] = self.inflight.get(kid, 0) + 1
        try:
            await self.app(scope, receive, watch)
        finally:
            n = self.inflight.get(kid, 1) - 1
            if n > 0:
                self.inflight[kid] = n
            else:
                self.inflight.pop(kid, None)
            self._charge(scope, kid, bool(seen["fresh"]) or seen["status"] == 202)

    def _charge(self, scope: Scope, kid: str, fresh: bool) -> None:
        p = scope.get("rsf.principal")
        if p is None or getattr(p, "key_id", None) != kid:
            return  # not authenticated with this key: nothing to account
        q: Quotas = p.quotas
        b = self.buckets.get(kid)
        if b is None or b.quotas != q:
            b = self.buckets[kid] = Bucket(q) if b is None else Bucket(q, b.tokens, b.stamp)
        self.buckets.move_to_end(kid)
        while len(self.buckets) > self.max_keys:
            self.buckets.popitem(last=False)
        if fresh:
            b.charge(1.0)


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
    app.add_middleware(Limits)
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
