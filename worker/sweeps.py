"""Sweep bookkeeping in the cache database: sweeps, chunks and points.

Guarantees:
* every point is stored exactly once: primary key (sweep_id, idx), idempotent inserts;
* a chunk is claimed by one live worker at a time (owner = host:pid, heartbeat);
  a chunk whose owner died (SIGKILL) or whose lease expired is requeued at worker start;
* cancel marks the sweep; running chunks check it between points and stop;
* failures are points with an ``error`` message; the sweep goes on.
Flat index idx = i * n_y + j for x[i], y[j].
"""
from __future__ import annotations

import json
import os
import socket
import time
from typing import Any

from sqlalchemy import (Column, Float, ForeignKey, Integer, String, Table, Text, and_, func,
                        select, update)

from . import db

__all__ = ["sweeps", "chunks", "points", "create", "claim", "store_points", "finish_chunk",
           "is_cancelled", "cancel", "status", "list_sweeps", "page_points", "stale_chunks",
           "requeue", "done_indices", "owner_id", "get_spec"]

sweeps = Table(
    "sweeps", db.metadata,
    Column("id", String(64), primary_key=True),
    Column("spec", Text, nullable=False),
    Column("status", String(16), nullable=False),  # queued|running|done|cancelled
    Column("n_total", Integer, nullable=False),
    Column("n_chunks", Integer, nullable=False),
    Column("numerics_version", String(32), nullable=False),
    Column("created_at", Float, nullable=False),
    Column("started_at", Float),
    Column("finished_at", Float),
)
chunks = Table(
    "sweep_chunks", db.metadata,
    Column("sweep_id", String(64), ForeignKey("sweeps.id"), primary_key=True),
    Column("idx", Integer, primary_key=True),
    Column("i0", Integer, nullable=False),
    Column("i1", Integer, nullable=False),
    Column("status", String(16), nullable=False),  # queued|running|done|cancelled
    Column("owner", String(128)),
    Column("heartbeat", Float),
    Column("attempts", Integer, nullable=False, default=0),
)
points = Table(
    "sweep_points", db.metadata,
    Column("sweep_id", String(64), ForeignKey("sweeps.id"), primary_key=True),
    Column("idx", Integer, primary_key=True),
    Column("i", Integer, nullable=False),
    Column("j", Integer, nullable=False),
    Column("x", Float, nullable=False),
    Column("y", Float, nullable=False),
    Column("kind", String(16)),
    Column("critical_size", Float),
    Column("outcome", String(16)),
    Column("rel_accuracy", Float),
    Column("error", Text),
    Column("created_at", Float, nullable=False),
)


def owner_id() -> str:
    """This process as a chunk owner: 'host:pid'."""
    return f"{socket.gethostname()}:{os.getpid()}"


def _owner_alive(owner: str | None, heartbeat: float | None, lease_s: float) -> bool:
    if not owner:
        return False
    host, _, pid = owner.rpartition(":")
    if host == socket.gethostname():
        try:
            os.kill(int(pid), 0)
        except (ProcessLookupError, ValueError):
            return False
        except PermissionError:
            return True
        return True
    return heartbeat is not None and time.time() - heartbeat < lease_s


