"""Long single queries computed by a worker: their state, shared by every process.

A single classify/trajectory query whose quick in-process attempt runs out of steps is
sent to the queue (task ``worker.tasks.compute_single``).  Its row here says it is
queued or has failed (with the message); its result, once computed, is in the result
store.  Writes are idempotent; the task is acknowledged late, so a worker killed mid-way
leaves the message to be delivered again.
"""

from __future__ import annotations

import enum
import time
from typing import NamedTuple

from sqlalchemy import select, update

from ..db.engine import Database, insert_ignore
from ..db.tables import jobs

__all__ = ["JobState", "JobStatus", "JobStore"]


class JobState(enum.StrEnum):
    """State of a queued single query."""

    queued = "queued"
    failed = "failed"


class JobStatus(NamedTuple):
    """State and failure message ('' unless failed)."""

    state: JobState
    message: str


class JobStore:
    """Queued single queries in ``db``."""

    def __init__(self, db: Database) -> None:
        self.db = db

    def mark_queued(self, key: str, kind: str) -> None:
        """Record that ``key`` was sent to the queue (no-op if already recorded)."""
        with self.db.write() as conn:
            insert_ignore(
                conn,
                jobs,
                {
                    "key": key,
                    "kind": kind,
                    "state": JobState.queued.value,
                    "message": "",
                    "updated_at": time.time(),
                },
            )

    def mark_failed(self, key: str, message: str) -> None:
        """Record that the worker could not compute ``key``."""
        with self.db.write() as conn:
            conn.execute(
                update(jobs)
                .where(jobs.c.key == key)
                .values(state=JobState.failed.value, message=message, updated_at=time.time())
            )

    def set_progress(self, key: str, message: str) -> None:
        """While ``key`` is queued (a worker is on it), record how far it got (a short
        text shown by GET /v1/fits/{key}); no effect once it failed."""
        with self.db.write() as conn:
            conn.execute(
                update(jobs)
                .where((jobs.c.key == key) & (jobs.c.state == JobState.queued.value))
                .values(message=message[:500], updated_at=time.time())
            )

    def status(self, key: str) -> JobStatus | None:
        """State of a queued single query, or None if it never was queued."""
        with self.db.read() as conn:
            row = conn.execute(
                select(jobs.c.state, jobs.c.message).where(jobs.c.key == key)
            ).first()
        return None if row is None else JobStatus(JobState(row[0]), str(row[1]))
