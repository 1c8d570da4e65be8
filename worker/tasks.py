"""Celery tasks: compute one chunk of a sweep, or one long single query.

A chunk is a range [i0, i1) of flat point indices of the sweep's spec
(:class:`rsfapp.grid.SweepSpec`); a grid's chunk is computed by one compiled call that
generates its parameters from the axes and reports the arrays that are one repeated value
(:func:`rsfapp.sweepdata.compute_block` -> :func:`rsfcore.batch.critical_grid`; scattered
points: batch calls on cache-sized parts), and its results stored as one compressed block,
written once (a chunk delivered twice, or recomputed after its worker was killed, is
stored once).  A task goes on with the sweep's next pending chunks, claimed in work units
(:func:`unit_chunks`) in the transaction that completes the unit before (chunk chaining,
:meth:`rsfapp.store.SweepStore.complete_run`), for about ``RSF_CHUNK_SECONDS``; then
it sends the sweep's next pending chunk to the queue (lazy dispatch), where it waits its
turn behind other sweeps' chunks.  Task names are stable strings
(:data:`rsfapp.queue.RUN_CHUNK`, ...).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any

from celery import Task
from kombu.exceptions import OperationalError as KombuOperationalError
from pydantic import BaseModel

from rsfapp import adapter, metrics, requests
from rsfapp.config import get_settings
from rsfapp.db.engine import diagnose
from rsfapp.queue import COMPUTE_SINGLE, FIT_RECORD, RUN_CHUNK, Queue
from rsfapp.reaper import Lease
from rsfapp.store import stores_for
from rsfapp.store.sweeps import BlockData
from rsfapp.sweepdata import compute_block

from .celery_app import app

__all__ = [
    "ChainPosition",
    "UNIT_MAX_BYTES",
    "UNIT_MAX_CHUNKS",
    "UNIT_SECONDS",
    "unit_chunks",
    "run_chunk",
    "run_chunk_body",
    "compute_single",
    "fit_record",
    "fit_record_body",
]
log = logging.getLogger("rsf.worker")


#: A task computes the chunks it chains in work units: runs of the sweep's next pending
#: chunks claimed together, computed one after the other and completed in one
#: transaction (:meth:`rsfapp.store.SweepStore.complete_run`), so a chunk of cheap points
#: (10^6 points, ~35 ms of kernel) does not pay a transaction of its own (~1.5-2 ms of the
#: worker's CPU and ~1 ms of PostgreSQL's).  The stored block (a Zarr chunk) keeps its
#: size; only the work between two transactions grows.  A unit holds about this many
#: seconds of work [s] (measured on the unit before; a task's first chunk is a unit of
#: one), which bounds what a cancel waits for and what a killed worker loses ...
UNIT_SECONDS = 0.25
#: ... at most this many chunks ...
UNIT_MAX_CHUNKS = 16
#: ... and at most this many bytes of encoded blocks held until the transaction [B].
UNIT_MAX_BYTES = 32 << 20


def unit_chunks(seconds_per_chunk: float, bytes_per_chunk: float, left_s: float) -> int:
    """Chunks of a task's next work unit from the last unit's wall time and block bytes
    per chunk: about :data:`UNIT_SECONDS` of work and no more than the ``left_s``
    seconds the task still chains (rounded up), at most :data:`UNIT_MAX_CHUNKS` and
    :data:`UNIT_MAX_BYTES`; 0 when ``left_s`` <= 0 (the chain stops), else at least 1."""
    if left_s <= 0:
        return 0
    per = max(seconds_per_chunk, 1e-9)
    k = min(
        UNIT_MAX_CHUNKS,
        int(UNIT_SECONDS / per),
        math.ceil(left_s / per),
        int(UNIT_MAX_BYTES / max(bytes_per_chunk, 1.0)),
    )
    return max(1, k)


@dataclass
class ChainPosition:
    """The chunk a task is on (its message's chunk, then each chunk it chains to: an
    error is retried on this chunk, :func:`run_chunk`) and the chunks of its work unit
    not completed yet (given back on an error)."""

    idx: int
    held: list[int] = field(default_factory=list)


def run_chunk_body(
    sweep_id: str, idx: int, chain_s: float = 0.0, at: ChainPosition | None = None
) -> dict[str, Any]:
    """Compute and store chunk ``idx``, then, while the task has run less than
    ``chain_s`` seconds, the sweep's next pending chunks in work units
    (:func:`unit_chunks`); returns a small summary (also for direct calls, which compute
    one chunk by default).

    A chunk of a cancelled sweep is skipped; a chunk already running elsewhere is left to
    its worker; a chunk whose block is already stored is only marked done.  Cancellation
    therefore takes effect within one work unit per worker process.  One transaction to
    claim the message's chunk, then one per unit (:meth:`rsfapp.store.SweepStore.complete_run`:
    its blocks, done marks, counters, the sweep closed when complete, and either the next
    unit claimed for this task or, when the chain stops, the next chunks marked queued
    and sent to the broker).  ``at`` follows the chunk being computed and the unit held.
    """
    s = get_settings()
    sweeps = stores_for(s).sweeps
    at = at or ChainPosition(idx)
    t_start = time.monotonic()
    rng = sweeps.claim(sweep_id, idx, s.lease_s)
    if rng is None:
        metrics.CHUNKS.labels(metrics.ChunkResult.skipped).inc()
        return {"skipped": True}
    n_chunks = n_points = n_stored = 0
    unit = [rng]
    while unit:
        at.held = [r.idx for r in unit]
        t_unit = time.monotonic()
        run: list[tuple[int, BlockData | None]] = []
        results: list[metrics.ChunkResult] = []
        n_bytes = 0
        # the unit's leases are renewed while it computes (rsfapp.reaper)
        with Lease(partial(sweeps.heartbeat, sweep_id, *at.held), s.heartbeat_s):
            for r in unit:
                at.idx = r.idx
                if r.stored:
                    run.append((r.idx, None))
                    results.append(metrics.ChunkResult.stored)
                    continue
                spec = sweeps.get_spec(sweep_id)
                if spec is None:  # deleted meanwhile, or stored in the pre-array layout
                    for i in at.held:
                        sweeps.finish_chunk(sweep_id, i, complete=False)
                    at.held = []
                    metrics.CHUNKS.labels(metrics.ChunkResult.skipped).inc()
                    return {"skipped": True, "chunks": n_chunks, "points": n_points}
                t0 = time.perf_counter()
                data, errors = compute_block(spec, r.i0, r.i1)
                metrics.CHUNK_SECONDS.observe(time.perf_counter() - t0)
                metrics.POINTS.labels("ok").inc(r.i1 - r.i0 - len(errors))
                metrics.POINTS.labels("failed").inc(len(errors))
                run.append((r.idx, (r.i0, r.i1, data, errors)))
                results.append(metrics.ChunkResult.computed)
                n_bytes += len(data)
        now = time.monotonic()
        k = unit_chunks((now - t_unit) / len(unit), n_bytes / len(unit), chain_s - (now - t_start))
        done = sweeps.complete_run(sweep_id, run, s.sweep_window, k, s.lease_s)
        for res in results:
            metrics.CHUNKS.labels(res).inc()
        n_chunks += len(unit)
        n_points += sum(r.i1 - r.i0 for r in unit)
        n_stored += done.stored
        if done.todo:
            q = Queue(s, app)
            for c in done.todo:
                q.send_chunk(sweep_id, c)
        unit = done.next
    at.held = []
    return {"stored": n_stored, "chunks": n_chunks, "points": n_points}


@app.task(name=RUN_CHUNK, bind=True, acks_late=True, reject_on_worker_lost=True, max_retries=5)
def run_chunk(self: Task, sweep_id: str, idx: int) -> dict[str, Any]:
    """Celery entry point: the message's chunk, then chained ones for about
    ``RSF_CHUNK_SECONDS``.  On an infrastructure error (e.g. DB locked) the chunk being
    computed is released and the task retried later on that chunk."""
    at = ChainPosition(idx)
    try:
        return run_chunk_body(sweep_id, idx, get_settings().chunk_seconds, at)
    except Exception as exc:  # noqa: BLE001
        metrics.CHUNKS.labels(metrics.ChunkResult.error).inc()
        # backoff 2, 4, 8, 16, 30, 30, ... s.  The database or broker being down is an
        # outage, not a defect of the chunk: one log line, and retried until it is back
        # (the message is never dropped); any other error: a traceback, 5 retries.
        delay = min(2.0 * 2**self.request.retries, 30.0)
        outage = diagnose(exc) is not None or isinstance(
            exc, (OSError, ConnectionError, KombuOperationalError)
        )
        if outage:
            log.warning(
                "chunk %s/%d: %s; retrying in %.0f s",
                sweep_id,
                at.idx,
                str(exc).strip().splitlines()[0] if str(exc) else type(exc).__name__,
                delay,
            )
        else:
            log.exception("chunk %s/%d failed; retrying in %.0f s", sweep_id, at.idx, delay)
        try:
            stores_for(get_settings()).sweeps.release_chunk(sweep_id, at.idx, at.held)
        except Exception as exc2:  # noqa: BLE001 - the reaper takes it back after the lease
            log.warning(
                "could not release chunk %s/%d: %s",
                sweep_id,
                at.idx,
                str(exc2).strip().splitlines()[0] if str(exc2) else "",
            )
        raise self.retry(
            args=(sweep_id, at.idx),
            exc=exc,
            countdown=delay,
            max_retries=None if outage else 5,
        ) from exc


_SINGLE: dict[str, tuple[type[BaseModel], Callable[..., dict[str, Any]]]] = {
    "classify": (requests.ClassifyRequest, adapter.classify),
    "trajectory": (requests.TrajectoryRequest, adapter.trajectory),
}


@app.task(name=COMPUTE_SINGLE, acks_late=True)
def compute_single(kind: str, request: dict[str, Any], key: str, version: str) -> None:
    """A long single query (classify or trajectory) with rsfcore's full step budget;
    the result lands in the result store under ``key``, a failure in the job store."""
    st = stores_for(get_settings())
    if st.results.get(key) is not None:  # delivered again after it was already done
        return
    model, fn = _SINGLE[kind]
    try:
        result = fn(model.model_validate(request), max_steps=None)
    except Exception as exc:  # noqa: BLE001 - every failure is recorded for the client
        log.warning("single query %s failed: %s", key, exc)
        st.jobs.mark_failed(key, f"{type(exc).__name__}: {exc}")
        return
    st.results.put(key, kind, version, request, result)


def fit_record_body(request: dict[str, Any], key: str, version: str) -> None:
    """Fit one lab record (rsfapp.adapter.fit); the result lands in the result store under
    ``key`` (stored request: the options and the record's hash, not the record), a
    failure in the job store (for GET /v1/fits/{key})."""
    from rsfapp.requests.fits import FitRequest

    st = stores_for(get_settings())
    if st.results.get(key) is not None:  # delivered again after it was already done
        return
    try:
        req = FitRequest.model_validate(request)
        summary = adapter.fit_key_request(req)
        result = adapter.fit(req, progress=lambda text: st.jobs.set_progress(key, text))
    except Exception as exc:  # noqa: BLE001 - every failure is recorded for the client
        log.warning("fit %s failed: %s", key, exc)
        st.jobs.mark_failed(key, f"{type(exc).__name__}: {exc}")
        return
    st.results.put(key, "fit", version, summary, result)


@app.task(name=FIT_RECORD, acks_late=True)
def fit_record(request: dict[str, Any], key: str, version: str) -> None:
    """Celery entry point of :func:`fit_record_body` (POST /v1/fits)."""
    fit_record_body(request, key, version)
