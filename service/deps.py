"""FastAPI dependencies: settings, stores, queue and in-flight bookkeeping.

Handlers declare what they need with these ``Annotated`` types; tests replace any of
them with ``app.dependency_overrides`` (e.g. a store on a temporary database, a queue
that records messages).  The providers are ``async def`` although they do no I/O: a
plain ``def`` dependency is run in the thread pool, one thread hop per dependency and
request, which cost a cached lookup more than its database read.
"""

from __future__ import annotations

import asyncio
import os
import threading
from dataclasses import dataclass, field
from typing import Annotated

import anyio
from fastapi import Depends, Request

from rsfapp.config import Settings, get_settings
from rsfapp.queue import Queue
from rsfapp.store import Stores, stores_for

__all__ = [
    "Inflight",
    "InflightDep",
    "QueueDep",
    "SettingsDep",
    "StoresDep",
    "get_inflight",
    "get_queue",
    "get_settings_dep",
    "get_stores",
]


async def get_settings_dep() -> Settings:
    """This process's settings."""
    return get_settings()


SettingsDep = Annotated[Settings, Depends(get_settings_dep)]


async def get_stores(settings: SettingsDep) -> Stores:
    """The result, job and sweep stores of the configured database."""
    return stores_for(settings)


StoresDep = Annotated[Stores, Depends(get_stores)]

_queues: dict[tuple[int, str, str], Queue] = {}
_qlock = threading.Lock()


async def get_queue(settings: SettingsDep) -> Queue:
    """The Celery producer for the configured broker and queue (one per process)."""
    key = (os.getpid(), settings.effective_broker_url, settings.queue)
    with _qlock:
        q = _queues.get(key)
        if q is None:
            q = _queues[key] = Queue(settings)
    return q


QueueDep = Annotated[Queue, Depends(get_queue)]


@dataclass
class Inflight:
    """Computations running in this API process (a local optimisation only).

    ``limiter`` bounds this process's compute threads (one per CPU); ``pending`` lets
    identical requests arriving at this process join one computation; ``failed`` is a
    local copy of recent failures.  Nothing here is needed by another process: a
    deferred computation is recorded in the job store (queued / failed with its message)
    and its result in the result store (:mod:`service.answer`), so any API process
    answers GET /v1/results/{key} the same.
    """

    limiter: anyio.CapacityLimiter = field(
        default_factory=lambda: anyio.CapacityLimiter(max(2, os.cpu_count() or 2))
    )
    pending: dict[str, asyncio.Future[str | None]] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)
    max_failed: int = 1000

    def fail(self, key: str, msg: str) -> None:
        """Remember that ``key`` failed with ``msg`` (forgetting the oldest beyond max)."""
        self.failed[key] = msg
        while len(self.failed) > self.max_failed:
            self.failed.pop(next(iter(self.failed)))


async def get_inflight(request: Request) -> Inflight:
    """The app's :class:`Inflight` (created in the lifespan, or on first use)."""
    inflight = getattr(request.app.state, "inflight", None)
    if inflight is None:
        inflight = request.app.state.inflight = Inflight()
    return inflight


InflightDep = Annotated[Inflight, Depends(get_inflight)]
