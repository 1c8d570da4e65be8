"""The Celery producer: the application object and the two messages the API sends.

Default broker: kombu's filesystem transport under ``RSF_DATA_DIR/broker`` (nothing to
install), through :mod:`rsfapp.fsqueue` (atomic publish and claim; stock kombu lets a
consumer read a message file still being written and the worker dies).
``RSF_BROKER_URL=redis://...`` switches to Redis. Results are not kept by Celery: every
result lands in the application database. Tasks are acknowledged late and prefetched one
at a time. Task names are explicit strings (``worker.tasks.*``), so the producer needs
no import of the worker package and queued messages survive code moves.
"""

from __future__ import annotations

from typing import Any

from celery import Celery

from .config import Settings, get_settings
from .fsqueue import TRANSPORT_PATH

__all__ = ["Queue", "make_app", "RUN_CHUNK", "COMPUTE_SINGLE", "FIT_RECORD"]

#: Task names (stable: messages already queued must keep working).
RUN_CHUNK = "worker.tasks.run_chunk"
COMPUTE_SINGLE = "worker.tasks.compute_single"
FIT_RECORD = "worker.tasks.fit_record"


def make_app(settings: Settings | None = None) -> Celery:
    """A Celery app configured from ``settings`` (default: this process's settings)."""
    s = settings or get_settings()
    url = s.effective_broker_url
    fs = url.startswith("filesystem")
    a = Celery("rsf", broker=url)
    if fs:
        # the race-free subclass of kombu's filesystem transport (see rsfapp.fsqueue)
        a.conf.broker_transport = TRANSPORT_PATH
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
        task_publish_retry_policy={
            "max_retries": 3,
            "interval_start": 0.2,
            "interval_step": 0.5,
            "interval_max": 1.0,
        },
    )
    return a


class Queue:
    """Sends work to the workers through ``app`` on the queue of ``settings``."""

    def __init__(self, settings: Settings, app: Celery | None = None) -> None:
        self.settings = settings
        self.app = app or make_app(settings)

    def send_chunk(self, sweep_id: str, idx: int) -> None:
        """Enqueue chunk ``idx`` of sweep ``sweep_id``."""
        self.app.send_task(RUN_CHUNK, args=[sweep_id, idx], queue=self.settings.queue)

    def send_single(self, kind: str, request: dict[str, Any], key: str, version: str) -> None:
        """Enqueue a long single query (see :mod:`rsfapp.store.jobs`)."""
        self.app.send_task(
            COMPUTE_SINGLE, args=[kind, request, key, version], queue=self.settings.queue
        )

    def send_fit(self, request: dict[str, Any], key: str, version: str) -> None:
        """Enqueue the fit of a lab record (``request``: a FitRequest as JSON)."""
        self.app.send_task(FIT_RECORD, args=[request, key, version], queue=self.settings.queue)
