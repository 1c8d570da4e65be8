"""The Celery application of the workers: ``celery -A worker.celery_app:app worker``.

The app itself comes from :func:`rsfapp.queue.make_app` (the API sends with the same
configuration); this module registers the tasks (:mod:`worker.tasks`) and the signal
handlers: memory reuse (:mod:`rsfapp.memory`) and warm-up of rsfcore's kernels before
the pool forks; when a worker is ready,
requeueing of sweep chunks that no live worker holds (the filesystem broker deletes a
message once delivered, so work held by a killed worker is resent here) and the start
of its reaper thread (:class:`rsfapp.reaper.Reaper`: worker registry, chunks whose lease
expired, self-repair of sweeps), stopped at shutdown.
"""

from __future__ import annotations

import logging

from celery.signals import worker_init, worker_ready, worker_shutdown

from rsfapp import metrics
from rsfapp.config import get_settings
from rsfapp.memory import keep_freed_memory
from rsfapp.queue import Queue, make_app
from rsfapp.reaper import Reaper
from rsfapp.store import stores_for
from rsfapp.warmup import warm_up

__all__ = ["app"]
log = logging.getLogger("rsf.worker")

app = make_app()
app.conf.include = ["worker.tasks"]


@worker_init.connect  # type: ignore[untyped-decorator]
def _warm_up(**_kw: object) -> None:
    """Keep freed chunk memory for reuse (:mod:`rsfapp.memory`) and load rsfcore's
    compiled kernels once, before the pool forks."""
    keep_freed_memory()
    warm_up()


@worker_ready.connect  # type: ignore[untyped-decorator]
def _requeue_unfinished(**_kw: object) -> None:
    """At worker start: requeue chunks of active sweeps that no live worker holds."""
    s = get_settings()
    try:
        sweeps = stores_for(s).sweeps
        n = sweeps.requeue(sweeps.stale_chunks(s.lease_s), Queue(s, app).send_chunk)
    except Exception:  # noqa: BLE001 - a worker must start even if this fails
        log.exception("requeue of unfinished chunks failed")
        return
    metrics.REQUEUES.labels(metrics.Requeue.worker_start).inc(n)
    if n:
        log.warning("requeued %d unfinished sweep chunk(s)", n)


_reaper: list[Reaper] = []


@worker_ready.connect  # type: ignore[untyped-decorator]
def _start_reaper(sender: object = None, **_kw: object) -> None:
    """Start this worker's reaper thread (in the main process, not the pool children)."""
    s = get_settings()
    name = str(getattr(sender, "hostname", "") or f"{s.node}")
    pool = getattr(sender, "pool", None)
    conc = int(getattr(pool, "num_processes", 0) or app.conf.worker_concurrency or 1)
    r = Reaper(s, name, conc, Queue(s, app).send_chunk)
    r.start()
    _reaper.append(r)


@worker_ready.connect  # type: ignore[untyped-decorator]
def _serve_metrics(**_kw: object) -> None:
    """With RSF_METRICS_PORT: serve /metrics of this worker (its pool processes added up
    through PROMETHEUS_MULTIPROC_DIR, which `rsf worker` sets) on that port, no key."""
    s = get_settings()
    if s.metrics_port:
        from prometheus_client import start_http_server

        start_http_server(s.metrics_port, s.metrics_host, registry=metrics.registry())
        log.info("metrics on http://%s:%d/metrics", s.metrics_host, s.metrics_port)


@worker_shutdown.connect  # type: ignore[untyped-decorator]
def _stop_reaper(**_kw: object) -> None:
    """Stop the reaper and leave the worker registry."""
    while _reaper:
        _reaper.pop().stop()
