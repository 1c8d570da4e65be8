"""The Celery application, configured from :mod:`service.settings`.

Default broker: kombu's filesystem transport under ``RSF_DATA_DIR/broker`` (nothing to
install).  ``RSF_BROKER_URL=redis://...`` switches to Redis.  Results are not kept by
Celery: every result lands in the cache database.  Tasks are acknowledged late and
prefetched one at a time; since the filesystem transport deletes a message once
delivered, a worker also requeues, when it starts, the chunks that no live worker holds.
"""
from __future__ import annotations

import logging

from celery import Celery
from celery.signals import worker_init, worker_ready

from service.settings import get_settings

__all__ = ["app", "make_app", "send_chunk", "send_single"]
log = logging.getLogger("rsf.worker")


def make_app() -> Celery:
    """A Celery app for the current settings."""
    s = get_settings()
    url = s.effective_broker_url
    fs = url.startswith("filesystem")
    a = Celery("rsf", broker=url, include=["worker.tasks"])
    a.conf.update(
        broker_transport_options=s.broker_transport_options,
        broker_connection_retry_on_startup=True,
        broker_connection_timeout=5,
        task_default_queue=s.queue,
        task_acks_late=True,
        task_reject_on_worker_lost=True,
        task_ignore_result=True,
        task_serializer="json",
        accept_content=["json"],
        worker_prefetch_multiplier=1,
        worker_enable_remote_control=not fs,
        worker_send_task_events=False,
        task_publish_retry_policy={"max_retries": 3, "interval_start": 0.2,
                                   "interval_step": 0.5, "interval_max": 1.0},
    )
    return a


app = make_app()


def send_chunk(sweep_id: str, idx: int) -> None:
    """Enqueue chunk ``idx`` of sweep ``sweep_id``."""
    app.send_task("worker.tasks.run_chunk", args=[sweep_id, idx], queue=get_settings().queue)


def send_single(kind: str, request: dict, key: str, version: str) -> None:
    """Enqueue a long single query (see worker.jobs)."""
    app.send_task("worker.tasks.compute_single", args=[kind, request, key, version],
                  queue=get_settings().queue)


@worker_init.connect
def _warm_up(**_kw: object) -> None:
    """Load rsfcore's compiled kernels once, before the pool forks."""
    try:
        from rsfcore import critical, trajectory
        from rsfcore.params import Params
        trajectory.classify(Params(2.0, 0.5, 0.5, 1.0), "velocity-jump", 0.1)
        critical.critical_perturbation(Params(2.0, 1.5, 0.5, 1.0))
    except Exception:  # noqa: BLE001 - warm-up only
        log.exception("rsfcore warm-up failed")


@worker_ready.connect
def _requeue_unfinished(**_kw: object) -> None:
    """At worker start: requeue chunks of active sweeps that no live worker holds."""
    from . import sweeps
    try:
        n = sweeps.requeue(sweeps.stale_chunks(get_settings().lease_s), send_chunk)
    except Exception:  # noqa: BLE001 - a worker must start even if this fails
        log.exception("requeue of unfinished chunks failed")
        return
    if n:
        log.warning("requeued %d unfinished sweep chunk(s)", n)
