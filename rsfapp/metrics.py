"""Prometheus metrics of the API and the workers: every name defined once, here.

Counters and histograms are kept per process; where several processes serve one
endpoint (``rsf api --workers N``, a worker's prefork pool, ``rsf serve``'s API and
embedded worker) ``rsf`` points ``PROMETHEUS_MULTIPROC_DIR`` at a private empty directory
before the processes start, and prometheus-client's multi-process collector adds up their
files at each scrape (:func:`render`).  Run uvicorn or Celery by hand with several
processes and you must set it yourself (an empty directory per deployment and host).
State that lives in the database or the broker (queue depth, sweeps by status, live
workers per host) is read at scrape time by :class:`rsfapp.metrics_state.StateCollector`.

Names (``_total`` is appended to counters in the exposition), units in the name:

* ``rsf_http_requests_total{route, method, status}``, ``rsf_http_request_duration_seconds
  {route, method}``: API requests by route template (``unmatched`` for unknown paths);
* ``rsf_cache_lookups_total{result="hit"|"miss"}``: result-cache lookups;
* ``rsf_sweep_points_total{result="ok"|"failed"}``: sweep points computed (``rate()``
  is points per second); ``rsf_sweep_chunks_total{result}``; ``rsf_sweep_chunk_duration
  _seconds``: compute time of one chunk;
* ``rsf_lease_expiries_total``: running chunks whose lease expired (worker died or hung);
  ``rsf_chunk_requeues_total{reason="lease_expired"|"repair"|"lost_message"|
  "worker_start"}``: chunks sent to the queue again;
* ``rsf_fits_total{result="ok"|"error"}``, ``rsf_fit_duration_seconds``: lab-record fits.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from enum import StrEnum

from prometheus_client import (
    CollectorRegistry,
    Counter,
    Histogram,
    disable_created_metrics,
    generate_latest,
)
from prometheus_client import multiprocess as _mp
from prometheus_client import values as _values
from prometheus_client.exposition import CONTENT_TYPE_LATEST
from prometheus_client.metrics_core import Metric
from prometheus_client.registry import Collector

__all__ = [
    "CACHE_LOOKUPS",
    "CHUNKS",
    "CHUNK_SECONDS",
    "CONTENT_TYPE",
    "ChunkResult",
    "FITS",
    "FIT_SECONDS",
    "LEASE_EXPIRIES",
    "POINTS",
    "REQUESTS",
    "REQUEST_SECONDS",
    "REQUEUES",
    "Requeue",
    "UNMATCHED",
    "multiprocess_dir",
    "registry",
    "render",
    "timed_fit",
]

#: Content-Type of the text exposition format.
CONTENT_TYPE = CONTENT_TYPE_LATEST
#: route label of a request that matched no route (keeps the label set bounded).
UNMATCHED = "unmatched"

disable_created_metrics()  # type: ignore[no-untyped-call]  # no *_created series (start times nobody queries)

# Every metric is created on this registry; it is scraped directly in a single process and
# through the files of every process in multi-process mode (see :func:`registry`).
_OWN = CollectorRegistry(auto_describe=True)

#: Latency buckets [s]: cached answers take ~1 ms, fresh ones up to the inline budget.
_HTTP_BUCKETS = (0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30)
#: Chunk buckets [s]: chunks aim at RSF_CHUNK_SECONDS (default 2 s, at most 600 s).
_CHUNK_BUCKETS = (0.1, 0.25, 0.5, 1, 2, 4, 8, 15, 30, 60, 120, 300, 600)
#: Fit buckets [s]: a least-squares fit ~0.1-10 s, with law comparison and posterior more.
_FIT_BUCKETS = (0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30, 60, 120, 300, 900)


class ChunkResult(StrEnum):
    """What became of a chunk task."""

    computed = "computed"  # computed and stored here
    stored = "stored"  # its block was already stored (computed twice), marked done
    skipped = "skipped"  # cancelled, deleted or held by another worker
    error = "error"  # raised (retried later)


class Requeue(StrEnum):
    """Why a chunk was sent to the queue again."""

    lease_expired = "lease_expired"  # its worker stopped renewing the lease
    repair = "repair"  # a sweep with nothing in flight got its next chunks
    lost_message = "lost_message"  # queued for longer than a lease, broker queue empty
    worker_start = "worker_start"  # a starting worker took back work no live worker holds


REQUESTS = Counter(
    "rsf_http_requests",
    "HTTP requests answered by the API, by route template, method and status code.",
    ["route", "method", "status"],
    registry=_OWN,
)
REQUEST_SECONDS = Histogram(
    "rsf_http_request_duration_seconds",
    "Time from request to the end of the response [s], by route template and method.",
    ["route", "method"],
    buckets=_HTTP_BUCKETS,
    registry=_OWN,
)
CACHE_LOOKUPS = Counter(
    "rsf_cache_lookups",
    "Result-cache lookups by result (hit or miss).",
    ["result"],
    registry=_OWN,
)
POINTS = Counter(
    "rsf_sweep_points",
    "Sweep points computed by the workers, by result (ok, or failed with a message).",
    ["result"],
    registry=_OWN,
)
CHUNKS = Counter(
    "rsf_sweep_chunks",
    "Sweep chunk tasks run by the workers, by what became of them.",
    ["result"],
    registry=_OWN,
)
CHUNK_SECONDS = Histogram(
    "rsf_sweep_chunk_duration_seconds",
    "Compute time of one sweep chunk [s].",
    buckets=_CHUNK_BUCKETS,
    registry=_OWN,
)
LEASE_EXPIRIES = Counter(
    "rsf_lease_expiries",
    "Running sweep chunks whose lease expired (their worker died or hung).",
    registry=_OWN,
)
REQUEUES = Counter(
    "rsf_chunk_requeues",
    "Sweep chunks sent to the queue again, by reason.",
    ["reason"],
    registry=_OWN,
)
FITS = Counter(
    "rsf_fits",
    "Fits of lab records, by result (ok, or error).",
    ["result"],
    registry=_OWN,
)
FIT_SECONDS = Histogram(
    "rsf_fit_duration_seconds",
    "Duration of one fit of a lab record [s] (with law comparison and posterior if asked).",
    buckets=_FIT_BUCKETS,
    registry=_OWN,
)

# Children appear in the exposition at 0 from the start (a rate is defined before the
# first event, and a dashboard shows 0 rather than "no data").
for _r in ("hit", "miss"):
    CACHE_LOOKUPS.labels(_r)
for _r in ("ok", "failed"):
    POINTS.labels(_r)
for _c in ChunkResult:
    CHUNKS.labels(_c.value)
for _q in Requeue:
    REQUEUES.labels(_q.value)
for _r in ("ok", "error"):
    FITS.labels(_r)


def multiprocess_dir() -> str | None:
    """The multi-process directory of this process (None: single-process mode, i.e.
    ``PROMETHEUS_MULTIPROC_DIR`` was not set when prometheus-client was first imported)."""
    if _values.ValueClass is _values.MutexValue:
        return None
    return os.environ.get("PROMETHEUS_MULTIPROC_DIR") or None


class _Own(Collector):
    def collect(self) -> Iterable[Metric]:
        return _OWN.collect()


def registry(*extra: Collector) -> CollectorRegistry:
    """A registry to scrape: this process's metrics (or, in multi-process mode, those of
    every process sharing the directory) plus ``extra`` collectors."""
    reg = CollectorRegistry(auto_describe=False)
    if multiprocess_dir() is not None:
        _mp.MultiProcessCollector(reg)  # type: ignore[no-untyped-call]
    else:
        reg.register(_Own())
    for c in extra:
        reg.register(c)
    return reg


def render(*extra: Collector) -> bytes:
    """The text exposition of :func:`registry` (``extra`` collectors included)."""
    return generate_latest(registry(*extra))


@contextmanager
def timed_fit() -> Iterator[None]:
    """Count one fit and observe its duration; an exception counts as ``error``."""
    t0 = time.perf_counter()
    try:
        yield
    except BaseException:
        FITS.labels("error").inc()
        raise
    finally:
        FIT_SECONDS.observe(time.perf_counter() - t0)
    FITS.labels("ok").inc()
