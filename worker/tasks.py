"""Celery tasks: compute one chunk of a sweep, or one long single query.

A chunk is a range [i0, i1) of flat grid indices (idx = i * n_y + j).  Points already
stored (from a killed earlier attempt) are skipped; writes are idempotent, so a chunk
may safely run again.  Cancellation is checked between points (the database at most
every 0.2 s).  Task names are stable strings (:data:`rsfapp.queue.RUN_CHUNK`, ...).
"""
from __future__ import annotations

import logging
import time
from typing import Any

from celery import Task

from rsfapp import adapter, requests
from rsfapp.config import get_settings
from rsfapp.queue import COMPUTE_SINGLE, RUN_CHUNK
from rsfapp.store import SweepStore, stores_for

from .celery_app import app

__all__ = ["run_chunk", "run_chunk_body", "compute_single"]
log = logging.getLogger("rsf.worker")


class _CancelProbe:
    """Callable telling whether the sweep was cancelled, polling the DB at most every dt."""

    def __init__(self, sweeps: SweepStore, sweep_id: str, dt: float = 0.2) -> None:
        self.sweeps, self.sweep_id, self.dt = sweeps, sweep_id, dt
        self.t, self.state = 0.0, False

    def __call__(self) -> bool:
        now = time.monotonic()
        if not self.state and now - self.t >= self.dt:
            self.t = now
            self.state = self.sweeps.is_cancelled(self.sweep_id)
        return self.state


def run_chunk_body(sweep_id: str, idx: int) -> dict[str, Any]:
    """Compute and store one chunk; returns a small summary (also for direct calls).

    Points are computed one by one (a failing point is recorded and the others go on)
    and flushed to the database every 0.5 s or 500 points, so a killed worker loses at
    most that much work; cancellation is checked between points.
    """
    s = get_settings()
    sweeps = stores_for(s).sweeps
    rng = sweeps.claim(sweep_id, idx, s.lease_s)
    if rng is None:
        return {"skipped": True}
    i0, i1 = rng
    spec = sweeps.get_spec(sweep_id)
    if spec is None:  # deleted meanwhile
        return {"skipped": True}
    xs, ys = spec["x"]["values"], spec["y"]["values"]
    ny = len(ys)
    have = sweeps.done_indices(sweep_id, i0, i1)
    probe = _CancelProbe(sweeps, sweep_id)
    buf: list[dict[str, Any]] = []
    n_new = 0
    t_flush = time.monotonic()
    for k in range(i0, i1):
        if k in have:
            continue
        if probe():
            n_new += sweeps.store_points(sweep_id, idx, buf)
            sweeps.finish_chunk(sweep_id, idx, complete=False)
            return {"cancelled": True, "stored": n_new}
        i, j = divmod(k, ny)
        buf.append(dict(adapter.compute_point(spec, xs[i], ys[j]), idx=k, i=i, j=j, x=xs[i],
                        y=ys[j]))
        if len(buf) >= 500 or time.monotonic() - t_flush > 0.5:
            n_new += sweeps.store_points(sweep_id, idx, buf)
            buf, t_flush = [], time.monotonic()
    n_new += sweeps.store_points(sweep_id, idx, buf)
    sweeps.finish_chunk(sweep_id, idx, complete=True)
    return {"stored": n_new}


@app.task(name=RUN_CHUNK, bind=True, acks_late=True, reject_on_worker_lost=True,
          max_retries=5)
def run_chunk(self: Task, sweep_id: str, idx: int) -> dict[str, Any]:
    """Celery entry point; on an infrastructure error (e.g. DB locked) retry later."""
    try:
        return run_chunk_body(sweep_id, idx)
    except Exception as exc:  # noqa: BLE001
        log.exception("chunk %s/%d failed; retrying", sweep_id, idx)
        try:
            stores_for(get_settings()).sweeps.release_chunk(sweep_id, idx)
        except Exception:  # noqa: BLE001
            log.exception("could not release chunk %s/%d", sweep_id, idx)
        raise self.retry(exc=exc, countdown=2.0) from exc


_SINGLE = {
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
        result = fn(model.model_validate(request), max_steps=None)  # type: ignore[attr-defined]
    except Exception as exc:  # noqa: BLE001 - every failure is recorded for the client
        log.warning("single query %s failed: %s", key, exc)
        st.jobs.mark_failed(key, f"{type(exc).__name__}: {exc}")
        return
    st.results.put(key, kind, version, request, result)
