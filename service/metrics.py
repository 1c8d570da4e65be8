"""Prometheus metrics of the API: the request middleware and ``GET /metrics``.

Every request is counted (``rsf_http_requests_total{route, method, status}``) and timed
(``rsf_http_request_duration_seconds{route, method}``) by a pure ASGI middleware, labelled
by the matched route's template (``/v1/sweeps/{sweep_id}``, so the label set stays
bounded; ``unmatched`` for unknown paths).  ``GET /metrics`` answers the text exposition
of :mod:`rsfapp.metrics` (every API process and worker sharing the multi-process
directory) and the deployment's state (:class:`rsfapp.metrics_state.StateCollector`); it
is in the schema, so it needs a key with scope ``read`` whenever keys are on (or use
``RSF_METRICS_PORT``: docs/operations.md).
"""

from __future__ import annotations

import time
from typing import Any

from fastapi import APIRouter, FastAPI
from starlette.concurrency import run_in_threadpool
from starlette.responses import Response
from starlette.routing import Match, Route
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from rsfapp import metrics
from rsfapp.metrics_state import StateCollector

from .deps import SettingsDep

__all__ = ["MetricsMiddleware", "install", "router"]

router = APIRouter(tags=["meta"])


@router.get(
    "/metrics",
    summary="Prometheus metrics (text exposition format)",
    response_class=Response,
    responses={
        200: {
            "description": "Counters, histograms and gauges in the Prometheus text format "
            "0.0.4 (names and labels: docs/operations.md).",
            "content": {metrics.CONTENT_TYPE: {"schema": {"type": "string"}}},
        }
    },
)
async def get_metrics(settings: SettingsDep) -> Response:
    """Request counts and latencies, cache hits and misses, sweep points and chunk
    durations, lease expiries and requeues, fits (from every API process and worker that
    shares this process's multi-process directory), and the deployment's queue depth,
    sweeps by status and live workers per host (read from the database and broker now)."""
    body = await run_in_threadpool(metrics.render, StateCollector(settings))
    return Response(body, media_type=metrics.CONTENT_TYPE)


class MetricsMiddleware:
    """Counts and times every HTTP request by route template, method and status.

    A request answered before routing (a cached answer served from memory by
    :class:`service.answer.FastHits`) is labelled by matching its path against
    ``owner``'s routes."""

    def __init__(self, app: ASGIApp, owner: FastAPI) -> None:
        self.app, self.owner = app, owner
        self._flat: list[Route] | None = None

    def _routes(self) -> list[Route]:
        """The owner's routes, routers included without a prefix flattened (this app
        includes every router so)."""
        if self._flat is None:
            out: list[Route] = []
            todo: list[Any] = list(self.owner.router.routes)
            while todo:
                r = todo.pop(0)
                inner = getattr(r, "original_router", None)
                if inner is not None:
                    todo[:0] = list(inner.routes)
                elif isinstance(r, Route):
                    out.append(r)
            self._flat = out
        return self._flat

    def _route(self, scope: Scope) -> str:
        route: Any = scope.get("route")
        if route is not None:
            return str(getattr(route, "path", metrics.UNMATCHED))
        for r in self._routes():
            if r.matches(scope)[0] == Match.FULL:
                return r.path
        return metrics.UNMATCHED

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        t0 = time.perf_counter()
        status = [500]

        async def _send(message: Message) -> None:
            if message["type"] == "http.response.start":
                status[0] = int(message["status"])
            await send(message)

        try:
            await self.app(scope, receive, _send)
        finally:
            path = self._route(scope)
            method = str(scope.get("method", ""))
            metrics.REQUESTS.labels(path, method, str(status[0])).inc()
            metrics.REQUEST_SECONDS.labels(path, method).observe(time.perf_counter() - t0)


def install(app: FastAPI) -> None:
    """Add the middleware (outermost, so every answer is counted) and the route."""
    app.add_middleware(MetricsMiddleware, owner=app)
    app.include_router(router)
