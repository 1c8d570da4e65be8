"""The Celery application of the workers: ``celery -A worker.celery_app:app worker``.

The app itself comes from :func:`rsfapp.queue.make_app` (the API sends with the same
configuration); this module registers the tasks (:mod:`worker.tasks`) and two signal
handlers: warm-up of rsfcore's kernels before the pool forks, and, when a worker is
ready, requeueing of sweep chunks that no live worker holds (the filesystem broker
deletes a message once delivered, so work held by a killed worker is resent here).
"""
from __future__ import annotations

import logging

from celery.signals import worker_init, worker_ready

from rsfapp.config import get_settings
from rsfapp.queue import Queue, make_app
from rsfapp.store import stores_for
from rsfapp.warmup import warm_up

__all__ = ["app"]
log = logging.getLogger("rsf.worker")

app = make_app()
app.conf.include = ["worker.tasks"]


@worker_init.connect
def _warm_up(**_kw: object) -> None:
    """Load rsfcore's compiled kernels once, before the pool forks."""
    warm_up()


@worker_ready.connect
def _requeue_unfinished(**_kw: object) -> None:
    """At worker start: requeue chunks of active sweeps that no live worker holds."""
    s = get_settings()
    try:
        sweeps = stores_for(s).sweeps
        n = sweeps.requeue(sweeps.stale_chunks(s.lease_s), Queue(s, app).send_chunk)
    except Exception:  # noqa: BLE001 - a worker must start even if this fails
        log.exception("requeue of unfinished chunks failed")
        return
    if n:
        log.warning("requeued %d unfinished sweep chunk(s)", n)
