"""Celery tasks: compute one chunk of a sweep and store its points.

A chunk is a range [i0, i1) of flat grid indices (idx = i * n_y + j).  Points already
stored (from a killed earlier attempt) are skipped; writes are idempotent, so a chunk
may safely run again.  Cancellation is checked between points (the DB at most every
0.2 s).
"""
from __future__ import annotations

import logging
import time
from typing import Any

from service.settings import get_settings

from . import sweeps
from .celery_app import app
from .sweep_compute import compute_point

__all__ = ["run_chunk", "compute_single"]
log = logging.getLogger("rsf.worker")


class _CancelProbe:
    """Callable telling whether the sweep was cancelled, polling the DB at most every dt."""

    def __init__(self, sweep_id: str, dt: float = 0.2) -> None:
        self.sweep_id, self.dt, self.t, self.state = sweep_id, dt, 0.0, False

    def __call__(self) -> bool:
        now = time.monotonic()
        if not self.state and now - self.t >= self.dt:
            self.t = now
            self.state = sweeps.is_cancelled(self.sweep_id)
        return self.state


def run_chunk_body(sweep_id: str, idx: int) -> dict[str, Any]:
    """Compute and store one chunk; returns a small summary (also for direct calls).

    Points are computed one by one (a failing point is recorded and the others go on)
    and flushed to the database every 0.5 s or 500 points, so a killed worker loses at
    most that much work; cancellation is checked between points.
    """
    s = get_settings()
    rng = sweeps.claim(sweep_id, idx, s.lease_s)
    if rng is None:
        return {"skipped": True}
    i0, i1 = rng
    spec = sweeps.get_spec(sweep_id)
    xs, ys = spec["x"]["values"], spec["y"]["values"]
    ny = len(ys)
    have = sweeps.done_indices(sweep_id, i0, i1)
    probe = _CancelProbe(sweep_id)
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
        buf.append(dict(compute_point(spec, xs[i], ys[j]), idx=k, i=i, j=j, x=xs[i], y=ys[j]))
        if len(buf) >= 500 or time.monotonic() - t_flush > 0.5:
            n_new += sweeps.store_points(sweep_id, idx, buf)
            buf, t_flush = [], time.monotonic()
    n_new += sweeps.store_points(sweep_id, idx, buf)
    sweeps.finish_chunk(sweep_id, idx, complete=True)
    return {"stored": n_new}


@app.task(name="worker.tasks.run_chunk", bind=True, acks_late=True,
          reject_on_worker_lost=True, max_retries=5)
def run_chunk(self, sweep_id: str, idx: int) -> dict[str, Any]:  # noqa: ANN001
    """Celery entry point; on an infrastructure error (e.g. DB locked) retry later."""
    try:
        return run_chunk_body(sweep_id, idx)
    except Exception as exc:  # noqa: BLE001
        log.exception("chunk %s/%d failed; retrying", sweep_id, idx)
        try:
            from sqlalchemy import and_, update

            from . import db
            with db.write() as conn:
                conn.execute(update(sweeps.chunks).where(and_(
                    sweeps.chunks.c.sweep_id == sweep_id, sweeps.chunks.c.idx == idx,
                    sweeps.chunks.c.status == "running")).values(status="queued", owner=None))
        except Exception:  # noqa: BLE001
            log.exception("could not release chunk %s/%d", sweep_id, idx)
        raise self.retry(exc=exc, countdown=2.0)


@app.task(name="worker.tasks.compute_single", acks_late=True)
def compute_single(kind: str, request: dict[str, Any], key: str, version: str) -> None:
    """A long single query (classify or trajectory) with rsfcore's full step budget;
    the result lands in the cache under ``key``, a failure in :mod:`worker.jobs`."""
    from service import compute, schemas

    from . import cache, jobs

    if cache.get(key) is not None:  # delivered again after it was already done
        return
    model = {"classify": schemas.ClassifyRequest, "trajectory": schemas.TrajectoryRequest}[kind]
    fn = {"classify": compute.classify, "trajectory": compute.trajectory}[kind]
    try:
        result = fn(model.model_validate(request), max_steps=None)
    except Exception as exc:  # noqa: BLE001 - every failure is recorded for the client
        log.warning("single query %s failed: %s", key, exc)
        jobs.mark_failed(key, f"{type(exc).__name__}: {exc}")
        return
    cache.put(key, kind, version, request, result)
