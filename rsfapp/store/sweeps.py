"""Sweep bookkeeping in the application database: sweeps, chunks and points.

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
from collections.abc import Callable
from typing import Any, NamedTuple

from sqlalchemy import Connection, Row, and_, func, select, update

from ..db.engine import Database, insert_ignore
from ..db.tables import chunks, points, sweeps

__all__ = ["ChunkRange", "Created", "SweepStore", "owner_id"]


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


class ChunkRange(NamedTuple):
    """Flat indices [i0, i1) of a claimed chunk."""

    i0: int
    i1: int


class Created(NamedTuple):
    """Outcome of :meth:`SweepStore.create`: was the sweep new, which chunks to enqueue."""

    created: bool
    todo: list[int]


def _chunk(sweep_id: str, idx: int) -> Any:
    return and_(chunks.c.sweep_id == sweep_id, chunks.c.idx == idx)


class SweepStore:
    """Sweeps, their chunks and points in ``db``."""

    def __init__(self, db: Database) -> None:
        self.db = db

    def create(self, sweep_id: str, spec: dict[str, Any], n_total: int, chunk_points: int,
               numerics_version: str) -> Created:
        """Create the sweep and its chunks unless it exists.

        An existing cancelled sweep is resumed (its unfinished chunks queued again); an
        existing active or done sweep enqueues nothing.
        """
        now = time.time()
        with self.db.write() as conn:
            row = conn.execute(select(sweeps.c.status).where(sweeps.c.id == sweep_id)).first()
            if row is None:
                n_chunks = -(-n_total // chunk_points)
                conn.execute(sweeps.insert().values(
                    id=sweep_id, spec=json.dumps(spec, sort_keys=True), status="queued",
                    n_total=n_total, n_chunks=n_chunks, numerics_version=numerics_version,
                    created_at=now))
                conn.execute(chunks.insert(), [
                    {"sweep_id": sweep_id, "idx": c, "i0": c * chunk_points,
                     "i1": min(n_total, (c + 1) * chunk_points), "status": "queued",
                     "attempts": 0}
                    for c in range(n_chunks)])
                return Created(True, list(range(n_chunks)))
            if row[0] != "cancelled":
                return Created(False, [])
            conn.execute(update(sweeps).where(sweeps.c.id == sweep_id).values(
                status="queued", finished_at=None))
            conn.execute(update(chunks).where(and_(chunks.c.sweep_id == sweep_id,
                                                   chunks.c.status == "cancelled"))
                         .values(status="queued", owner=None))
            idx = conn.execute(select(chunks.c.idx).where(and_(
                chunks.c.sweep_id == sweep_id, chunks.c.status == "queued"))).scalars().all()
            return Created(False, [int(i) for i in idx])

    def get_spec(self, sweep_id: str) -> dict[str, Any] | None:
        """The stored spec of a sweep (None if unknown)."""
        with self.db.read() as conn:
            row = conn.execute(select(sweeps.c.spec).where(sweeps.c.id == sweep_id)).first()
        return None if row is None else dict(json.loads(row[0]))

    def claim(self, sweep_id: str, idx: int, lease_s: float) -> ChunkRange | None:
        """Claim chunk ``idx`` for this process; None if there is nothing to do.

        Nothing to do: the sweep is unknown or cancelled, the chunk is done, or another
        live worker holds it.
        """
        me = owner_id()
        now = time.time()
        with self.db.write() as conn:
            s = conn.execute(select(sweeps.c.status).where(sweeps.c.id == sweep_id)).first()
            c = conn.execute(select(chunks).where(_chunk(sweep_id, idx))).first()
            if s is None or c is None or c.status in ("done", "cancelled"):
                return None
            if s.status == "cancelled":
                conn.execute(update(chunks).where(_chunk(sweep_id, idx))
                             .values(status="cancelled"))
                return None
            if c.status == "running" and c.owner != me and _owner_alive(
                    c.owner, c.heartbeat, lease_s):
                return None
            conn.execute(update(chunks).where(_chunk(sweep_id, idx)).values(
                status="running", owner=me, heartbeat=now, attempts=chunks.c.attempts + 1))
            conn.execute(update(sweeps).where(and_(sweeps.c.id == sweep_id,
                                                   sweeps.c.status == "queued"))
                         .values(status="running",
                                 started_at=func.coalesce(sweeps.c.started_at, now)))
            return ChunkRange(int(c.i0), int(c.i1))

    def release_chunk(self, sweep_id: str, idx: int) -> None:
        """Put a running chunk back in the queue (its worker hit an infrastructure error)."""
        with self.db.write() as conn:
            conn.execute(update(chunks).where(and_(_chunk(sweep_id, idx),
                                                   chunks.c.status == "running"))
                         .values(status="queued", owner=None))

    def done_indices(self, sweep_id: str, i0: int, i1: int) -> set[int]:
        """Flat indices in [i0, i1) already stored."""
        with self.db.read() as conn:
            rows = conn.execute(select(points.c.idx).where(and_(
                points.c.sweep_id == sweep_id, points.c.idx >= i0,
                points.c.idx < i1))).scalars()
            return {int(r) for r in rows}

    def store_points(self, sweep_id: str, chunk_idx: int, rows: list[dict[str, Any]]) -> int:
        """Insert point rows (idempotent) and refresh the chunk heartbeat; rows added."""
        now = time.time()
        for r in rows:
            r.setdefault("sweep_id", sweep_id)
            r.setdefault("created_at", now)
        with self.db.write() as conn:
            n = insert_ignore(conn, points, rows)
            conn.execute(update(chunks).where(_chunk(sweep_id, chunk_idx))
                         .values(heartbeat=now))
        return n

    def is_cancelled(self, sweep_id: str) -> bool:
        """True once the sweep has been cancelled."""
        with self.db.read() as conn:
            s = conn.execute(select(sweeps.c.status).where(sweeps.c.id == sweep_id)).scalar()
        return bool(s == "cancelled")

    def finish_chunk(self, sweep_id: str, idx: int, complete: bool) -> None:
        """Mark the chunk done (or cancelled if incomplete); close the sweep when all done."""
        now = time.time()
        with self.db.write() as conn:
            conn.execute(update(chunks).where(_chunk(sweep_id, idx))
                         .values(status="done" if complete else "cancelled", heartbeat=now))
            left = conn.execute(select(func.count()).select_from(chunks).where(and_(
                chunks.c.sweep_id == sweep_id, chunks.c.status != "done"))).scalar()
            if left == 0:
                conn.execute(update(sweeps).where(sweeps.c.id == sweep_id)
                             .values(status="done", finished_at=now))

    def cancel(self, sweep_id: str) -> str | None:
        """Cancel a sweep; returns its new status (None if unknown). Done sweeps stay done."""
        with self.db.write() as conn:
            s = conn.execute(select(sweeps.c.status).where(sweeps.c.id == sweep_id)).scalar()
            if s is None or s == "done":
                return None if s is None else str(s)
            conn.execute(update(sweeps).where(sweeps.c.id == sweep_id)
                         .values(status="cancelled", finished_at=time.time()))
            conn.execute(update(chunks).where(and_(chunks.c.sweep_id == sweep_id,
                                                   chunks.c.status == "queued"))
                         .values(status="cancelled"))
            return "cancelled"

    @staticmethod
    def _summary(conn: Connection, row: Row[Any], n_failures: int = 100) -> dict[str, Any]:
        n_done, n_failed = conn.execute(
            select(func.count(), func.count(points.c.error)).where(points.c.sweep_id == row.id)
        ).one()
        now = time.time()
        eta = None
        if row.status in ("queued", "running") and row.started_at and n_done:
            eta = (now - row.started_at) / n_done * (row.n_total - n_done)
        elif row.status == "done":
            eta = 0.0
        out: dict[str, Any] = {
            "id": row.id, "status": row.status, "n_done": int(n_done),
            "n_total": row.n_total, "n_failed": int(n_failed), "n_chunks": row.n_chunks,
            "eta_s": eta, "created_at": row.created_at, "started_at": row.started_at,
            "finished_at": row.finished_at, "numerics_version": row.numerics_version,
            "spec": json.loads(row.spec)}
        if n_failures:
            fails = conn.execute(
                select(points.c.idx, points.c.i, points.c.j, points.c.x, points.c.y,
                       points.c.error)
                .where(and_(points.c.sweep_id == row.id, points.c.error.is_not(None)))
                .order_by(points.c.idx).limit(n_failures)).all()
            out["failures"] = [dict(f._mapping) for f in fails]
        return out

    def status(self, sweep_id: str) -> dict[str, Any] | None:
        """Status, progress, ETA [s] and the first 100 failures of a sweep."""
        with self.db.read() as conn:
            row = conn.execute(select(sweeps).where(sweeps.c.id == sweep_id)).first()
            return None if row is None else self._summary(conn, row)

    def list_sweeps(self, limit: int, offset: int) -> list[dict[str, Any]]:
        """Sweeps, newest first, with progress (no failure lists)."""
        with self.db.read() as conn:
            rows = conn.execute(select(sweeps).order_by(sweeps.c.created_at.desc())
                                .limit(limit).offset(offset)).all()
            return [self._summary(conn, r, n_failures=0) for r in rows]

    def page_points(self, sweep_id: str, offset: int, limit: int) -> list[dict[str, Any]]:
        """Stored points ordered by flat index, from the ``offset``-th stored one."""
        with self.db.read() as conn:
            rows = conn.execute(
                select(points.c.idx, points.c.i, points.c.j, points.c.x, points.c.y,
                       points.c.kind, points.c.critical_size, points.c.outcome,
                       points.c.rel_accuracy, points.c.error)
                .where(points.c.sweep_id == sweep_id).order_by(points.c.idx)
                .limit(limit).offset(offset)).all()
        return [dict(r._mapping) for r in rows]

    def stale_chunks(self, lease_s: float) -> list[tuple[str, int]]:
        """Chunks of active sweeps that no live worker holds (queued, or owner dead).

        Stale running chunks are reset to queued.  Used at worker start to requeue work
        lost with a killed worker (the filesystem broker deletes a message once delivered).
        """
        out: list[tuple[str, int]] = []
        with self.db.write() as conn:
            rows = conn.execute(
                select(chunks.c.sweep_id, chunks.c.idx, chunks.c.status, chunks.c.owner,
                       chunks.c.heartbeat)
                .join(sweeps, sweeps.c.id == chunks.c.sweep_id)
                .where(and_(sweeps.c.status.in_(("queued", "running")),
                            chunks.c.status.in_(("queued", "running"))))).all()
            for r in rows:
                if r.status == "running":
                    if _owner_alive(r.owner, r.heartbeat, lease_s):
                        continue
                    conn.execute(update(chunks).where(_chunk(r.sweep_id, r.idx))
                                 .values(status="queued", owner=None))
                out.append((str(r.sweep_id), int(r.idx)))
        return out

    @staticmethod
    def requeue(pairs: list[tuple[str, int]], send: Callable[[str, int], None]) -> int:
        """Send ``send(sweep_id, idx)`` for each pair; returns how many were sent."""
        for sid, idx in pairs:
            send(sid, idx)
        return len(pairs)