def create(sweep_id: str, spec: dict[str, Any], n_total: int, chunk_points: int,
           numerics_version: str) -> tuple[bool, list[int]]:
    """Create the sweep and its chunks unless it exists.

    Returns (created, chunk indices to enqueue).  An existing cancelled sweep is resumed
    (its unfinished chunks queued again); an existing active or done sweep enqueues
    nothing.
    """
    now = time.time()
    with db.write() as conn:
        row = conn.execute(select(sweeps.c.status).where(sweeps.c.id == sweep_id)).first()
        if row is None:
            n_chunks = -(-n_total // chunk_points)
            conn.execute(sweeps.insert().values(
                id=sweep_id, spec=json.dumps(spec, sort_keys=True), status="queued",
                n_total=n_total, n_chunks=n_chunks, numerics_version=numerics_version,
                created_at=now))
            conn.execute(chunks.insert(), [
                {"sweep_id": sweep_id, "idx": c, "i0": c * chunk_points,
                 "i1": min(n_total, (c + 1) * chunk_points), "status": "queued", "attempts": 0}
                for c in range(n_chunks)])
            return True, list(range(n_chunks))
        if row[0] != "cancelled":
            return False, []
        conn.execute(update(sweeps).where(sweeps.c.id == sweep_id).values(
            status="queued", finished_at=None))
        conn.execute(update(chunks).where(and_(chunks.c.sweep_id == sweep_id,
                                               chunks.c.status == "cancelled"))
                     .values(status="queued", owner=None))
        idx = conn.execute(select(chunks.c.idx).where(and_(
            chunks.c.sweep_id == sweep_id, chunks.c.status == "queued"))).scalars().all()
        return False, list(idx)


def get_spec(sweep_id: str) -> dict[str, Any] | None:
    """The stored spec of a sweep (None if unknown)."""
    with db.read() as conn:
        row = conn.execute(select(sweeps.c.spec).where(sweeps.c.id == sweep_id)).first()
    return None if row is None else json.loads(row[0])


def claim(sweep_id: str, idx: int, lease_s: float) -> tuple[int, int] | None:
    """Claim chunk ``idx`` for this process; (i0, i1) or None if nothing to do.

    Nothing to do: the sweep is unknown or cancelled, the chunk is done, or another live
    worker holds it.
    """
    me = owner_id()
    now = time.time()
    with db.write() as conn:
        s = conn.execute(select(sweeps.c.status).where(sweeps.c.id == sweep_id)).first()
        c = conn.execute(select(chunks).where(and_(chunks.c.sweep_id == sweep_id,
                                                   chunks.c.idx == idx))).first()
        if s is None or c is None or c.status in ("done", "cancelled"):
            return None
        if s.status == "cancelled":
            conn.execute(update(chunks).where(and_(chunks.c.sweep_id == sweep_id,
                                                   chunks.c.idx == idx))
                         .values(status="cancelled"))
            return None
        if c.status == "running" and c.owner != me and _owner_alive(c.owner, c.heartbeat,
                                                                      lease_s):
            return None
        conn.execute(update(chunks).where(and_(chunks.c.sweep_id == sweep_id,
                                               chunks.c.idx == idx)).values(
            status="running", owner=me, heartbeat=now, attempts=chunks.c.attempts + 1))
        conn.execute(update(sweeps).where(and_(sweeps.c.id == sweep_id,
                                               sweeps.c.status == "queued"))
                     .values(status="running", started_at=func.coalesce(sweeps.c.started_at,
                                                                       now)))
        return int(c.i0), int(c.i1)


def done_indices(sweep_id: str, i0: int, i1: int) -> set[int]:
    """Flat indices in [i0, i1) already stored."""
    with db.read() as conn:
        rows = conn.execute(select(points.c.idx).where(and_(
            points.c.sweep_id == sweep_id, points.c.idx >= i0, points.c.idx < i1))).scalars()
        return set(rows)


def store_points(sweep_id: str, chunk_idx: int, rows: list[dict[str, Any]]) -> int:
    """Insert point rows (idempotent) and refresh the chunk heartbeat; rows added."""
    now = time.time()
    for r in rows:
        r.setdefault("sweep_id", sweep_id)
        r.setdefault("created_at", now)
    with db.write() as conn:
        n = db.insert_ignore(conn, points, rows)
        conn.execute(update(chunks).where(and_(chunks.c.sweep_id == sweep_id,
                                               chunks.c.idx == chunk_idx))
                     .values(heartbeat=now))
    return n


def is_cancelled(sweep_id: str) -> bool:
    """True once the sweep has been cancelled."""
    with db.read() as conn:
        s = conn.execute(select(sweeps.c.status).where(sweeps.c.id == sweep_id)).scalar()
    return s == "cancelled"


def finish_chunk(sweep_id: str, idx: int, complete: bool) -> None:
    """Mark the chunk done (or cancelled if incomplete); close the sweep when all done."""
    now = time.time()
    with db.write() as conn:
        conn.execute(update(chunks).where(and_(chunks.c.sweep_id == sweep_id,
                                               chunks.c.idx == idx))
                     .values(status="done" if complete else "cancelled", heartbeat=now))
        left = conn.execute(select(func.count()).select_from(chunks).where(and_(
            chunks.c.sweep_id == sweep_id, chunks.c.status != "done"))).scalar()
        if left == 0:
            conn.execute(update(sweeps).where(sweeps.c.id == sweep_id)
                         .values(status="done", finished_at=now))


def cancel(sweep_id: str) -> str | None:
    """Cancel a sweep; returns its new status (None if unknown). Done sweeps stay done."""
    with db.write() as conn:
        s = conn.execute(select(sweeps.c.status).where(sweeps.c.id == sweep_id)).scalar()
        if s is None or s == "done":
            return s
        conn.execute(update(sweeps).where(sweeps.c.id == sweep_id)
                     .values(status="cancelled", finished_at=time.time()))
        conn.execute(update(chunks).where(and_(chunks.c.sweep_id == sweep_id,
                                               chunks.c.status == "queued"))
                     .values(status="cancelled"))
        return "cancelled"


def _summary(conn: Any, row: Any, n_failures: int = 100) -> dict[str, Any]:
    n_done, n_failed = conn.execute(
        select(func.count(), func.count(points.c.error)).where(points.c.sweep_id == row.id)
    ).one()
    now = time.time()
    eta = None
    if row.status in ("queued", "running") and row.started_at and n_done:
        eta = (now - row.started_at) / n_done * (row.n_total - n_done)
    elif row.status == "done":
        eta = 0.0
    out = {"id": row.id, "status": row.status, "n_done": int(n_done), "n_total": row.n_total,
           "n_failed": int(n_failed), "n_chunks": row.n_chunks, "eta_s": eta,
           "created_at": row.created_at, "started_at": row.started_at,
           "finished_at": row.finished_at, "numerics_version": row.numerics_version,
           "spec": json.loads(row.spec)}
    if n_failures:
        fails = conn.execute(select(points.c.idx, points.c.i, points.c.j, points.c.x,
                                    points.c.y, points.c.error)
                             .where(and_(points.c.sweep_id == row.id, points.c.error.is_not(None)))
                             .order_by(points.c.idx).limit(n_failures)).all()
        out["failures"] = [dict(f._mapping) for f in fails]
    return out


def status(sweep_id: str) -> dict[str, Any] | None:
    """Status, progress, ETA [s] and the first 100 failures of a sweep."""
    with db.read() as conn:
        row = conn.execute(select(sweeps).where(sweeps.c.id == sweep_id)).first()
        return None if row is None else _summary(conn, row)


def list_sweeps(limit: int, offset: int) -> list[dict[str, Any]]:
    """Sweeps, newest first, with progress (no failure lists)."""
    with db.read() as conn:
        rows = conn.execute(select(sweeps).order_by(sweeps.c.created_at.desc())
                            .limit(limit).offset(offset)).all()
        return [_summary(conn, r, n_failures=0) for r in rows]


def page_points(sweep_id: str, offset: int, limit: int) -> list[dict[str, Any]]:
    """Stored points ordered by flat index, from the ``offset``-th stored one."""
    with db.read() as conn:
        rows = conn.execute(select(points.c.idx, points.c.i, points.c.j, points.c.x,
                                   points.c.y, points.c.kind, points.c.critical_size,
                                   points.c.outcome, points.c.rel_accuracy, points.c.error)
                            .where(points.c.sweep_id == sweep_id).order_by(points.c.idx)
                            .limit(limit).offset(offset)).all()
    return [dict(r._mapping) for r in rows]


def stale_chunks(lease_s: float) -> list[tuple[str, int]]:
    """Chunks of active sweeps that no live worker holds (queued, or owner dead).

    Stale running chunks are reset to queued.  Used at worker start to requeue work lost
    with a killed worker (the filesystem broker deletes a message once delivered).
    """
    out: list[tuple[str, int]] = []
    with db.write() as conn:
        rows = conn.execute(select(chunks.c.sweep_id, chunks.c.idx, chunks.c.status,
                                   chunks.c.owner, chunks.c.heartbeat)
                            .join(sweeps, sweeps.c.id == chunks.c.sweep_id)
                            .where(and_(sweeps.c.status.in_(("queued", "running")),
                                        chunks.c.status.in_(("queued", "running"))))).all()
        for r in rows:
            if r.status == "running":
                if _owner_alive(r.owner, r.heartbeat, lease_s):
                    continue
                conn.execute(update(chunks).where(and_(chunks.c.sweep_id == r.sweep_id,
                                                       chunks.c.idx == r.idx))
                             .values(status="queued", owner=None))
            out.append((r.sweep_id, int(r.idx)))
    return out


def requeue(pairs: list[tuple[str, int]], send: Any) -> int:
    """Send ``send(sweep_id, idx)`` for each pair; returns how many were sent."""
    for sid, idx in pairs:
        send(sid, idx)
    return len(pairs)
