"""Long single queries computed by a worker: their state, shared by every process.

A single classify/trajectory query whose quick in-process attempt runs out of steps is
sent to the queue (task ``worker.tasks.compute_single``).  Its row here says it is
queued or has failed (with the message); its result, once computed, is in the cache.
Writes are idempotent; the task is acknowledged late, so a worker killed mid-way leaves
the message to be delivered again.
"""
from __future__ import annotations

import time

from sqlalchemy import Column, Float, String, Table, Text, select, update

from . import db

__all__ = ["jobs", "mark_queued", "mark_failed", "status"]

jobs = Table(
    "jobs", db.metadata,
    Column("key", String(64), primary_key=True),
    Column("kind", String(32), nullable=False),
    Column("state", String(16), nullable=False),  # queued | failed
    Column("message", Text, nullable=False, default=""),
    Column("updated_at", Float, nullable=False),
)


def mark_queued(key: str, kind: str) -> None:
    """Record that ``key`` was sent to the queue (no-op if already recorded)."""
    with db.write() as conn:
        db.insert_ignore(conn, jobs, {"key": key, "kind": kind, "state": "queued",
                                      "message": "", "updated_at": time.time()})


def mark_failed(key: str, message: str) -> None:
    """Record that the worker could not compute ``key``."""
    with db.write() as conn:
        conn.execute(update(jobs).where(jobs.c.key == key)
                     .values(state="failed", message=message, updated_at=time.time()))


def status(key: str) -> tuple[str, str] | None:
    """(state, message) of a queued single query, or None if it never was queued."""
    with db.read() as conn:
        row = conn.execute(select(jobs.c.state, jobs.c.message).where(jobs.c.key == key)).first()
    return None if row is None else (row[0], row[1])
